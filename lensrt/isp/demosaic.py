"""Demosaicing: Bayer through colour-demosaicing, any other CFA by normalised convolution.

Bayer methods (colour-demosaicing): ``bilinear``; ``malvar2004`` (Malvar, He and Cutler 2004,
gradient-corrected linear interpolation); ``menon2007`` (Menon, Andriani and Calvagno 2007,
directional filtering with a posteriori decision; slow on large frames).

``normalized`` (X-Trans and custom CFAs; also accepted for Bayer): for each channel c the
missing values are the weighted mean of the channel's samples in the 3x3 neighbourhood,

    V_c = (K * (M_c v)) / (K * M_c),   K = [1 2 1]^T [1 2 1],

with M_c the channel's mask and v the mosaic; a photosite keeps its own measured value. On a
Bayer mosaic this is exactly bilinear interpolation (tested against colour-demosaicing); on
X-Trans every 3x3 window holds all three colours, so the 3x3 kernel always finds samples
(a coarser kernel is used only for custom patterns where it does not). It is a simple
bilinear-style method: no edge direction, so colour fringes on sharp edges remain.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from ..sensor.cfa import CFA

__all__ = ["demosaic", "DEMOSAIC_METHODS"]

DEMOSAIC_METHODS = ("bilinear", "malvar2004", "menon2007", "normalized")


def _tent_sum(a: np.ndarray, radius: int) -> np.ndarray:
    """Separable tent filter ([1 2 1] for radius 1, [1 2 3 2 1] for 2) with zero padding, float32."""
    w = np.concatenate([np.arange(1, radius + 2), np.arange(radius, 0, -1)]).astype(np.float32)
    out = np.zeros_like(a)
    pad = np.pad(a, ((radius, radius), (0, 0)))
    for i, wi in enumerate(w):
        out += wi * pad[i:i + a.shape[0]]
    out2 = np.zeros_like(a)
    pad = np.pad(out, ((0, 0), (radius, radius)))
    for i, wi in enumerate(w):
        out2 += wi * pad[:, i:i + a.shape[1]]
    return out2


def _normalized(mosaic: np.ndarray, cfa: CFA) -> np.ndarray:
    rows, cols = mosaic.shape
    cmap = cfa.channel_map(rows, cols)
    tile = cfa.tile_array()
    # smallest tent whose window always holds every channel of the (periodic) pattern
    radius = 1
    while radius < 4:
        big = np.tile(tile, (3, 3))
        from numpy.lib.stride_tricks import sliding_window_view
        ok = all(sliding_window_view(big == c, (2 * radius + 1,) * 2).any(axis=(-1, -2)).all() for c in range(3))
        if ok:
            break
        radius += 1
    out = np.empty((rows, cols, 3), dtype=np.float32)
    v = mosaic.astype(np.float32, copy=False)
    for c in range(3):
        m = (cmap == c).astype(np.float32)
        num = _tent_sum(v * m, radius)
        den = _tent_sum(m, radius)
        est = num / np.maximum(den, np.float32(1e-12))
        out[..., c] = np.where(cmap == c, v, est)
    return out


def demosaic(mosaic: np.ndarray, cfa: CFA, method: str = "bilinear") -> np.ndarray:
    """Full-colour image (rows, cols, 3) float32 from a mosaic (rows, cols).

    Parameters
    ----------
    mosaic : float array (rows, cols)
        Linear, black-subtracted, white-balanced raw values.
    cfa : CFA
    method : str
        ``bilinear``, ``malvar2004``, ``menon2007`` (Bayer only) or ``normalized`` (any CFA).
        For a non-Bayer CFA, ``bilinear`` means ``normalized``.
    """
    m = method.lower().replace(" ", "").replace("_", "")
    if m not in DEMOSAIC_METHODS:
        raise LensrtError(f"unknown demosaicing method {method!r}", hint=f"use one of {', '.join(DEMOSAIC_METHODS)}")
    if m == "normalized" or (not cfa.is_bayer and m == "bilinear"):
        return _normalized(mosaic, cfa)
    if not cfa.is_bayer:
        raise LensrtError(f"{method} demosaicing needs a Bayer CFA; this sensor's is {cfa.name}",
                          hint="use --demosaic normalized (or bilinear) for X-Trans and custom patterns")
    import colour_demosaicing as cd
    fn = {"bilinear": cd.demosaicing_CFA_Bayer_bilinear, "malvar2004": cd.demosaicing_CFA_Bayer_Malvar2004,
          "menon2007": cd.demosaicing_CFA_Bayer_Menon2007}[m]
    return np.asarray(fn(mosaic, cfa.name), dtype=np.float32)
