"""Error against run time on real rays: standard errors that match the scatter, targets that are met.

All seeded; the bounds are the 95 % (or tighter) ranges of the statistics involved.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.fields import FieldSpec
from lensrt.analysis.psf.setup import make_setup
from lensrt.analysis.psf.geometric import geometric_psf_at, prepare_field
from lensrt.loading import load_lens

FIELD = FieldSpec(0.0, 0.7, "0.7")


@pytest.fixture(scope="module")
def dgauss():
    lens = load_lens("dgauss_50mm_f2")
    setup = make_setup(lens, focus="image", device="cpu", rays=1 << 14, batches=16, pixels=48, ee_fractions=(),
                       mtf_freqs_cpmm=(20.0,))
    return setup, prepare_field(setup, FIELD, "cpu")


@pytest.mark.parametrize("sampler", ["random", "sobol"])
def test_reported_standard_error_matches_the_scatter_of_repeated_runs(dgauss, sampler):
    setup, geom = dgauss
    setup = setup.with_(sampler=sampler)
    runs = [geometric_psf_at(setup, FIELD, seed, "cpu", geom) for seed in range(24)]
    for key in ("rms_radius_mm", "centroid_y_mm", "mtf_tangential"):
        vals = np.array([float(np.ravel(r.estimates[key].value)[0]) for r in runs])
        ses = np.array([float(np.ravel(r.estimates[key].stderr)[0]) for r in runs])
        ratio = vals.std(ddof=1) / ses.mean()
        # 24 runs: the sample standard deviation is within about +-30 % of the truth (95 %)
        assert 0.65 < ratio < 1.45, (key, ratio)


def test_target_error_is_met_at_the_stated_confidence(dgauss):
    setup, geom = dgauss
    ref = geometric_psf_at(setup.with_(rays=1 << 21, batches=32, sampler="sobol"), FIELD, 999, "cpu",
                           geom).estimates["rms_radius_mm"]
    target = 2e-3  # relative standard error of the RMS radius
    prog = setup.with_(sampler="random", target_error=target, rays=1 << 24)
    hits, runs = 0, 12
    for seed in range(runs):
        r = geometric_psf_at(prog, FIELD, seed, "cpu", geom)
        e = r.estimates["rms_radius_mm"]
        assert r.metadata["stop_reason"] == "target_error"
        assert e.stderr <= target * e.value
        steps = [p["samples"] for p in r.metadata["progress"]]
        assert len(steps) >= 2 and all(b == 2 * a for a, b in zip(steps, steps[1:]))  # rounds double the total
        hits += abs(e.value - ref.value) <= 1.96 * math.hypot(target * e.value, ref.stderr)
    # each run is within 1.96 sigma with probability 0.95: at least 10 of 12 (binomial, P > 0.98)
    assert hits >= 10


def test_mtf_target_and_time_budget_stop_progressive_runs(dgauss):
    setup, geom = dgauss
    r = geometric_psf_at(setup.with_(target_error=0.004, target_quantity="mtf", rays=1 << 22), FIELD, 1, "cpu", geom)
    assert r.metadata["stop_reason"] == "target_error"
    for key in ("mtf_sagittal", "mtf_tangential"):
        assert np.all(r.estimates[key].stderr <= 0.004)
    r = geometric_psf_at(setup.with_(target_error=1e-9, time_budget_s=0.3, rays=1 << 30), FIELD, 1, "cpu", geom)
    assert r.metadata["stop_reason"] == "time_budget" and r.samples < 1 << 30
    assert r.estimates["rms_radius_mm"].samples == r.samples
