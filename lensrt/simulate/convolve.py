"""Spatially varying convolution: bilinear interpolation of node PSFs on the *source* side, FFT tiles.

The PSF of a source point x' is taken as the bilinear blend of the PSFs of the
four grid nodes around it, h(x'; .) = sum_n w_n(x') h_n (w_n the tent weights).
Then the image is

    out(x) = sum_x' I(x') h(x'; x - x') = sum_n [h_n * (w_n I)](x),

i.e. each node's PSF convolves the image *weighted by that node's tent* (Nagy &
O'Leary, "Restoring images degraded by spatially variant blur", SIAM J. Sci.
Comput. 19(4), 1998; Hirsch et al., "Efficient filter flow", CVPR 2010). A tent
is non-zero only over the two cells either side of its node, so each node
convolves one overlapping tile (2 x 2 cells) by FFT, and the tiles add. There
are no seams: the weights are continuous and sum to 1, a point source anywhere
gets exactly the blended PSF, and light is conserved.

Work per depth layer (:func:`convolve_layer`): only the tiles that hold some of
the layer are transformed (:func:`tile_plan`), once for all wavelength bands
(channel-first arrays, single-precision real FFTs on every core); each band's
PSF spectrum multiplies them. The response to a full layer of ones (the
normalisation of :mod:`.compose`) is formed for every tile whose blur reaches
where the layer's does, and the outputs only over that box. The device path
(:mod:`.device`) runs the same tiles with Warp's tile FFTs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["convolve_varying", "convolve_layer", "tile_plan", "tile_bounds", "tile_window", "TilePlan"]


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


@dataclass(frozen=True)
class TilePlan:
    """Which node tiles one depth layer needs.

    ``active`` (gr, gc): tiles holding some of the layer (their image part is convolved); ``needed`` (gr, gc):
    tiles whose response to a full layer of ones is needed -- every tile whose blur reaches where an active
    tile's blur lands (so the normalisation is exact wherever the layer shows); ``box`` (r0, r1, c0, c1): the
    image pixels the layer's blur reaches (the outputs are computed over this box only).
    """

    active: np.ndarray
    needed: np.ndarray
    box: tuple[int, int, int, int]


def tile_bounds(k: int, nodes: np.ndarray) -> tuple[int, int]:
    """Pixel range [start, stop) of node k's tent (the cells either side)."""
    return int(nodes[max(k - 1, 0)]), int(nodes[min(k + 1, len(nodes) - 1)]) + 1


def _reach(nodes: np.ndarray, half: int, n_px: int) -> np.ndarray:
    """(nodes, 2): the image-pixel range [lo, hi) node k's tile reaches after a blur of half-width ``half``."""
    out = np.empty((len(nodes), 2), dtype=int)
    for k in range(len(nodes)):
        a, b = tile_bounds(k, nodes)
        out[k] = max(a - half, 0), min(b + half, n_px)
    return out


def tile_plan(alpha: np.ndarray, rows: np.ndarray, cols: np.ndarray, half: int) -> TilePlan:
    """The :class:`TilePlan` of a layer of coverage ``alpha`` (H, W) blurred by PSFs of half-width ``half``."""
    h_img, w_img = alpha.shape
    gr, gc = len(rows), len(cols)
    present = alpha > 0
    # per cell (between neighbouring nodes; the last node row/column closes the last cell): any of the layer?
    by_rows = np.logical_or.reduceat(present, [int(r) for r in rows[:-1]], axis=0)
    cells = np.logical_or.reduceat(by_rows, [int(c) for c in cols[:-1]], axis=1)
    active = np.zeros((gr, gc), dtype=bool)
    for i in range(gr):
        for j in range(gc):
            active[i, j] = bool(cells[max(i - 1, 0):min(i, gr - 2) + 1, max(j - 1, 0):min(j, gc - 2) + 1].any())
    rr, rc = _reach(rows, half, h_img), _reach(cols, half, w_img)
    over_r = (rr[:, None, 0] < rr[None, :, 1]) & (rr[None, :, 0] < rr[:, None, 1])
    over_c = (rc[:, None, 0] < rc[None, :, 1]) & (rc[None, :, 0] < rc[:, None, 1])
    needed = np.einsum("ik,jl,kl->ij", over_r.astype(int), over_c.astype(int), active.astype(int)) > 0
    if not active.any():
        return TilePlan(active, needed, (0, 0, 0, 0))
    ai, aj = np.nonzero(active)
    box = (int(rr[ai, 0].min()), int(rr[ai, 1].max()), int(rc[aj, 0].min()), int(rc[aj, 1].max()))
    return TilePlan(active, needed, box)


def tile_window(i: int, j: int, rows: np.ndarray, cols: np.ndarray, n: int, box: tuple[int, int, int, int]):
    """Tile (i, j): its pixels (r0, r1, c0, c1), and where its full convolution (offset by -n // 2) meets the
    box: (source slices into the full result, destination slices into the box arrays), or None."""
    r0, r1 = tile_bounds(i, rows)
    c0, c1 = tile_bounds(j, cols)
    half = n // 2
    lo_r, hi_r = max(r0 - half, box[0]), min(r1 + half, box[1])
    lo_c, hi_c = max(c0 - half, box[2]), min(c1 + half, box[3])
    if lo_r >= hi_r or lo_c >= hi_c:
        return (r0, r1, c0, c1), None
    src = (slice(lo_r - r0 + half, hi_r - r0 + half), slice(lo_c - c0 + half, hi_c - c0 + half))
    dst = (slice(lo_r - box[0], hi_r - box[0]), slice(lo_c - box[2], hi_c - box[2]))
    return (r0, r1, c0, c1), (src, dst)


def convolve_layer(shared: np.ndarray, own: np.ndarray, psfs: np.ndarray, wr: np.ndarray, wc: np.ndarray,
                   rows: np.ndarray, cols: np.ndarray, plan: TilePlan) -> tuple[np.ndarray, np.ndarray]:
    """One layer, all K bands, on the host (NumPy/SciPy FFTs, single precision, both cores).

    ``shared`` (S, H, W) channels blurred by every band's PSF; ``own`` (K, H, W) one channel per band, blurred
    by that band's PSF only; ``psfs`` (K, gr, gc, n, n). Returns over ``plan.box``: the blurred channels
    (K, S + 1, bh, bw) -- band k's blur of the S shared channels, then of its own -- and the response to a
    full layer of ones (K, bh, bw). Each active tile is transformed once for all bands.
    """
    from scipy import fft
    n_b, n = psfs.shape[0], psfs.shape[-1]
    r0b, r1b, c0b, c1b = plan.box
    n_s = shared.shape[0]
    out = np.zeros((n_b, n_s + 1, r1b - r0b, c1b - c0b), dtype=np.float32)
    ones = np.zeros((n_b, r1b - r0b, c1b - c0b), dtype=np.float32)
    for i, j in zip(*np.nonzero(plan.needed)):
        (r0, r1, c0, c1), where = tile_window(int(i), int(j), rows, cols, n, plan.box)
        if where is None:
            continue
        (sr, sc), (dr, dc) = where
        shape = (fft.next_fast_len(r1 - r0 + n - 1, True), fft.next_fast_len(c1 - c0 + n - 1, True))
        wt = (wr[i, r0:r1, None] * wc[j, c0:c1][None, :]).astype(np.float32)
        kf = fft.rfft2(psfs[:, i, j].astype(np.float32), s=shape, workers=-1)  # (K, fy, fx) complex64
        kf_w = kf * fft.rfft2(wt, s=shape, workers=-1)
        ones[:, dr, dc] += fft.irfft2(kf_w, s=shape, workers=-1)[:, sr, sc]
        if not plan.active[i, j]:
            continue
        x = np.concatenate([shared[:, r0:r1, c0:c1], own[:, r0:r1, c0:c1]]) * wt
        f_x = fft.rfft2(x, s=shape, workers=-1)  # (S + K, fy, fx)
        spec = np.empty((n_b, n_s + 1) + f_x.shape[1:], dtype=f_x.dtype)
        np.multiply(f_x[None, :n_s], kf[:, None], out=spec[:, :n_s])
        np.multiply(f_x[n_s:], kf, out=spec[:, n_s])
        out[:, :, dr, dc] += fft.irfft2(spec, s=shape, workers=-1)[:, :, sr, sc]
    return out, ones
