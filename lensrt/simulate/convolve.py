"""Spatially varying convolution: bilinear interpolation of node PSFs on the *source* side, FFTs by cell.

The PSF of a source point x' is taken as the bilinear blend of the PSFs of the
four grid nodes around it, h(x'; .) = sum_n w_n(x') h_n (w_n the tent weights).
Then the image is

    out(x) = sum_x' I(x') h(x'; x - x') = sum_n [h_n * (w_n I)](x),

i.e. each node's PSF convolves the image *weighted by that node's tent* (Nagy &
O'Leary, "Restoring images degraded by spatially variant blur", SIAM J. Sci.
Comput. 19(4), 1998; Hirsch et al., "Efficient filter flow", CVPR 2010). There
are no seams: the weights are continuous and sum to 1, a point source anywhere
gets exactly the blended PSF, and light is conserved. (:func:`convolve_varying`
is the float64 reference: one FFT per node's 2 x 2-cell tile.)

Work per depth layer (:func:`convolve_layer`), cell by cell (a cell lies between
four neighbouring nodes, the only ones whose tents are non-zero over it): the
cell's channels weighted by each corner's tent are transformed, multiplied by
that corner's PSF spectrum and the four products summed, so each output channel
takes one inverse FFT per cell. Only the cells that hold some of the layer are
transformed (:func:`tile_plan`), once for all wavelength bands (channel-first
arrays, single-precision real FFTs on every core); the PSF spectra once per node
and layer. The response to a full layer of ones (the normalisation of
:mod:`.compose`) is formed for every cell whose blur reaches where the layer's
does, and the outputs only over that box. The device path (:mod:`.device`) runs
the same cells with Warp's tile FFTs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["convolve_varying", "convolve_layer", "tile_plan", "plan_from_cells", "cell_edges", "meet_box",
           "TilePlan"]


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
    """Which cells one depth layer needs.

    ``cells`` (gr - 1, gc - 1): cells (between neighbouring nodes) holding some of the layer -- these are
    convolved; ``cells_needed``: cells whose response to a full layer of ones is needed (their blur reaches
    where an active cell's blur lands, so the normalisation is exact wherever the layer shows). ``box`` (r0, r1,
    c0, c1): the pixels the layer's blur reaches (the outputs are computed over this box only).
    ``row_edges``/``col_edges``: the cells' pixel bounds (cell i is [edges[i], edges[i + 1])), clipped to the
    picture (a cell may be empty).
    """

    cells: np.ndarray
    cells_needed: np.ndarray
    box: tuple[int, int, int, int]
    row_edges: np.ndarray
    col_edges: np.ndarray


def cell_edges(nodes: np.ndarray, n_px: int) -> np.ndarray:
    """Pixel bounds of the cells between neighbouring ``nodes`` (the last cell closes at the last node, as the
    tents of :func:`lensrt.simulate.psf_grid.hat_weights` do), clipped to [0, n_px]: cell i is
    [edges[i], edges[i + 1])."""
    edges = np.asarray(nodes, dtype=int).copy()
    edges[-1] += 1
    return np.clip(edges, 0, n_px)


def _overlaps(reach: np.ndarray) -> np.ndarray:
    """(n, n): whether the ranges [lo, hi) of ``reach`` (n, 2) overlap."""
    return (reach[:, None, 0] < reach[None, :, 1]) & (reach[None, :, 0] < reach[:, None, 1])


def _cells_present(present: np.ndarray, er: np.ndarray, ec: np.ndarray) -> np.ndarray:
    """(len(er) - 1, len(ec) - 1): whether each cell holds a True of ``present``."""
    out = np.zeros((len(er) - 1, len(ec) - 1), dtype=bool)
    for i in range(len(er) - 1):
        if er[i + 1] > er[i]:
            line = present[er[i]:er[i + 1]].any(axis=0)
            for j in range(len(ec) - 1):
                out[i, j] = ec[j + 1] > ec[j] and bool(line[ec[j]:ec[j + 1]].any())
    return out


def tile_plan(alpha: np.ndarray, rows: np.ndarray, cols: np.ndarray, half: int) -> TilePlan:
    """The :class:`TilePlan` of a layer of coverage ``alpha`` (H, W) blurred by PSFs of half-width ``half``
    (``rows``/``cols``: the node pixels, in ``alpha``'s frame -- they may lie beyond it for a band of rows)."""
    h_img, w_img = alpha.shape
    er, ec = cell_edges(rows, h_img), cell_edges(cols, w_img)
    return plan_from_cells(_cells_present(alpha > 0, er, ec), er, ec, half, alpha.shape)


def plan_from_cells(cells: np.ndarray, er: np.ndarray, ec: np.ndarray, half: int,
                    shape: tuple[int, int]) -> TilePlan:
    """The :class:`TilePlan` of a layer that shows in ``cells`` (bounds ``er``, ``ec`` of
    :func:`cell_edges`) of a picture of ``shape``, blurred by PSFs of half-width ``half``."""
    h_img, w_img = shape
    # a cell reaches its own pixels +- half
    cr = np.stack([np.maximum(er[:-1] - half, 0), np.minimum(er[1:] + half, h_img)], axis=1)
    cc = np.stack([np.maximum(ec[:-1] - half, 0), np.minimum(ec[1:] + half, w_img)], axis=1)
    nonempty = (er[1:] > er[:-1])[:, None] & (ec[1:] > ec[:-1])[None, :]
    cells_needed = nonempty & (np.einsum("ik,jl,kl->ij", _overlaps(cr).astype(int), _overlaps(cc).astype(int),
                                         cells.astype(int)) > 0)
    if not cells.any():
        return TilePlan(cells, cells_needed, (0, 0, 0, 0), er, ec)
    ai, aj = np.nonzero(cells)
    box = (int(cr[ai, 0].min()), int(cr[ai, 1].max()), int(cc[aj, 0].min()), int(cc[aj, 1].max()))
    return TilePlan(cells, cells_needed, box, er, ec)


def meet_box(r0: int, r1: int, c0: int, c1: int, n: int, box: tuple[int, int, int, int]):
    """Where the full convolution of pixels [r0, r1) x [c0, c1) by an n x n kernel meets ``box``: (source
    slices into the full result, destination slices into the box arrays), or None."""
    half = n // 2
    lo_r, hi_r = max(r0 - half, box[0]), min(r1 + half, box[1])
    lo_c, hi_c = max(c0 - half, box[2]), min(c1 + half, box[3])
    if lo_r >= hi_r or lo_c >= hi_c:
        return None
    src = (slice(lo_r - r0 + half, hi_r - r0 + half), slice(lo_c - c0 + half, hi_c - c0 + half))
    dst = (slice(lo_r - box[0], hi_r - box[0]), slice(lo_c - box[2], hi_c - box[2]))
    return src, dst


#: complex values of a cell's summed spectra formed at a time (a few MB: the corners' products stay in cache)
_CHUNK_COMPLEX = 1 << 18


class _NodeSpectra:
    """The PSF spectra of one layer's nodes at one FFT shape, transformed when first asked for (K bands each)
    and dropped with :meth:`drop_row` once no cell needs them."""

    def __init__(self, psfs: np.ndarray, shape: tuple[int, int]):
        self.psfs, self.shape, self.cache = psfs, shape, {}

    def __call__(self, i: int, j: int) -> np.ndarray:
        from scipy import fft
        if (i, j) not in self.cache:
            self.cache[(i, j)] = fft.rfft2(self.psfs[:, i, j], s=self.shape, workers=-1)
        return self.cache[(i, j)]

    def drop_row(self, i: int) -> None:
        for key in [k for k in self.cache if k[0] <= i]:
            del self.cache[key]


def convolve_layer(shared: np.ndarray, own: np.ndarray, psfs: np.ndarray, wr: np.ndarray, wc: np.ndarray,
                   rows: np.ndarray, cols: np.ndarray, plan: TilePlan) -> tuple[np.ndarray, np.ndarray]:
    """One layer, all K bands, on the host (SciPy real FFTs, single precision, every core), cell by cell.

    ``shared`` (S, H, W) channels blurred by every band's PSF; ``own`` (K, H, W) one channel per band, blurred
    by that band's PSF only; ``psfs`` (K, gr, gc, n, n); ``wr`` (gr, H), ``wc`` (gc, W) the tents in the
    arrays' frame. Returns over ``plan.box``: the blurred channels (K, S + 1, bh, bw) -- band k's blur of the S
    shared channels, then of its own -- and the response to a full layer of ones (K, bh, bw).

    Per cell, its four corner nodes' tent-weighted channels are transformed (4 (S + K) forward FFTs), multiplied
    by the nodes' PSF spectra (transformed once per node and layer) and *summed in the frequency domain*, so
    each output channel takes one inverse FFT per cell: a pixel's light is transformed back once, not four times
    as with one FFT per node tile. The full-layer response is formed the same way from the tents' spectra
    (separable: the outer product of two 1-D FFTs).
    """
    from scipy import fft
    n_b, n = psfs.shape[0], psfs.shape[-1]
    er, ec = plan.row_edges, plan.col_edges
    r0b, r1b, c0b, c1b = plan.box
    n_s = shared.shape[0]
    out = np.zeros((n_b, n_s + 1, r1b - r0b, c1b - c0b), dtype=np.float32)
    ones = np.zeros((n_b, r1b - r0b, c1b - c0b), dtype=np.float32)
    if not plan.cells.any():
        return out, ones
    shape = (fft.next_fast_len(int(np.diff(er).max()) + n - 1, True),
             fft.next_fast_len(int(np.diff(ec).max()) + n - 1, True))
    spectra = _NodeSpectra(psfs, shape)
    for ci in range(len(er) - 1):
        for cj in range(len(ec) - 1):
            if plan.cells_needed[ci, cj]:
                _cell(shared, own, spectra, wr, wc, ci, cj, plan, n, out, ones)
        spectra.drop_row(ci)
    return out, ones


def _cell(shared, own, spectra: _NodeSpectra, wr, wc, ci: int, cj: int, plan: TilePlan, n: int,
          out: np.ndarray, ones: np.ndarray) -> None:
    """Add cell (ci, cj)'s full-layer response and (if it holds some of the layer) its blur into the box."""
    from scipy import fft
    r0, r1 = int(plan.row_edges[ci]), int(plan.row_edges[ci + 1])
    c0, c1 = int(plan.col_edges[cj]), int(plan.col_edges[cj + 1])
    where = meet_box(r0, r1, c0, c1, n, plan.box)
    if where is None:
        return
    (sr, sc), (dr, dc) = where
    shape = spectra.shape
    corners = [(ci + a, cj + b) for a in (0, 1) for b in (0, 1)]
    tents_r = {i: wr[i, r0:r1].astype(np.float32) for i in (ci, ci + 1)}
    tents_c = {j: wc[j, c0:c1].astype(np.float32) for j in (cj, cj + 1)}
    # the full-layer response: sum over the corners of (tent spectrum x PSF spectrum), one inverse per band
    # (a tent's spectrum is the outer product of its row and column spectra: two broadcast products)
    acc = None
    for i, j in corners:
        term = spectra(i, j) * fft.fft(wr[i, r0:r1], shape[0]).astype(np.complex64)[:, None]
        term *= fft.rfft(wc[j, c0:c1], shape[1]).astype(np.complex64)[None, :]
        acc = term if acc is None else np.add(acc, term, out=acc)
    ones[:, dr, dc] += _inverse(acc, shape, sr, sc)
    if not plan.cells[ci, cj]:
        return
    n_s, n_b = shared.shape[0], out.shape[0]
    spec = _cell_spectra(np.concatenate([shared[:, r0:r1, c0:c1], own[:, r0:r1, c0:c1]]), n_s, n_b, corners,
                         tents_r, tents_c, spectra)
    out[:, :, dr, dc] += _inverse(spec, shape, sr, sc)


def _cell_spectra(x: np.ndarray, n_s: int, n_b: int, corners, tents_r: dict, tents_c: dict,
                  spectra: _NodeSpectra) -> np.ndarray:
    """(K, S + 1, fy, fx): per band, the sum over the cell's corners of (the corner's tent-weighted channels'
    spectrum x its PSF spectrum) -- the S shared channels and the band's own one. A tent is separable, a(row)
    b(col), and the row-by-row real FFT comes first, so ``x`` b is transformed along its rows once per corner
    column, scaled by a, and only then transformed along the columns (zero rows are not transformed)."""
    from scipy import fft
    p, q = spectra.shape
    n_c, h, w = x.shape
    # the tent-weighted channels are written straight into zero-padded buffers, transformed in place
    buf = np.empty((n_c, h, q), dtype=np.float32)
    buf[:, :, w:] = 0.0
    half_spec = {}
    for j in sorted(tents_c):
        np.multiply(x, tents_c[j][None, None, :], out=buf[:, :, :w])
        half_spec[j] = fft.rfft(buf, axis=-1, workers=-1)
    f_x = []
    for i, j in corners:
        col = np.empty((n_c, p, half_spec[j].shape[-1]), dtype=half_spec[j].dtype)
        col[:, h:] = 0.0
        np.multiply(half_spec[j], tents_r[i][None, :, None], out=col[:, :h])
        f_x.append(fft.fft(col, axis=-2, workers=-1, overwrite_x=True))
    k_f = [spectra(i, j) for i, j in corners]
    del half_spec, buf
    fx = f_x[0].shape[-1]
    spec = np.empty((n_b, n_s + 1, p, fx), dtype=f_x[0].dtype)
    step = max(1, _CHUNK_COMPLEX // (n_b * (n_s + 1) * fx))
    tmp = np.empty((n_b, n_s, step, fx), dtype=spec.dtype)
    # a few frequency rows at a time, so that the four corners' products are summed in cache
    for y0 in range(0, p, step):
        y1 = min(y0 + step, p)
        out, t = spec[:, :, y0:y1], tmp[:, :, :y1 - y0]
        for c in range(4):
            x_c, h_c = f_x[c][:, y0:y1], k_f[c][:, y0:y1]
            if c == 0:
                np.multiply(x_c[None, :n_s], h_c[:, None], out=out[:, :n_s])
                np.multiply(x_c[n_s:], h_c, out=out[:, n_s])
            else:
                np.multiply(x_c[None, :n_s], h_c[:, None], out=t)
                out[:, :n_s] += t
                np.multiply(x_c[n_s:], h_c, out=t[:, 0])
                out[:, n_s] += t[:, 0]
    return spec


def _inverse(spec: np.ndarray, shape: tuple[int, int], sr: slice, sc: slice) -> np.ndarray:
    """The inverse real 2-D FFT of ``spec`` (..., fy, fx) at ``shape``, over rows ``sr`` and columns ``sc``
    only (the columns' transform runs on the rows kept)."""
    from scipy import fft
    half = fft.ifft(spec, n=shape[0], axis=-2, workers=-1, overwrite_x=True)[..., sr, :]
    return fft.irfft(half, n=shape[1], axis=-1, workers=-1)[..., sc]
