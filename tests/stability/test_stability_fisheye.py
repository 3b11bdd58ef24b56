"""Stability: the library fisheye (Muller 10 mm f/4, 155.9 deg) at and beyond its full field.

Near 90 deg the paraxial entrance pupil says nothing about where real rays go, so rays are
aimed at the real stop (``aim="real"``: Newton's method, continued in field from the axis).
References and tolerances:

* aiming: the float64 NumPy reference tracer puts the aimed chief ray on the stop's centre
  to 1e-9 mm (Newton stops at 1e-10 mm);
* statuses: the float64 reference tracer (status and surface) in both precisions, and the
  geometry -- a clipped chief ray passes exactly where its unclipped path stays inside every
  clear semi-diameter;
* image heights: monotone in field up to 110 deg (unclipped), f theta at 0.5 deg to 1e-5
  relative (the paraxial f tan(theta) to 5e-5: the lens maps nearly equidistantly); float32 within :data:`F32_BOUND_MM` of float64 (these chief rays
  are not grazing: their steepest angle is 64 deg at 105 deg field).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from stability_cases import F32_BOUND_MM, finite, library

from lensrt.paraxial import first_order
from lensrt.trace import make_rays, trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import MISSED, OK, VIGNETTED

LENS = library("fisheye_10mm_f4")
FULL_DEG = math.degrees(LENS.fields.max_radial)  # 77.95
#: half-field angles (deg): the full field, just beyond it, up to and past 90 deg
ANGLES = (0.5, 30.0, 60.0, 74.0, 76.0, FULL_DEG, 80.0, 85.0, 89.0, 89.9, 90.0, 90.1, 95.0, 100.0, 105.0, 110.0)


def _chief(angles_deg) -> object:
    a = np.asarray(angles_deg, dtype=np.float64)
    return make_rays(LENS, 0.0, a / FULL_DEG, 0.0, 0.0, aim="real", device="cpu")


@pytest.fixture(scope="module")
def chief():
    return _chief(ANGLES)


def test_real_aiming_converges_up_to_110_deg(chief):
    """The aimed chief ray meets the real stop's centre (reference tracer, float64)."""
    assert chief.aimed.all()
    assert finite(chief.origin_mm, chief.direction)
    stop = LENS.stop_index
    for i, deg in enumerate(ANGLES):
        ref = trace_reference(LENS, chief.origin_mm[i], chief.direction[i], chief.wavelength_nm[i],
                              clip=False, end=stop)
        assert ref.status == OK, deg
        assert math.hypot(ref.x_mm, ref.y_mm) < 1e-9, deg
        # the beam really comes from that angle (polar field: linear in angle beyond 90 deg)
        assert math.degrees(math.acos(chief.direction[i, 2])) == pytest.approx(deg, abs=1e-9)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_chief_ray_statuses_match_reference_and_geometry(chief, precision, device):
    clipped = trace(LENS, chief, precision, device)
    free = trace(LENS, chief, precision, device, clip=False, record=True)
    for res in (clipped, free):
        assert finite(res.position_mm, res.direction, res.opl_mm, res.min_cos_incidence)
        assert np.all((res.status == OK) == (res.surface == -1))
    sd = np.array([s.semi_diameter_mm for s in LENS.surfaces])
    for i, deg in enumerate(ANGLES):
        ref = trace_reference(LENS, chief.origin_mm[i], chief.direction[i], chief.wavelength_nm[i])
        assert (clipped.status[i], clipped.surface[i]) == (ref.status, ref.surface), deg
        # clipping agrees with the unclipped path: the first surface it leaves the clear aperture
        h = np.hypot(free.records[i, :LENS.n_surfaces, 0], free.records[i, :LENS.n_surfaces, 1])
        outside = np.nonzero(h > sd * (1 + 1e-6))[0]
        if len(outside) == 0:
            assert clipped.status[i] == OK, deg
        else:
            assert (clipped.status[i], clipped.surface[i]) == (VIGNETTED, outside[0]), deg
    # the clear aperture of surface 1 (15.17 mm) vignettes the chief ray between 74 and 76 deg
    ok = dict(zip(ANGLES, clipped.status == OK))
    assert ok[74.0] and not ok[76.0] and not ok[FULL_DEG]


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_image_height_monotone_through_90_deg(chief, precision, device):
    res = trace(LENS, chief, precision, device, clip=False, record=True)
    assert res.ok.all()
    y = res.position_mm[:, 1]
    assert np.all(np.diff(y) > 0.0)
    # up to 90 deg every segment runs forward; beyond, the unclipped path meets surface 3 behind
    # surface 2 (a virtual segment, t < 0), where the two surfaces cross outside their clear
    # apertures -- clipped, those rays stop at surface 1 anyway
    upto90 = np.array(ANGLES) <= 90.0
    assert np.all(res.records[upto90, 1:, 8] > 0.0)
    assert np.all(res.records[np.array(ANGLES) >= 95.0, 2, 8] < 0.0)
    assert np.all(res.direction[:, 2] > 0.0)
    assert not res.grazing.any()
    if precision == "float64":
        fo = first_order(LENS)
        paraxial = fo.efl_mm * math.tan(math.radians(0.5))
        # the fisheye maps nearly equidistantly (y = f theta): its distortion at 0.5 deg is close to
        # theta^2 / 3 = -2.5e-5 of f tan(theta)
        assert y[0] == pytest.approx(paraxial, rel=5e-5)
        assert y[0] == pytest.approx(fo.efl_mm * math.radians(0.5), rel=1e-5)
    else:
        ref = trace(LENS, chief, "float64", device, clip=False)
        assert np.max(np.abs(res.position_mm - ref.position_mm)) < F32_BOUND_MM


def test_paraxial_pupil_is_meaningless_near_90_deg(device):
    """At 85 deg the paraxially aimed 'chief ray' does not reach the image; the real one does."""
    par = make_rays(LENS, 0.0, 85.0 / FULL_DEG, 0.0, 0.0, aim="paraxial")
    real = make_rays(LENS, 0.0, 85.0 / FULL_DEG, 0.0, 0.0, aim="real")
    assert trace(LENS, par, "float64", device, clip=False).status[0] == MISSED
    assert trace(LENS, real, "float64", device, clip=False).status[0] == OK


@pytest.mark.parametrize("deg", [120.0, 150.0, 179.0, 180.0])
def test_beams_from_behind_fail_cleanly(deg, device):
    """No path exists: aiming reports it (aimed False), rays end MISSED, nothing is NaN.

    (Before this suite, a 150 deg beam was traced backwards through the lens and reported OK
    at the mirror image of the 30 deg point.)
    """
    rays = make_rays(LENS, 0.0, deg / FULL_DEG, [0.0, 0.5], [0.0, -0.5], aim="real")
    assert not rays.aimed.any()
    assert finite(rays.origin_mm, rays.direction)
    for precision in ("float64", "float32"):
        for clip in (True, False):
            res = trace(LENS, rays, precision, device, clip=clip)
            assert not res.ok.any()
            assert finite(res.position_mm, res.direction, res.opl_mm)
            if not clip:
                assert np.all(res.status == MISSED)


def test_stream_pupil_shrinks_to_nothing_at_the_vignetting_limit(device):
    """The real pupil's area falls with field and vanishes at full field (the pbrt table's front
    element is too small for 77.95 deg); every ray is counted, none transmitted there."""
    from lensrt.trace.stream import Grid, stream, stream_source
    areas = []
    for deg in (60.0, 74.0, FULL_DEG, 85.0):
        src = stream_source(LENS, 0.0, deg / FULL_DEG, device=device)
        res = stream(LENS, [src], Grid(8, 8, 0.05), 1 << 11, sampler="sobol", seed=1, precision="float32",
                     device=device)
        counts = res.status_counts()
        assert sum(v for k, v in counts.items() if k not in ("OUTSIDE_GRID", "GRAZING")) == res.rays_total
        area, se = res.transmitted_area_mm2()
        assert math.isfinite(area) and math.isfinite(se)
        areas.append(area)
    assert areas[0] > areas[1] > 0.0
    assert areas[2] == 0.0 and areas[3] == 0.0


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_specialised_kernel_agrees_through_and_beyond_90_deg(chief, precision, device):
    """The lens-specialised kernel (what large GPU runs use) makes the same choices: the same
    statuses, roots and grazing measure as the generic kernel, for the chief rays to 110 deg
    and for beams from behind."""
    behind = _chief([120.0, 150.0, 180.0])
    for rays in (chief, behind):
        for clip in (True, False):
            g = trace(LENS, rays, precision, device, clip=clip, kernel="generic")
            s = trace(LENS, rays, precision, device, clip=clip, kernel="specialised")
            assert np.array_equal(g.status, s.status) and np.array_equal(g.surface, s.surface)
            tol = 1e-12 if precision == "float64" else 2e-5
            assert np.max(np.abs(g.position_mm - s.position_mm)) < tol
            assert np.max(np.abs(g.min_cos_incidence - s.min_cos_incidence)) < 1e-6
