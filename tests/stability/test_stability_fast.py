"""Stability at f/0.95: the Nikkor-S 50 mm f/1.4 opened to f/0.95 (clear apertures recomputed by
real rays), where marginal rays meet surfaces near grazing incidence and some are totally
reflected or miss.

References and stated tolerances:

* float64 kernel = float64 NumPy reference tracer: status and surface identical, positions,
  directions and OPL to :data:`F64_VS_REFERENCE_MM` (dense fans over the whole pupil, three
  fields, three wavelengths);
* optiland (peer, unclipped, the same indices): image intercepts to 1e-9 mm where both trace;
* float32: identical statuses but for rays within rounding of a TIR or miss boundary (< 1 %);
  image intercepts within :data:`F32_BOUND_MM` of float64 for the rays not flagged grazing
  (incidence or refraction beyond 80 deg; the flagged ones differ by up to ~2e-4 mm here);
* the pupil height where the axial fan starts to fail is the same in float32 to 1e-5 of the pupil.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from stability_cases import F32_BOUND_DIRECTION, F32_BOUND_MM, F64_VS_REFERENCE_MM, finite, opened_lens

from lensrt.paraxial import first_order
from lensrt.trace import make_rays, trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import MISSED, OK, TIR

LENS = opened_lens("nikkor_50mm_f1.4", 0.95)
PY = np.linspace(-1.0, 1.0, 81)


def _fans(aim: str = "real"):
    hy = np.repeat([0.0, 0.7, 1.0], len(PY))
    py = np.tile(PY, 3)
    wl = np.resize(np.array(LENS.wavelengths.nm), len(py))
    return make_rays(LENS, 0.0, hy, 0.0, py, wl, aim=aim)


def test_the_lens_is_f095():
    fo = first_order(LENS)
    assert fo.f_number == pytest.approx(0.95, rel=1e-12)
    assert fo.entrance_pupil_diameter_mm == pytest.approx(fo.efl_mm / 0.95, rel=1e-12)
    assert "real rays" in LENS.meta["clear_apertures"]


@pytest.mark.parametrize("clip", [True, False])
def test_kernel_equals_reference_near_grazing(clip, device):
    rays = _fans()
    res = trace(LENS, rays, "float64", device, clip=clip)
    assert finite(res.position_mm, res.direction, res.opl_mm, res.min_cos_incidence)
    counts = res.counts
    if not clip:  # the stretched lens has TIR and misses beyond its clear apertures
        assert counts["TIR"] > 0 and counts["MISSED"] > 0
    worst = 0.0
    for i in range(len(rays)):
        ref = trace_reference(LENS, rays.origin_mm[i], rays.direction[i], rays.wavelength_nm[i], clip=clip)
        assert (ref.status, ref.surface) == (res.status[i], res.surface[i]), i
        got = np.r_[res.position_mm[i], res.direction[i], res.opl_mm[i], res.min_cos_incidence[i]]
        want = np.r_[ref.x_mm, ref.y_mm, ref.z_mm, ref.L, ref.M, ref.N, ref.opl_mm, ref.min_cos_incidence]
        worst = max(worst, float(np.max(np.abs(got - want))))
    assert worst <= F64_VS_REFERENCE_MM
    # the steepest rays really are steep: some refract beyond 80 deg (flagged grazing)
    assert res.grazing.any() and np.degrees(np.arccos(res.min_cos_incidence.min())) > 85.0


@pytest.mark.parametrize("clip", [True, False])
def test_float32_within_bound_or_flagged(clip, device):
    rays = _fans()
    r64 = trace(LENS, rays, "float64", device, clip=clip)
    r32 = trace(LENS, rays, "float32", device, clip=clip)
    assert finite(r32.position_mm, r32.direction, r32.opl_mm)
    assert np.mean(r64.status == r32.status) >= 0.99
    both = (r64.status == OK) & (r32.status == OK)
    steady = both & ~r64.grazing
    assert steady.sum() > 150
    assert np.max(np.abs(r32.position_mm[steady] - r64.position_mm[steady])) < F32_BOUND_MM
    assert np.max(np.abs(r32.opl_mm[steady] - r64.opl_mm[steady])) < F32_BOUND_MM
    assert np.max(np.abs(r32.direction[steady] - r64.direction[steady])) < F32_BOUND_DIRECTION
    # grazing rays may differ more, but they are flagged, and still sensible (< 0.01 mm here)
    flagged = both & r64.grazing
    assert flagged.any()
    assert np.max(np.abs(r32.position_mm[flagged] - r64.position_mm[flagged])) < 1e-2


def test_matches_optiland(device):
    """The same rays through optiland's NumPy tracer (no apertures, the same indices)."""
    pytest.importorskip("optiland")
    import optiland.backend as be
    from optiland.rays import RealRays
    from optiland_cases import optiland_optic
    wl = LENS.wavelengths.primary_nm
    op = optiland_optic(LENS, wl)
    hy = np.repeat([0.0, 0.7, 1.0], len(PY))
    rays = make_rays(LENS, 0.0, hy, 0.0, np.tile(PY, 3), wl, aim="paraxial")
    o, d = rays.origin_mm, rays.direction
    start = o + ((-20.0 - o[:, 2]) / d[:, 2])[:, None] * d
    n = len(start)
    peer = RealRays(start[:, 0], start[:, 1], start[:, 2], d[:, 0], d[:, 1], d[:, 2], np.ones(n), np.full(n, wl / 1e3))
    op.surfaces.trace(peer)
    want = np.column_stack([be.to_numpy(peer.x), be.to_numpy(peer.y)])
    res = trace(LENS, rays, "float64", device, clip=False)
    ok = res.ok & np.all(np.isfinite(want), axis=1)
    assert ok.sum() > 150
    assert np.max(np.abs(res.position_mm[ok, :2] - want[ok])) <= 1e-9


def test_failure_boundary_is_the_same_in_float32(device):
    """Walk the axial fan outward (unclipped) to the first pupil height where rays stop reaching
    the image (TIR or a miss); bisect it in each precision."""
    def fails(py: float, precision: str) -> bool:
        r = trace(LENS, make_rays(LENS, 0.0, 0.0, 0.0, py, aim="paraxial"), precision, device, clip=False)
        return r.status[0] != OK

    grid = np.linspace(0.5, 2.5, 81)
    first = next(p for p in grid if fails(p, "float64"))
    status = trace(LENS, make_rays(LENS, 0.0, 0.0, 0.0, first, aim="paraxial"), "float64", device, clip=False)
    assert status.status[0] in (TIR, MISSED)
    edges = {}
    for precision in ("float64", "float32"):
        lo, hi = first - 0.025, first
        assert not fails(lo, precision) and fails(hi, precision)
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if fails(mid, precision) else (mid, hi)
        edges[precision] = hi
    assert abs(edges["float32"] - edges["float64"]) < 1e-5
    assert math.isfinite(edges["float64"])
