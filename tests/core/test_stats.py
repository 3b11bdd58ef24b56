"""Monte Carlo statistics: batch means and jackknife standard errors are calibrated."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.stats import Estimate, ProgressiveRun, StopRule, batch_means, fit_loglog_slope, jackknife


def test_batch_means_matches_known_variance() -> None:
    rng = np.random.default_rng(1)
    # 32 batches of 1000 uniform samples: se of the mean = sqrt(1/12 / 32000)
    batches = rng.random((32, 1000)).mean(axis=1)
    mean, se = batch_means(batches)
    assert abs(mean - 0.5) < 4 * math.sqrt(1 / 12 / 32000)
    assert se == pytest.approx(math.sqrt(1 / 12 / 32000), rel=0.35)


def test_jackknife_of_rms_radius_is_calibrated() -> None:
    """Across repeated seeded runs, |estimate - truth| / se behaves like a standard normal."""
    sigma = 2.0  # 2-D Gaussian spot: RMS radius = sqrt(2) sigma
    truth = math.sqrt(2.0) * sigma
    z = []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        xy = rng.normal(0, sigma, size=(16, 500, 2))
        sums = (np.full(16, 500.0), xy[..., 0].sum(1), xy[..., 1].sum(1), (xy ** 2).sum(axis=(1, 2)))

        def rms(w, sx, sy, sr2):
            cx, cy = sx / w, sy / w
            return math.sqrt(sr2 / w - cx * cx - cy * cy)

        value, se = jackknife(sums, rms)
        z.append((value - truth) / se)
    z = np.asarray(z)
    # coverage of +-1.96 se should be ~95 %: allow 90..99 % for 200 runs
    coverage = np.mean(np.abs(z) < 1.96)
    assert 0.90 <= coverage <= 0.99
    assert abs(np.mean(z)) < 0.25


def test_jackknife_array_statistic() -> None:
    rng = np.random.default_rng(3)
    hist = rng.poisson(100.0, size=(8, 5)).astype(float)
    value, se = jackknife(hist, lambda h: h / h.sum())
    assert value.shape == (5,) and se.shape == (5,) and np.all(se > 0)
    assert value.sum() == pytest.approx(1.0)


def test_stop_rule_and_progressive_run() -> None:
    rule = StopRule(target_error=0.1, max_samples=10_000)
    run = ProgressiveRun(rule)
    errors = [1.0, 0.5, 0.2, 0.09, 0.05]
    stopped_at = None
    for i, e in enumerate(errors):
        run.add(100)
        run.record(1.0, e)
        if run.should_stop(e):
            stopped_at = i
            break
    assert stopped_at == 3 and run.stop_reason == "target_error"
    assert len(run.history) == 4 and run.history[-1].samples == 400
    with pytest.raises(ValueError):
        StopRule()


def test_loglog_slope() -> None:
    t = np.logspace(-2, 1, 10)
    assert fit_loglog_slope(t, 3.0 * t ** -0.5) == pytest.approx(-0.5)


def test_estimate_dict_and_text() -> None:
    e = Estimate(1.5, 0.01, 1000, 0.2, "batch means", "mm")
    d = e.to_dict()
    assert d["samples"] == 1000 and d["stderr"] == 0.01 and d["unit"] == "mm"
    assert "1000" in str(e) or "1e+03" in str(e)
    assert e.relative_stderr == pytest.approx(0.01 / 1.5)
