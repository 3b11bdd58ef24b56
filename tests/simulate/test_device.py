"""The device path of lensrt.simulate (Warp kernels and tile FFTs) against the host path (NumPy/SciPy).

Run on the CPU through Warp (``backend="warp"``: the same kernels, and the same cooperative tile-FFT
code as a GPU build without cuFFTDx), and on ``cuda:0`` when Warp sees one.
"""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.simulate.pipeline import SimulateOptions, simulate


def _devices():
    import warp as wp
    wp.init()
    return ["cpu"] + (["cuda:0"] if wp.is_cuda_available() else [])


def _scene(rows: int, cols: int):
    rng = np.random.default_rng(3)
    img = rng.random((rows, cols, 3)).astype(np.float32)
    depth = np.full((rows, cols), 4.0)
    depth[:, cols // 2:] = 1.0           # a near half with an occluding edge
    depth[rows // 3:2 * rows // 3, :cols // 4] = 10.0
    return img, depth


@pytest.mark.parametrize("device", _devices())
def test_device_path_equals_host_path(device, tmp_path):
    """Same coefficients, sRGB, Y standard error and frame overflow as the host path (single precision)."""
    img, depth = _scene(42, 56)
    base = dict(sensor="24x18", focus_m=2.0, grid=(3, 4), rays=1 << 11, ri_rays=1 << 12, bands=2, layers=3,
                cache_dir=str(tmp_path), device="cpu")
    host = simulate(img, load_lens("dgauss_50mm_f2"), depth, SimulateOptions(**base, backend="host"))
    base["device"] = device
    dev = simulate(img, load_lens("dgauss_50mm_f2"), depth, SimulateOptions(**base, backend="warp"))
    assert "Warp tile FFTs" in dev.notes[0] and "host" in host.notes[0]
    scale = float(np.abs(host.rgb).max())
    np.testing.assert_allclose(dev.coefficients, host.coefficients, atol=2e-5 * scale)
    np.testing.assert_allclose(dev.rgb, host.rgb, atol=2e-5 * scale)
    # the variance is a difference of near-equal single-precision sums: compare it, not its square root
    var_h, var_d = host.y_stderr.astype(np.float64) ** 2, dev.y_stderr.astype(np.float64) ** 2
    np.testing.assert_allclose(var_d, var_h, atol=1e-3 * float(var_h.max()))
    assert dev.outside_fraction == pytest.approx(host.outside_fraction)


def test_device_path_without_a_depth_map_equals_host_path(tmp_path):
    """One layer everywhere (no mask: every cell flagged without the flag kernel)."""
    img, _ = _scene(42, 56)
    base = dict(sensor="24x18", focus_m=2.0, grid=(3, 4), rays=1 << 11, ri_rays=1 << 12, bands=2,
                cache_dir=str(tmp_path), device="cpu")
    host = simulate(img, load_lens("dgauss_50mm_f2"), None, SimulateOptions(**base, backend="host"))
    dev = simulate(img, load_lens("dgauss_50mm_f2"), None, SimulateOptions(**base, backend="warp"))
    scale = float(np.abs(host.rgb).max())
    np.testing.assert_allclose(dev.coefficients, host.coefficients, atol=2e-5 * scale)
    np.testing.assert_allclose(dev.rgb, host.rgb, atol=2e-5 * scale)


def test_tile_fft_rows_match_numpy():
    """The row-FFT kernel (wp.tile_fft) is numpy.fft.fft along rows, forward and inverse (unnormalised)."""
    import warp as wp
    from lensrt.simulate.device import fft_rows
    rng = np.random.default_rng(0)
    for n in (8, 64):
        x = rng.standard_normal((3, n)) + 1j * rng.standard_normal((3, n))
        a = wp.array(np.stack([x.real, x.imag], -1).astype(np.float32), dtype=wp.vec2f, device="cpu")
        wp.launch_tiled(fft_rows(n, False), dim=[3], inputs=[a], block_dim=max(1, n // 4), device="cpu")
        got = a.numpy()
        np.testing.assert_allclose(got[..., 0] + 1j * got[..., 1], np.fft.fft(x, axis=1), atol=1e-4 * n)
        wp.launch_tiled(fft_rows(n, True), dim=[3], inputs=[a], block_dim=max(1, n // 4), device="cpu")
        got = a.numpy()
        np.testing.assert_allclose((got[..., 0] + 1j * got[..., 1]) / n, x, atol=1e-4)


def test_cuda_without_a_gpu_is_one_clear_error(tmp_path):
    """--device cuda where Warp sees no GPU: one LensrtError, never a silent host run."""
    import warp as wp
    from lensrt.errors import LensrtError
    wp.init()
    if wp.is_cuda_available():
        pytest.skip("a CUDA device is present")
    img, depth = _scene(24, 32)
    with pytest.raises(LensrtError, match="no CUDA device"):
        simulate(img, load_lens("dgauss_50mm_f2"), depth,
                 SimulateOptions(sensor="24x18", grid=(3, 3), rays=1 << 10, ri_rays=1 << 12, bands=2, layers=2,
                                 cache_dir=str(tmp_path), device="cuda"))
