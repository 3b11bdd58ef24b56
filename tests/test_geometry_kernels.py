"""Mirrors and tilts/decenters in the Warp kernels against the float64 reference tracer.

The generic store kernel (the shared ``@wp.func`` surface code of :mod:`lensrt.trace.kernels.surfaces`)
traces the folded, tilted/decentred, Mangin and Cassegrain systems of
``tests/test_geometry_optiland.py`` (there checked against optiland): float64 to 1e-9 mm
and float32 within the documented bound, same statuses, same records; the specialised
generator leaves such lenses to the generic kernel; surface apertures are refused.
"""
from __future__ import annotations

import numpy as np
import pytest

from test_geometry_optiland import (WL_NM, cassegrain_system, folded_system, mangin_system, ray_grid,
                                    tilted_decentred_system)
from test_trace_kernels import FLOAT32_BOUND_MM

from lensrt.errors import LensrtError
from lensrt.trace import trace
from lensrt.trace.api import RayBatch
from lensrt.trace.reference import trace_reference
from lensrt.trace.reverse import reversed_lens
from lensrt.trace.status import OK

SYSTEMS = {"folded": folded_system, "tilted_decentred": tilted_decentred_system, "mangin": mangin_system,
           "cassegrain": lambda: cassegrain_system().replace_surface(0, apertures=())}


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
        assert (res.status[k], ref.status) == (OK, OK)
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


def test_surface_apertures_are_refused_by_the_kernels(device: str) -> None:
    o, d = ray_grid(1.0)
    with pytest.raises(LensrtError, match="only in the reference tracer"):
        trace(cassegrain_system(), RayBatch(o, d, np.full(len(o), WL_NM)), "float64", device)
