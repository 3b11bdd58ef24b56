"""Spatially varying convolution: bilinear interpolation of node PSFs on the *source* side, FFT tiles.

The PSF of a source point x' is taken as the bilinear blend of the PSFs of the
four grid nodes around it, h(x'; .) = sum_n w_n(x') h_n (w_n the tent weights).
Then the image is

    out(x) = sum_x' I(x') h(x'; x - x') = sum_n [h_n * (w_n I)](x),

i.e. each node's PSF convolves the image *weighted by that node's tent* (Nagy &
O'Leary, "Restoring images degraded by spatially variant blur", SIAM J. Sci.
Comput. 19(4), 1998; Hirsch et al., "Efficient filter flow", CVPR 2010). A tent
is non-zero only over the two cells either side of its node, so each node
convolves one overlapping tile (2 x 2 cells) by FFT (``scipy.signal.fftconvolve``),
and the tiles add. There are no seams: the weights are continuous and sum to 1,
a point source anywhere gets exactly the blended PSF, and light is conserved.
"""
from __future__ import annotations

import numpy as np

__all__ = ["convolve_varying", "convolve_bands"]


def convolve_varying(image: np.ndarray, psf: np.ndarray, wr: np.ndarray, wc: np.ndarray,
                     rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Blur ``image`` (H, W, C) by node PSFs ``psf`` (gr, gc, n, n) (n odd, centred), tent weights ``wr`` (gr, H) and
    ``wc`` (gc, W) on node pixels ``rows``, ``cols``; returns (H, W, C) float64."""
    from scipy.fft import set_workers
    from scipy.signal import fftconvolve
    h_img, w_img, n_ch = image.shape
    half = psf.shape[-1] // 2
    out = np.zeros((h_img + 2 * half, w_img + 2 * half, n_ch))
    for i in range(len(rows)):
        r0, r1 = int(rows[max(i - 1, 0)]), int(rows[min(i + 1, len(rows) - 1)]) + 1
        for j in range(len(cols)):
            c0, c1 = int(cols[max(j - 1, 0)]), int(cols[min(j + 1, len(cols) - 1)]) + 1
            tile = image[r0:r1, c0:c1] * (wr[i, r0:r1, None, None] * wc[j, c0:c1][None, :, None])
            if not np.any(tile):
                continue
            k = psf[i, j].astype(np.float64)[:, :, None]
            with set_workers(-1):  # the FFTs on every core
                out[r0:r1 + 2 * half, c0:c1 + 2 * half] += fftconvolve(tile, k, mode="full", axes=(0, 1))
    return out[half:half + h_img, half:half + w_img]


def _tile_bounds(k: int, nodes: np.ndarray) -> tuple[int, int]:
    """Pixel range [start, stop) of node k's tent (the cells either side)."""
    return int(nodes[max(k - 1, 0)]), int(nodes[min(k + 1, len(nodes) - 1)]) + 1


def convolve_bands(image: np.ndarray, psfs: np.ndarray, mix: np.ndarray, wr: np.ndarray, wc: np.ndarray,
                   rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`convolve_varying` for K bands at once, sharing each tile's forward FFT between the bands.

    ``image`` (H, W, C); ``psfs`` (K, gr, gc, n, n); ``mix`` (K, O, C) mixes the input channels into O output
    channels per band (linear, so it is applied to the spectra). Returns (K, H, W, O) and, for a uniform image
    of ones, the full-layer response (K, H, W) -- both with the same tiles, kernels and weights.
    """
    from scipy import fft
    h_img, w_img, _ = image.shape
    n_b, n_out = mix.shape[0], mix.shape[1]
    n = psfs.shape[-1]
    half = n // 2
    out = np.zeros((n_b, h_img + 2 * half, w_img + 2 * half, n_out), dtype=np.float32)  # float32: memory
    ones = np.zeros((n_b, h_img + 2 * half, w_img + 2 * half), dtype=np.float32)
    for i in range(len(rows)):
        r0, r1 = _tile_bounds(i, rows)
        for j in range(len(cols)):
            c0, c1 = _tile_bounds(j, cols)
            wt = wr[i, r0:r1, None] * wc[j, c0:c1][None, :]
            shape = (fft.next_fast_len(r1 - r0 + n - 1, True), fft.next_fast_len(c1 - c0 + n - 1, True))
            # single precision FFTs (about 1e-7 of the signal; accumulated in float64)
            kf = fft.rfft2(psfs[:, i, j].astype(np.float32), s=shape, axes=(1, 2), workers=-1)  # (K, fy, fx)
            f_one = fft.rfft2(wt.astype(np.float32), s=shape, workers=-1)
            u = fft.irfft2(kf * f_one[None], s=shape, axes=(1, 2), workers=-1)
            ones[:, r0:r1 + 2 * half, c0:c1 + 2 * half] += u[:, :r1 - r0 + n - 1, :c1 - c0 + n - 1]
            tile = image[r0:r1, c0:c1] * wt[..., None]
            if not np.any(tile):
                continue
            f_img = fft.rfft2(tile.astype(np.float32), s=shape, axes=(0, 1), workers=-1)  # (fy, fx, C)
            spec = np.matmul(f_img[None], mix.transpose(0, 2, 1)[:, None].astype(f_img.dtype)) * kf[..., None]
            res = fft.irfft2(spec, s=shape, axes=(1, 2), workers=-1)
            out[:, r0:r1 + 2 * half, c0:c1 + 2 * half] += res[:, :r1 - r0 + n - 1, :c1 - c0 + n - 1]
    return out[:, half:half + h_img, half:half + w_img], ones[:, half:half + h_img, half:half + w_img]
