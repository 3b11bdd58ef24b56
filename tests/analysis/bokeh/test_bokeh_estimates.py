"""The bokeh map's per-source statistics for all sources of a stream at once (``stream_estimates``).

Oracle: ``StreamResult.transmission`` / ``centroid`` / ``rms_radius``, one source at a time -- the
vectorised version must give the same bits, batches with non-finite values left out as they leave them.
"""
from __future__ import annotations

import numpy as np

from lensrt.analysis.bokeh.trace import stream_estimates
from lensrt.trace.kernels import N_COUNTS, N_STATS
from lensrt.trace.stream import Grid, StreamResult


def _result(stats: np.ndarray, rays: int) -> StreamResult:
    S, B = stats.shape[:2]
    rng = np.random.default_rng(3)
    return StreamResult(np.zeros((S, 1, 2, 2)), rays, B, stats, np.zeros((S, B, N_COUNTS), dtype=np.int64),
                        rng.uniform(1.0, 5.0, S), 1.0, rng.normal(size=(S, 2)), Grid(2, 2, 0.1), 0.0, "float32",
                        "cpu", "sobol", 0)


def _check(res: StreamResult) -> None:
    est = stream_estimates(res)
    for k in range(len(res.pupil_area_mm2)):
        t, t_se = res.transmission(k)
        c, c_se = res.centroid(k)
        r, r_se = res.rms_radius(k)
        np.testing.assert_array_equal([est["transmission"][k], est["transmission_se"][k]], [t, t_se])
        np.testing.assert_array_equal(est["centroid"][k], c)
        np.testing.assert_array_equal(est["centroid_se"][k], c_se)
        np.testing.assert_array_equal([est["rms_radius"][k], est["rms_radius_se"][k]], [r, r_se])


def test_estimates_of_all_sources_equal_the_per_source_methods_bit_for_bit():
    rng = np.random.default_rng(11)
    S, B, n_b = 37, 32, 1000
    stats = np.zeros((S, B, N_STATS))
    w = rng.uniform(0.5, 1.0, (S, B, n_b))
    x = rng.normal(0.3, 0.2, (S, B, n_b))
    y = rng.normal(-0.1, 0.4, (S, B, n_b))
    stats[..., 0] = rng.integers(600, n_b, (S, B))
    stats[..., 1] = w.sum(axis=2)
    stats[..., 2], stats[..., 3] = (w * x).sum(axis=2), (w * y).sum(axis=2)
    stats[..., 4], stats[..., 5] = (w * x * x).sum(axis=2), (w * y * y).sum(axis=2)
    _check(_result(stats, B * n_b))


def test_batches_with_no_light_are_left_out_as_the_per_source_methods_do():
    rng = np.random.default_rng(5)
    S, B = 4, 8
    stats = rng.uniform(1.0, 2.0, (S, B, N_STATS))
    stats[1, 3, 1:] = 0.0  # source 1: one batch saw nothing (its centroid and radius are NaN there)
    stats[2, :, 1:] = 0.0  # source 2: no batch saw anything (no standard error: NaN pooled values)
    stats[3, 1:, 1:] = 0.0  # source 3: a single batch with light (infinite standard errors)
    res = _result(stats, B * 100)
    _check(res)
    est = stream_estimates(res)
    assert np.isfinite(est["centroid_se"][1]).all() and np.isnan(est["centroid"][2]).all()
    assert np.isinf(est["rms_radius_se"][3]) and np.isinf(est["centroid_se"][3]).all()


def test_the_discs_99th_percentile_is_numpys_bit_for_bit():
    from lensrt.analysis.bokeh.trace import percentile99
    rng = np.random.default_rng(7)
    for n in list(range(1, 120)) + [1000, 1601, 4096]:
        for x in (rng.uniform(0.0, 1.0, n), rng.exponential(3.0, n) ** 3, rng.integers(1, 4, n).astype(float),
                  np.full(n, 0.7)):
            assert percentile99(x.copy()) == np.percentile(x, 99.0)
