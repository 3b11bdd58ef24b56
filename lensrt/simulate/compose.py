"""Depth layers, the distortion warp, and back-to-front compositing of blurred layers.

Layers. The depth map is cut into layers at depths evenly spaced in 1/depth (the
blur diameter is linear in it); every pixel goes to the nearest layer (hard
assignment), so the depth error is at most half a layer spacing in dioptres
(reported). Without a depth map there is one layer at the focus distance.

Warp. For each layer and output pixel, the input is sampled (bilinear) at the
pinhole position of the direction whose real chief ray lands there
(:meth:`lensrt.simulate.optics.LayerOptics.ideal_of_real`); the layer's mask is
sampled nearest. Output pixels whose pinhole position lies outside the input
frame take the nearest edge pixel (counted in the sidecar). The sharp layer is
then multiplied by the layer's relative illumination and on-axis gain.

Compositing (occlusion). Layers are blurred by their own PSFs as premultiplied
colour B = h * (alpha I) and coverage A = h * alpha and composited back to front
with the "over" operator, C <- B + (1 - A) C, Acc <- A + (1 - A) Acc (Porter &
Duff 1984; the layered depth-of-field scheme of Kraus & Strengert, "Depth-of-Field
Rendering by Pyramidal Image Processing", Eurographics 2007, and Lee, Eisemann &
Seidel, "Real-time lens blur effects and focus control", SIGGRAPH 2010). The
B and A are first divided by the same blur of a full layer of ones, so that
a layer covering everything has A = 1 exactly (and the frame's edge does not
darken). The result is C / Acc: the division renormalises where a layer's hidden part (behind
a nearer layer, or beyond the frame edge) would otherwise darken its blur -- the
single-image input cannot show what is hidden. So a sharp foreground stays sharp
(its A is 1 over it: nothing from behind leaks onto it), and a blurred foreground
spreads over the background by its own blur radius only.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from .convolve import convolve_bands
from .optics import Camera, LayerOptics, picture_positions_mm

__all__ = ["layer_depths_mm", "assign_layers", "warp_layer", "composite_layers"]


def layer_depths_mm(depth_m: np.ndarray, n_layers: int) -> np.ndarray:
    """At most ``n_layers`` layer depths (mm), evenly spaced in 1/depth over the map's range, far first."""
    if n_layers < 1:
        raise LensrtError(f"{n_layers} depth layers: use at least 1")
    inv = 1.0 / np.asarray(depth_m, dtype=np.float64).ravel()
    lo, hi = float(inv.min()), float(inv.max())
    if hi - lo <= 1e-12 * hi or n_layers == 1:
        return np.array([1000.0 / (0.5 * (lo + hi))])
    levels = np.unique(inv)
    if len(levels) <= n_layers:
        return np.sort(1000.0 / levels)[::-1]
    return 1000.0 / np.linspace(lo, hi, n_layers)


def assign_layers(depth_m: np.ndarray, layers_mm: np.ndarray) -> tuple[np.ndarray, float]:
    """Layer index of every pixel (nearest in 1/depth) and the largest dioptre error (1/m)."""
    inv = 1.0 / np.asarray(depth_m, dtype=np.float64)
    lev = 1000.0 / np.asarray(layers_mm)
    idx = np.argmin(np.abs(inv[..., None] - lev), axis=-1)
    return idx, float(np.max(np.abs(inv - lev[idx])))


def warp_layer(cam: Camera, opt: LayerOptics, image: np.ndarray, mask: np.ndarray | None,
               gain: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(sharp linear image x RI x gain (H, W, 3), alpha (H, W), fraction of pixels from beyond the input frame)."""
    from scipy.ndimage import map_coordinates
    rows, cols = cam.shape
    rr, cc = np.mgrid[0:rows, 0:cols].astype(np.float64)
    u, v = picture_positions_mm(cam, rr, cc)
    r = np.hypot(u, v)
    ri = opt.ideal_of_real(r)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(r > 0, ri / np.where(r > 0, r, 1.0), 1.0)
    ci = u * s / cam.pitch_mm + 0.5 * (cols - 1)
    ri_row = 0.5 * (rows - 1) - v * s / cam.pitch_mm
    outside = float(np.mean((ci < -0.5) | (ci > cols - 0.5) | (ri_row < -0.5) | (ri_row > rows - 0.5)))
    coords = np.stack([ri_row, ci])
    sharp = np.stack([map_coordinates(image[..., k], coords, order=1, mode="nearest") for k in range(3)], axis=-1)
    alpha = np.ones((rows, cols)) if mask is None else map_coordinates(mask.astype(np.float64), coords, order=0,
                                                                       mode="nearest")
    sharp *= (opt.ri_at(r) * gain)[..., None]
    return sharp.astype(np.float32), alpha.astype(np.float32), outside


def _products(sharp: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W, 10): colour x alpha (3), alpha, and the 6 products rgb_c rgb_c' alpha (c <= c')."""
    pairs = [sharp[..., a] * sharp[..., b] for a in range(3) for b in range(a, 3)]
    return np.concatenate([sharp * alpha[..., None], alpha[..., None], np.stack(pairs, axis=-1) * alpha[..., None]],
                          axis=-1, dtype=np.float32)


def _mix(y_weights: np.ndarray) -> np.ndarray:
    """(K, 5, 10): per band, colour (3) and alpha pass through; Y^2 alpha = sum w_c w_c' (rgb_c rgb_c' alpha)."""
    k = len(y_weights)
    m = np.zeros((k, 5, 10))
    m[:, :4, :4] = np.eye(4)
    col = 4
    for a in range(3):
        for b in range(a, 3):
            m[:, 4, col] = y_weights[:, a] * y_weights[:, b] * (1.0 if a == b else 2.0)
            col += 1
    return m


def composite_layers(layers: list[tuple[np.ndarray, np.ndarray]], psfs: list[np.ndarray], y_weights: np.ndarray,
                     rays: np.ndarray, wr: np.ndarray, wc: np.ndarray, rows: np.ndarray,
                     cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All bands: (rgb coefficients (K, H, W, 3), variance of Y from the PSFs' rays (H, W)).

    ``layers`` far to near: (sharp (H, W, 3), alpha (H, W)); ``psfs[l]`` (K, gr, gc, n, n); ``y_weights`` (K, 3)
    each band's Y per coefficient; ``rays`` (L, K) rays landed per PSF. Each layer's tiles are transformed once
    for all bands (:func:`lensrt.simulate.convolve.convolve_bands`).
    """
    mix = _mix(np.asarray(y_weights, dtype=np.float64))
    c = acc = var = None
    for li, ((sharp, alpha), psf) in enumerate(zip(layers, psfs)):
        blurred, u = convolve_bands(_products(sharp, alpha), psf, mix, wr, wc, rows, cols)
        # divide by the operator's response to a full, uniform layer U: a layer that covers everything then has
        # coverage exactly 1 (the blend of node PSFs need not add up to 1 everywhere; the frame edge loses light)
        u = np.maximum(u, np.float32(1e-12))
        b, q = blurred[..., :3] / u[..., None], blurred[..., 4] / u
        a = np.clip(blurred[..., 3] / u, 0.0, 1.0)
        yb = np.einsum("khwc,kc->khw", b, y_weights.astype(np.float32))
        v = np.maximum(q - yb ** 2, 0.0) / np.maximum(rays[li], 1.0).astype(np.float32)[:, None, None]  # ray sampling
        if c is None:
            c, acc, var = b, a, v
        else:
            c = b + (1.0 - a)[..., None] * c
            var = v + (1.0 - a) ** 2 * var
            acc = a + (1.0 - a) * acc
    good = acc > 1e-6
    inv = np.where(good, 1.0 / np.where(good, acc, 1.0), 0.0)
    return c * inv[..., None], (var * inv * inv).sum(axis=0)
