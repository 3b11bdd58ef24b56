"""Plane textures: procedural test charts and image files, with a float64 NumPy reference.

A texture is evaluated at plane coordinates (s, t) in mm, measured from the
plane's centre along its ``right`` and ``up`` axes as seen from the front (the
side its normal points to). Its value at a wavelength is dimensionless: for a
reflective plane the spectral reflectance, for an emissive one the factor that
multiplies the plane's emission spectrum (white = 1).

Procedural kinds (levels ``low``/``high`` are spectrally flat factors that
multiply the plane's ``tint`` spectrum):

================  ==============================================================
``uniform``        everywhere ``high`` (1 by default; the tint is the reflectance)
``slanted_edge``   ISO 12233 e-SFR style: a dark square (``low``) of side
                   ``square`` x the shorter plane side, rotated by ``angle_deg``
                   (default 5 deg), on ``high`` -- four slanted edges
``siemens_star``   ``spokes`` dark/light cycles (``low``/``high``) inside a
                   circle filling the shorter side; ``high`` outside
``grid``           lines of width ``line_width`` (fraction of a cell) at the
                   borders of ``cells`` = [nx, ny] cells, ``low`` on ``high``
``colorchecker``   6 x 4 patches with colour-science's spectral reflectances
                   (``chart``, default "ColorChecker N Ohta"), dark skin at the
                   top left, gaps of ``gap`` x the patch pitch showing the
                   chart's black patch as frame
``image``          a PNG/JPEG (PIL), sRGB-decoded to linear RGB and turned into
                   reflectance by the Mallett-Yuksel (2019) basis; bilinear
================  ==============================================================
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...colour import WavelengthGrid, colorchecker_reflectances, mallett2019_basis, srgb_decode
from ...errors import LensrtError

__all__ = ["TEXTURE_KINDS", "TEX_UNIFORM", "TEX_SLANTED_EDGE", "TEX_SIEMENS_STAR", "TEX_GRID",
           "TEX_COLORCHECKER", "TEX_IMAGE", "Texture", "load_image_linear", "pattern_level",
           "texture_value_ref"]

TEX_UNIFORM, TEX_SLANTED_EDGE, TEX_SIEMENS_STAR, TEX_GRID, TEX_COLORCHECKER, TEX_IMAGE = range(6)
#: texture kind names -> the integer code the kernels use
TEXTURE_KINDS = {"uniform": TEX_UNIFORM, "slanted_edge": TEX_SLANTED_EDGE, "siemens_star": TEX_SIEMENS_STAR,
                 "grid": TEX_GRID, "colorchecker": TEX_COLORCHECKER, "image": TEX_IMAGE}

#: largest image texture side accepted (pixels)
MAX_IMAGE_SIDE = 16384


@dataclass(frozen=True, eq=False)
class Texture:
    """A plane's texture, with every geometric parameter already in mm.

    Attributes
    ----------
    kind : str
        One of :data:`TEXTURE_KINDS`.
    params : tuple of 4 float
        slanted_edge: (angle_rad, half_side_mm, 0, 0); siemens_star:
        (spokes, radius_mm, 0, 0); grid: (cell_w_mm, cell_h_mm,
        line_half_width_mm, 0); colorchecker: (pitch_x_mm, pitch_y_mm,
        gap_half_mm, 0); others zeros.
    low, high : float
        Levels of the two-level patterns.
    chart : str
        colour-science ColorChecker data set (colorchecker only).
    image_linear : ndarray (H, W, 3) or None
        Linear sRGB texels, row 0 at the top (image only).
    source : str
        File the image came from, or a description.
    """

    kind: str = "uniform"
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    low: float = 0.0
    high: float = 1.0
    chart: str = "ColorChecker N Ohta"
    image_linear: np.ndarray | None = field(default=None, repr=False)
    source: str = ""

    @property
    def code(self) -> int:
        return TEXTURE_KINDS[self.kind]


def load_image_linear(path: Path, encoding: str = "srgb") -> np.ndarray:
    """An image file as linear RGB float32 (H, W, 3) in [0, 1], row 0 at the top.

    ``encoding``: ``"srgb"`` decodes the sRGB transfer curve (8- and 16-bit
    files), ``"linear"`` takes the values as they are. Alpha is dropped.
    """
    from PIL import Image, UnidentifiedImageError
    if not path.is_file():
        raise LensrtError(f"image file {str(path)!r} does not exist")
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im, dtype=np.float64) / 65535.0
                arr = np.repeat(arr[..., None], 3, axis=2)
            else:
                arr = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except (UnidentifiedImageError, OSError) as err:
        raise LensrtError(f"cannot read image {str(path)!r}: {err}", hint="use a PNG or JPEG file") from None
    h, w = arr.shape[:2]
    if h < 1 or w < 1 or max(h, w) > MAX_IMAGE_SIDE:
        raise LensrtError(f"image {str(path)!r} is {w} x {h} pixels; textures must be 1 to {MAX_IMAGE_SIDE} pixels a side")
    if encoding == "srgb":
        arr = srgb_decode(arr)
    elif encoding != "linear":
        raise LensrtError(f"image encoding {encoding!r} is not 'srgb' or 'linear'")
    return np.ascontiguousarray(np.clip(arr, 0.0, 1.0), dtype=np.float32)


def pattern_level(tex: Texture, size_mm: tuple[float, float], s_mm: np.ndarray, t_mm: np.ndarray) -> np.ndarray:
    """Two-level patterns (uniform, slanted_edge, siemens_star, grid): ``low`` or ``high`` at (s, t).

    Grid lines sit on the cell borders counted from the plane's left and bottom edges.
    """
    s = np.asarray(s_mm, dtype=np.float64)
    t = np.asarray(t_mm, dtype=np.float64)
    p = tex.params
    if tex.kind == "uniform":
        dark = np.zeros(np.broadcast(s, t).shape, dtype=bool)
    elif tex.kind == "slanted_edge":
        c, sn = math.cos(p[0]), math.sin(p[0])
        sr, tr = c * s + sn * t, -sn * s + c * t
        dark = (np.abs(sr) <= p[1]) & (np.abs(tr) <= p[1])
    elif tex.kind == "siemens_star":
        r = np.hypot(s, t)
        dark = (r <= p[1]) & (np.sin(p[0] * np.arctan2(t, s)) < 0.0)
    elif tex.kind == "grid":
        a = (s + 0.5 * size_mm[0]) / p[0]
        b = (t + 0.5 * size_mm[1]) / p[1]
        ds = np.abs(a - np.round(a)) * p[0]
        dt = np.abs(b - np.round(b)) * p[1]
        dark = (ds <= p[2]) | (dt <= p[2])
    else:
        raise ValueError(f"{tex.kind} is not a two-level pattern")
    return np.where(dark, tex.low, tex.high)


def _colorchecker_index(tex: Texture, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Patch index 0..23 at (s, t), or 24 for the frame; the chart spans 6 x 4 pitches."""
    px, py, gap = tex.params[0], tex.params[1], tex.params[2]
    a = s / px + 3.0          # 0..6 from left to right
    b = 2.0 - t / py          # 0..4 from top to bottom
    col, row = np.floor(a), np.floor(b)
    fa, fb = (a - col) * px, (b - row) * py
    inside = (col >= 0) & (col < 6) & (row >= 0) & (row < 4) & (fa >= gap) & (fa <= px - gap) \
        & (fb >= gap) & (fb <= py - gap)
    return np.where(inside, row * 6 + col, 24).astype(int)


def _image_bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear lookup with clamped edges; u right, v up, in [0, 1]; texel centres at (i + 0.5) / n."""
    h, w = img.shape[:2]
    x = np.clip(u * w - 0.5, 0.0, w - 1.0)
    y = np.clip((1.0 - v) * h - 0.5, 0.0, h - 1.0)
    x0 = np.clip(np.floor(x).astype(int), 0, max(w - 2, 0))
    y0 = np.clip(np.floor(y).astype(int), 0, max(h - 2, 0))
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    im = img.astype(np.float64)
    return ((1 - fx) * (1 - fy) * im[y0, x0] + fx * (1 - fy) * im[y0, x1]
            + (1 - fx) * fy * im[y1, x0] + fx * fy * im[y1, x1])


def texture_value_ref(tex: Texture, size_mm: tuple[float, float], s_mm: np.ndarray, t_mm: np.ndarray,
                      wavelength_nm: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Float64 reference of a texture's spectral value at plane point(s) and wavelength(s).

    Multiply by the plane's tint (reflective) or emission (emissive) spectrum
    for the full value; that product is what the kernel returns.
    """
    s = np.asarray(s_mm, dtype=np.float64)
    t = np.asarray(t_mm, dtype=np.float64)
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    if tex.kind == "colorchecker":
        table = np.vstack([colorchecker_reflectances(grid, tex.chart),
                           colorchecker_reflectances(grid, tex.chart)[23:24]])
        idx = _colorchecker_index(tex, s, t)
        return np.array([np.interp(lv, grid.nm, table[i]) for i, lv in
                         zip(np.ravel(idx), np.ravel(np.broadcast_to(lam, idx.shape)))]).reshape(idx.shape)
    if tex.kind == "image":
        assert tex.image_linear is not None
        u = s / size_mm[0] + 0.5
        v = t / size_mm[1] + 0.5
        rgb = _image_bilinear(tex.image_linear, u, v)
        basis = mallett2019_basis(grid)
        bl = np.stack([np.interp(lam, grid.nm, basis[i]) for i in range(3)], axis=-1)
        return np.sum(rgb * bl, axis=-1)
    return pattern_level(tex, size_mm, s, t) * np.ones_like(lam)
