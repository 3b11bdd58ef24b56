"""The host blur in horizontal bands of rows, within a memory budget.

A picture whose working memory exceeds the budget is simulated band by band:
for output rows [R0, R1), every layer is warped over the rows [R0 - h, R1 + h)
(h the largest PSF half-width of all layers: the only rows whose light can land
in the band), blurred cell by cell over that window
(:func:`lensrt.simulate.convolve.convolve_layer`, the node tents taken from the
whole frame) and composited over the band's rows only. The operator is the same
as for the whole picture, so the bands join without seams: a banded run equals
the whole-picture run to single-precision rounding (tests/simulate/test_banding.py).
What stays whole: the input picture and its layer fill, and the outputs (the
per-band coefficients, linear sRGB and Y error); only the blur's working set --
compositing accumulators, the layer's channels and blur, the FFT scratch -- scales
with the band. A budget too small for even one band of :data:`MIN_BAND_ROWS`
rows is one clear error.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.budget import format_bytes
from ..errors import LensrtError
from .compose import Compositor, blur_and_composite, geometry, warp_layer

__all__ = ["plan_row_bands", "blur_host", "fixed_bytes", "window_bytes", "MIN_BAND_ROWS"]

#: the thinnest band of rows worth running (thinner ones would mostly redo the halo)
MIN_BAND_ROWS = 16


def fixed_bytes(shape: tuple[int, int], bands: int) -> int:
    """Memory (bytes) held for the whole picture whatever the bands: the input and its layer fill (colour
    twice, layer index), the outputs (K x 3 coefficients, linear sRGB, Y error), float32 words."""
    return int(shape[0] * shape[1] * 4 * (3 * bands + 12))


def window_bytes(rows: int, cols: int, bands: int, cell_cols: int, psf_px: int) -> int:
    """Working memory (bytes) of a window of ``rows`` x ``cols`` pixels: per pixel the compositing accumulators
    (5 per band), a layer's blur over its box and its temporaries (11 per band), the layer's channels, the
    float64 geometry and warp temporaries (32 words); plus one cell's FFT scratch (about 12 words per band and
    8 more per padded pixel of a cell ``cell_cols`` wide, grown by the PSF's ``psf_px``)."""
    cell = (rows + psf_px) * (cell_cols + psf_px) * 4 * (12 * bands + 8)
    return int(rows * cols * 4 * (16 * bands + 32) + cell)


def plan_row_bands(shape: tuple[int, int], bands: int, halo: int, cell_cols: int, psf_px: int,
                   budget_bytes: int) -> list[tuple[int, int]]:
    """Bands of rows [(r0, r1), ...] covering the picture, as few as fit ``budget_bytes`` (each band's window
    is its rows +- ``halo``); the whole picture as one band when it fits. One clear error if even a band of
    :data:`MIN_BAND_ROWS` rows does not fit."""
    h, w = shape
    fixed = fixed_bytes(shape, bands)

    def need(rows: int) -> int:
        return fixed + window_bytes(min(rows + 2 * halo, h), w, bands, cell_cols, psf_px)

    if need(h) <= budget_bytes:
        return [(0, h)]
    least = min(MIN_BAND_ROWS, h)
    if need(least) > budget_bytes:
        raise LensrtError(f"a {w} x {h} picture needs {format_bytes(need(least))} of working memory even in bands "
                          f"of {least} rows ({format_bytes(fixed)} of it for the whole input and outputs), more "
                          f"than the {format_bytes(budget_bytes)} allowed",
                          hint="give more memory (--max-memory), or use a smaller picture or fewer --bands")
    lo, hi = least, h  # need(lo) fits, need(hi) does not: the tallest band that fits
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if need(mid) <= budget_bytes else (lo, mid)
    count = math.ceil(h / lo)
    step = math.ceil(h / count)
    return [(r, min(r + step, h)) for r in range(0, h, step)]


def blur_host(cam, optics: list, layer_inputs, grid, yw: np.ndarray, rays: np.ndarray, gains: list[float],
              to_rgb: np.ndarray, row_bands: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                              float]:
    """Warp, blur and composite every layer on the host, band by band: (coefficients (K, H, W, 3), linear sRGB
    (H, W, 3), variance of Y (H, W), fraction of pixels from beyond the input frame). ``layer_inputs()`` gives
    a fresh iterator over the layers' (colour, mask), far first (:func:`lensrt.simulate.pipeline.simulate`)."""
    from .psf_grid import hat_weights
    rows, cols = cam.shape
    n_b = len(yw)
    halo = max(p.shape[-1] // 2 for p in grid.psf)
    wr, wc = hat_weights(grid.node_rows, rows), hat_weights(grid.node_cols, cols)
    coef = np.empty((n_b, rows, cols, 3), dtype=np.float32)
    rgb = np.empty((rows, cols, 3), dtype=np.float32)
    var_y = np.empty((rows, cols), dtype=np.float32)
    outside = np.zeros(len(optics))
    m_rgb = to_rgb.reshape(3, -1).astype(np.float32)
    for r0, r1 in row_bands:
        s0, s1 = max(r0 - halo, 0), min(r1 + halo, rows)
        geo = geometry(cam, (s0, s1))
        comp = Compositor(n_b, (r1 - r0, cols), yw, row0=r0 - s0)
        for li, (opt, (layer_img, mask)) in enumerate(zip(optics, layer_inputs())):
            layer, out, win = warp_layer(cam, geo, opt, layer_img, mask, gains[li], (r0 - s0, r1 - s0))
            outside[li] += out * (r1 - r0)
            blur_and_composite(comp, layer, grid.psf[li], rays[li], wr[:, s0:s1], wc, grid.node_rows - s0,
                               grid.node_cols, win)
            del layer
        comp.write(coef, rgb, var_y, m_rgb, r0)
    return coef, rgb, var_y, float(outside.max()) / rows

