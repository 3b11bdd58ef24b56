"""Random prescriptions (property-based, hypothesis): no NaN ever, a status for every failed ray,
float32 = float64 within the stated per-ray bound unless the ray is flagged grazing.

The lenses (``stability_cases.random_lens_strategy``): one to three singlets or cemented
doublets, |R| from 8 mm to 2 m or planes, glass 1-12 mm thick (five catalog glasses, a model
glass, a constant index), air gaps 0.5-20 mm, a plane stop in front or in an air gap, one clear
semi-diameter for all surfaces -- a fraction of the largest at which no element gets thinner than
0.5 mm and no air gap than 0.1 mm at its edge, and no sphere beyond 0.95 |R| -- half fields up to
30 deg, objects at infinity, 1e9, 2000 or 300 mm, the image at the paraxial focus (or 50 mm
behind the last surface when that is not between 1 mm and 1 m). Rays: 150 named (fields 0, 0.5, 1,
pupil [-1.2, 1.2]^2, paraxial aim, 450-650 nm) and 50 free ones (up to 60 deg, a tenth of them
pointing away from the lens).

Stated tolerances: float64 kernel = reference tracer (status, surface; values to 1e-9 mm +
1e-12 relative) on every 10th ray; float32 against float64 per ray:
``2e-4 mm + 2e-6 x L / (N' c)`` (L the optical path, N' the final z direction cosine, c the
smallest cosine of incidence or refraction: :func:`stability_cases.f32_ray_bound_mm`) for rays not
flagged grazing; at most 1 % of rays may change status between precisions (none did in 1000
lenses). CI runs 50 derandomized examples with the generic kernels; ``-m slow`` runs 400, and 8
with the lens-specialised kernels (large GPU runs use those; one compile per lens shape).
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stability_cases import f32_ray_bound_mm, finite, random_lens_strategy, random_rays

from lensrt.trace import trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import N_STATUS, OK

SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow,
                                                                         HealthCheck.filter_too_much])


def _check(lens, seed: int, kernel: str = "auto") -> None:
    rays = random_rays(lens, 150, 50, seed)
    n = len(rays)
    res = {p: trace(lens, rays, p, "cpu", kernel=kernel) for p in ("float64", "float32")}
    for r in res.values():
        # no NaN or inf reaches an output, whatever happened to the ray
        assert finite(r.position_mm, r.direction, r.opl_mm, r.min_cos_incidence)
        # every ray has a status; OK rays no failing surface, failed rays a surface of the lens
        assert np.all((r.status >= 0) & (r.status < N_STATUS))
        assert np.all((r.status == OK) == (r.surface == -1))
        assert np.all((r.surface[~r.ok] >= 0) & (r.surface[~r.ok] <= lens.n_surfaces))
        assert sum(r.counts.values()) == n
    r64, r32 = res["float64"], res["float32"]
    # the float64 kernel is the reference tracer
    for i in range(0, n, 10):
        ref = trace_reference(lens, rays.origin_mm[i], rays.direction[i], rays.wavelength_nm[i])
        assert (ref.status, ref.surface) == (r64.status[i], r64.surface[i])
        want = np.array([ref.x_mm, ref.y_mm, ref.z_mm, ref.L, ref.M, ref.N, ref.opl_mm])
        got = np.r_[r64.position_mm[i], r64.direction[i], r64.opl_mm[i]]
        assert np.all(np.abs(got - want) <= 1e-9 + 1e-12 * np.abs(want))
    # float32 agrees within the per-ray bound, or the ray is flagged grazing
    assert np.mean(r64.status != r32.status) <= 0.01
    steady = r64.ok & r32.ok & ~r64.grazing
    bound = f32_ray_bound_mm(r64.opl_mm[steady], r64.direction[steady, 2], r64.min_cos_incidence[steady])
    assert np.all(np.max(np.abs(r32.position_mm[steady] - r64.position_mm[steady]), axis=1) <= bound)
    assert np.all(np.abs(r32.opl_mm[steady] - r64.opl_mm[steady]) <= bound)


@settings(max_examples=50, **SETTINGS)
@given(random_lens_strategy(), st.integers(0, 2**31 - 1))
def test_random_prescriptions(lens, seed):
    _check(lens, seed)


@pytest.mark.slow
@settings(max_examples=400, **SETTINGS)
@given(random_lens_strategy(), st.integers(0, 2**31 - 1))
def test_random_prescriptions_many(lens, seed):
    _check(lens, seed)


@pytest.mark.slow
@settings(max_examples=8, **SETTINGS)
@given(random_lens_strategy(), st.integers(0, 2**31 - 1))
def test_random_prescriptions_specialised_kernel(lens, seed):
    """The lens-specialised kernels (compiled per lens shape, ~2 s each on the CPU: few examples)."""
    _check(lens, seed, kernel="specialised")


def test_the_generator_makes_valid_varied_lenses():
    """The strategy's lenses pass lensrt's own geometry checks, and vary (glasses, stops, fields)."""
    from lensrt.prescription.validate import check_geometry
    seen = []

    @settings(max_examples=40, database=None, **SETTINGS)
    @given(random_lens_strategy())
    def collect(lens):
        check_geometry(lens)
        seen.append(lens)

    collect()
    assert len(seen) >= 30
    assert len({s.n_surfaces for s in seen}) >= 3
    assert len({m.describe() for s in seen for m in s.media()}) >= 5
    assert any(s.stop_index > 0 for s in seen) and any(s.stop_index == 0 for s in seen)
    assert any(np.isfinite(s.object_distance_mm) for s in seen)
