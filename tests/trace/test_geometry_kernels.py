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


def _annulus_ratio(r2: np.ndarray) -> float:
    """sqrt(r_in^2 / r_out^2) of a uniform annulus from the mean and variance of r^2 (r^2 is uniform there)."""
    m, v = float(r2.mean()), float(r2.var())
    a, b = m - np.sqrt(3.0 * v), m + np.sqrt(3.0 * v)
    return float(np.sqrt(max(a, 0.0) / b))


@pytest.mark.parametrize("defocus_mm", [-60.0, 40.0])
def test_obscured_telescope_bokeh_is_a_ring_of_the_obscuration_ratio(defocus_mm: float, device: str) -> None:
    """A distant point on the axis of the obscured classical Cassegrain (free of axial spherical aberration),
    the sensor moved off its focus: the blur is a ring whose inner/outer radius ratio is the obscuration
    ratio seen from the point (obscuration and stop share a plane here: 2 mm / 5 mm = 0.4), within 3
    jackknife standard errors. Uniform pupil sampling makes r^2 uniform across the ring, so the mean and
    variance of r^2 give both radii."""
    from lensrt.loading import complete_lens
    from lensrt.paraxial.first_order import first_order
    lens = complete_lens(cassegrain_system(obscuration_mm=2.0).replace_surface(0, semi_diameter_mm=5.0))
    focus_z = first_order(lens).image_z_mm
    rng = np.random.default_rng(17)
    n = 128_000
    r, ph = 5.2 * np.sqrt(rng.random(n)), 2.0 * np.pi * rng.random(n)
    o = np.stack([r * np.cos(ph), r * np.sin(ph), np.full(n, -1.0)], axis=1)
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    res = trace(lens, RayBatch(o, d, np.full(n, WL_NM)), "float64", device, plane_z_mm=focus_z + defocus_mm)
    r2 = res.position_mm[res.ok, 0] ** 2 + res.position_mm[res.ok, 1] ** 2
    assert res.ok.sum() > 0.95 * n * (1 - 0.4 ** 2) * (5.0 / 5.2) ** 2
    parts = np.array_split(r2, 32)
    jack = np.array([_annulus_ratio(np.concatenate(parts[:k] + parts[k + 1:])) for k in range(32)])
    se = float(np.sqrt(31.0 / 32.0 * np.sum((jack - jack.mean()) ** 2)))
    assert abs(_annulus_ratio(r2) - 0.4) < 3.0 * se
    assert se < 0.005


def test_symmetric_and_general_variants_agree(device: str) -> None:
    """The run plan's lens variant: a rotationally symmetric lens packs as symmetric (the kernel
    without the frame/mirror/aperture code); the same lens made general by a surface aperture that
    never clips traces to the same rays (float64 rounding) through the general variant."""
    from dataclasses import replace

    from lensrt.loading import load_lens
    from lensrt.prescription.geometry import SurfaceAperture
    from lensrt.trace.api import make_rays
    from lensrt.trace.pack import pack_lens

    lens = load_lens("cooke_triplet_50mm_f5")
    wide = SurfaceAperture(shape="circle", a=1.0e3)
    general = lens.replace(surfaces=(replace(lens.surfaces[0], apertures=(wide,)),) + lens.surfaces[1:])
    assert not pack_lens(lens, "float64", device).general
    assert pack_lens(general, "float64", device).general
    g = np.linspace(-1.0, 1.0, 9)
    px, py = (v.ravel() for v in np.meshgrid(g, g))
    rays = make_rays(lens, 0.0, 0.7, px, py, 587.6)
    a = trace(lens, rays, "float64", device, kernel="generic")
    b = trace(general, rays, "float64", device, kernel="generic")
    assert np.array_equal(a.status, b.status) and np.count_nonzero(a.status == OK) > 20
    ok = a.status == OK
    assert np.max(np.abs(a.position_mm[ok] - b.position_mm[ok])) < 1e-9
    assert np.max(np.abs(a.direction[ok] - b.direction[ok])) < 1e-12
