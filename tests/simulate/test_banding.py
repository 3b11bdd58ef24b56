"""Pictures beyond the memory budget: the host blur in bands of rows equals the whole-picture blur."""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.simulate.banding import MIN_BAND_ROWS, fixed_bytes, plan_row_bands, window_bytes
from lensrt.simulate.pipeline import SimulateOptions, simulate


def _scene(rows: int, cols: int):
    rng = np.random.default_rng(5)
    img = rng.random((rows, cols, 3)).astype(np.float32)
    depth = np.full((rows, cols), 4.0)
    depth[:, cols // 2:] = 0.8           # a near, strongly blurred half with an occluding edge
    depth[rows // 3:2 * rows // 3, :cols // 4] = 10.0
    return img, depth


def test_banded_run_equals_the_whole_picture(tmp_path):
    """A budget that forces bands of rows (with the PSFs' halo) gives the whole-picture result: coefficients,
    sRGB, Y error and the frame-overflow fraction, to single-precision rounding."""
    img, depth = _scene(96, 64)
    base = dict(sensor="24x36", focus_m=2.0, grid=(4, 3), rays=1 << 11, ri_rays=1 << 12, bands=2, layers=3,
                cache_dir=str(tmp_path))
    lens = load_lens("dgauss_50mm_f2")
    whole = simulate(img, lens, depth, SimulateOptions(**base))
    assert "bands" not in whole.notes[0]
    n_px = max(p.shape[-1] for p in whole.psf_grid.psf)
    halo = n_px // 2
    assert halo >= 2  # the near layer's blur crosses the bands' borders
    cell_cols = int(np.diff(whole.psf_grid.node_cols).max()) + 1
    budget = fixed_bytes(img.shape[:2], 2) + window_bytes(20 + 2 * halo, 64, 2, cell_cols, n_px)
    banded = simulate(img, lens, depth, SimulateOptions(**base, max_memory_bytes=budget))
    assert "bands of up to" in banded.notes[0]
    count = int(banded.notes[0].split(" in ")[1].split()[0])
    assert count >= 4
    scale = float(np.abs(whole.rgb).max())
    np.testing.assert_allclose(banded.coefficients, whole.coefficients, atol=2e-6 * scale)
    np.testing.assert_allclose(banded.rgb, whole.rgb, atol=2e-6 * scale)
    var_w, var_b = whole.y_stderr.astype(np.float64) ** 2, banded.y_stderr.astype(np.float64) ** 2
    np.testing.assert_allclose(var_b, var_w, atol=1e-4 * float(var_w.max()))
    assert banded.outside_fraction == pytest.approx(whole.outside_fraction, abs=1e-12)


def test_row_bands_cover_the_picture_within_the_budget():
    shape, k, halo, cell, n_px = (3000, 4000), 4, 100, 700, 201
    fixed = fixed_bytes(shape, k)
    for budget_gib in (1.5, 2.0, 4.0):
        budget = int(budget_gib * 2**30)
        bands = plan_row_bands(shape, k, halo, cell, n_px, budget)
        assert bands[0][0] == 0 and bands[-1][1] == shape[0]
        assert all(a[1] == b[0] for a, b in zip(bands, bands[1:]))  # contiguous, no gap, no overlap
        tallest = max(r1 - r0 for r0, r1 in bands)
        assert tallest >= MIN_BAND_ROWS
        assert fixed + window_bytes(min(tallest + 2 * halo, shape[0]), shape[1], k, cell, n_px) <= budget
        if len(bands) > 1:  # as few bands as fit: one band fewer would be too tall
            fewer = -(-shape[0] // (len(bands) - 1))
            assert fixed + window_bytes(min(fewer + 2 * halo, shape[0]), shape[1], k, cell, n_px) > budget
    assert plan_row_bands(shape, k, halo, cell, n_px, 1 << 40) == [(0, shape[0])]
    with pytest.raises(LensrtError, match="even in bands of 16 rows"):
        plan_row_bands(shape, k, halo, cell, n_px, fixed + 1)


def test_a_budget_below_the_outputs_or_one_band_is_one_clear_error(tmp_path):
    """Both before any PSF is traced: the whole input and outputs, then the thinnest band."""
    img, _ = _scene(48, 64)
    for budget, text in ((1000, "input and outputs alone"), (fixed_bytes((48, 64), 4) + 1000, "even in bands of 16")):
        with pytest.raises(LensrtError, match=text):
            simulate(img, load_lens("dgauss_50mm_f2"), None,
                     SimulateOptions(sensor="24x18", rays=1 << 11, ri_rays=1 << 12, cache_dir=str(tmp_path),
                                     max_memory_bytes=budget))
        assert not any(tmp_path.iterdir())  # nothing traced or cached


def test_depth_layers_take_the_map_s_few_distinct_depths_exactly():
    """A map of at most ``layers`` distinct depths gets exactly those as layers (far first); one more distinct
    depth -- even a single pixel that a strided sample misses -- gives layers evenly spaced in 1/depth."""
    from lensrt.simulate.compose import assign_layers, layer_depths_mm
    rng = np.random.default_rng(7)
    levels_m = np.array([0.8, 1.3, 2.0, 4.5, 9.0])
    depth = levels_m[rng.integers(0, 5, (600, 800))]
    got = layer_depths_mm(depth, 8)
    np.testing.assert_allclose(got, np.sort(1000.0 * levels_m)[::-1], rtol=1e-12)
    idx, err = assign_layers(depth, got)
    assert err < 1e-12
    np.testing.assert_allclose(got[idx] / 1000.0, depth, rtol=1e-12)
    depth[123, 322] = 3.0  # a sixth depth, one pixel, off the strided sample's grid (every 7th pixel)
    assert (123 * 800 + 322) % (depth.size // 65536) != 0
    assert len(layer_depths_mm(depth, 5)) == 5
    np.testing.assert_allclose(1000.0 / layer_depths_mm(depth, 5), np.linspace(1 / 9.0, 1 / 0.8, 5))
    np.testing.assert_allclose(layer_depths_mm(depth, 6), np.sort(1000.0 * np.append(levels_m, 3.0))[::-1],
                               rtol=1e-12)
