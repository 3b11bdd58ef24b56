"""Mirrors and tilts/decenters in the Warp kernels against the float64 reference tracer.

The generic store kernel (the shared ``@wp.func`` surface code of :mod:`lensrt.trace.kernels.surfaces`)
traces the folded, tilted/decentred, Mangin and Cassegrain systems of
``tests/oracles/geometry_cases.py`` (checked against optiland in ``test_geometry_optiland.py``) (there checked against optiland): float64 to 1e-9 mm
and float32 within the documented bound, same statuses, same records; the specialised
generator leaves such lenses to the generic kernel; surface apertures vignette as in the reference.
"""
from __future__ import annotations

import numpy as np
import pytest

from geometry_cases import (WL_NM, cassegrain_system, folded_system, mangin_system, ray_grid,
                            tilted_decentred_system)
from test_trace_kernels import FLOAT32_BOUND_MM

from lensrt.errors import LensrtError
from lensrt.trace import trace
from lensrt.trace.api import RayBatch
from lensrt.trace.reference import trace_reference
from lensrt.trace.reverse import reversed_lens
from lensrt.trace.status import OK

SYSTEMS = {"folded": folded_system, "tilted_decentred": tilted_decentred_system, "mangin": mangin_system,
           "cassegrain": cassegrain_system}


@pytest.mark.parametrize("name", sorted(SYSTEMS))
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_kernel_matches_reference(name: str, precision: str, device: str) -> None:
    lens = SYSTEMS[name]()
    o, d = ray_grid(4.5, 1.5)
    res = trace(lens, RayBatch(o, d, np.full(len(o), WL_NM)), precision, device, kernel="auto", record=True)
    assert res.kernel == "generic"
    bound = 1e-9 if precision == "float64" else FLOAT32_BOUND_MM
    for k in range(len(o)):
        ref = trace_reference(lens, tuple(o[k]), tuple(d[k]), WL_NM)
        assert (res.status[k], res.surface[k]) == (ref.status, ref.surface)
        if ref.status != OK:  # the Cassegrain's obscuration
            continue
        got = (res.position_mm[k, 0], res.position_mm[k, 1], res.position_mm[k, 2], res.opl_mm[k])
        want = (ref.x_mm, ref.y_mm, ref.z_mm, ref.opl_mm)
        assert np.max(np.abs(np.subtract(got, want))) < bound
        assert np.max(np.abs(res.direction[k] - (ref.L, ref.M, ref.N))) < bound
        hits = np.array([[h.x_mm, h.y_mm, h.z_mm, h.L, h.M, h.N] for h in ref.hits])
        assert np.max(np.abs(res.records[k, :, :6] - hits)) < bound


def test_specialised_kernel_and_image_side_tracing_refuse_geometry(device: str) -> None:
    lens = folded_system()
    o, d = ray_grid(1.0)
    with pytest.raises(LensrtError, match="mirrors, tilts/decenters"):
        trace(lens, RayBatch(o, d, np.full(len(o), WL_NM)), "float32", device, kernel="specialised")
    with pytest.raises(LensrtError, match="image side"):
        reversed_lens(lens)


@pytest.mark.parametrize("shape,a,b,obscuration", [("circle", 2.2, 0.0, True), ("annulus", 4.0, 1.5, False),
                                                    ("rectangle", 3.0, 1.2, False), ("ellipse", 3.0, 1.5, True)])
def test_surface_apertures_vignette_as_in_the_reference(shape: str, a: float, b: float, obscuration: bool,
                                                        device: str) -> None:
    from lensrt.prescription.geometry import SurfaceAperture
    ap = SurfaceAperture(shape, a, b, decenter_x_mm=0.3, decenter_y_mm=-0.4, rotation_rad=0.3,
                         obscuration=obscuration)
    lens = cassegrain_system().replace_surface(0, apertures=(ap,))
    o, d = ray_grid(4.5)
    res = trace(lens, RayBatch(o, d, np.full(len(o), WL_NM)), "float64", device)
    ref = [trace_reference(lens, tuple(o[k]), tuple(d[k]), WL_NM).status for k in range(len(o))]
    assert list(res.status) == ref
    assert 0 < np.count_nonzero(res.status == OK) < len(o)


def test_too_many_surface_apertures_for_the_kernels_is_one_error(device: str) -> None:
    from lensrt.prescription.geometry import SurfaceAperture
    aps = tuple(SurfaceAperture("circle", r) for r in (6.0, 7.0, 8.0))
    o, d = ray_grid(1.0)
    with pytest.raises(LensrtError, match="at most 2"):
        trace(cassegrain_system().replace_surface(0, apertures=aps), RayBatch(o, d, np.full(len(o), WL_NM)),
              "float64", device)
