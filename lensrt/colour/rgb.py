"""CIE XYZ <-> linear sRGB, the sRGB transfer curves and CIELAB of sRGB colours: the one copy in lensrt.

sRGB is IEC 61966-2-1: the primaries and D65 white as colour-science ships them
(``RGB_COLOURSPACES["sRGB"]``, its matrices) and its piecewise transfer curve
(12.92 x for x <= 0.0031308, 1.055 x^(1/2.4) - 0.055 above; colour-science's ``eotf_sRGB``
and ``eotf_inverse_sRGB``). XYZ here is relative to the D65 white, no adaptation. The matrices,
the white and the 8-bit codes of the curve (:func:`srgb_encode8`) are read from colour-science once per
version and kept on disk (:mod:`.datacache`); the curve itself still imports colour-science.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .cmfs import CIE_1931_2DEG
from .datacache import cached_tables

__all__ = ["srgb_matrices", "xyz_to_linear_srgb", "linear_srgb_to_xyz", "srgb_encode", "srgb_decode",
           "srgb_encode8", "srgb_white_xy", "srgb_matrix_for_white", "linear_srgb_to_lab"]


def _srgb_tables() -> dict[str, np.ndarray]:
    """colour-science's sRGB colourspace (matrices, white) and the 8-bit code thresholds of its curve."""
    import colour
    cs = colour.RGB_COLOURSPACES["sRGB"]
    return {"xyz_to_rgb": np.asarray(cs.matrix_XYZ_to_RGB, dtype=np.float64),
            "rgb_to_xyz": np.asarray(cs.matrix_RGB_to_XYZ, dtype=np.float64),
            "white_xy": np.asarray(cs.whitepoint, dtype=np.float64),
            "code8_from": _code_thresholds(srgb_encode, 255)}


def _code_thresholds(encode, top: int) -> np.ndarray:
    """For k = 1 .. ``top``: the smallest float64 x in [0, 1] whose code ``int(top * encode(x) + 0.5)`` is >= k.

    A bisection on the bit patterns of the non-negative doubles (ordered like the numbers), all codes at once;
    with a non-decreasing code, ``code(x) = number of thresholds <= x`` for every x in [0, 1].
    """
    def code(bits):
        return (encode(bits.view(np.float64)) * float(top) + 0.5).astype(np.int64)

    k = np.arange(1, top + 1, dtype=np.int64)
    lo = np.zeros(top, dtype=np.int64)  # code(0) = 0 < k
    hi = np.full(top, np.array(1.0).view(np.int64), dtype=np.int64)  # code(1) = top >= k
    while np.any(hi - lo > 1):
        mid = lo + (hi - lo) // 2
        up = code(mid) >= k
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    return hi.view(np.float64)


@lru_cache(maxsize=1)
def srgb_matrices() -> tuple[np.ndarray, np.ndarray]:
    """(XYZ -> linear sRGB, linear sRGB -> XYZ) 3x3 matrices of colour-science's sRGB colourspace."""
    t = cached_tables("srgb", _srgb_tables)
    return t["xyz_to_rgb"], t["rgb_to_xyz"]


def xyz_to_linear_srgb(xyz: np.ndarray) -> np.ndarray:
    """XYZ (last axis) -> linear sRGB (IEC 61966-2-1 matrix, D65 white, no adaptation, no clipping)."""
    return np.asarray(xyz, dtype=np.float64) @ srgb_matrices()[0].T


def linear_srgb_to_xyz(rgb: np.ndarray) -> np.ndarray:
    """Linear sRGB (last axis) -> XYZ (D65 white)."""
    return np.asarray(rgb, dtype=np.float64) @ srgb_matrices()[1].T


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (the IEC 61966-2-1 EOTF), clipped to [0, 1] first."""
    import colour
    return np.asarray(colour.models.eotf_sRGB(np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)),
                      dtype=np.float64)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded [0, 1] (the inverse EOTF), clipped to [0, 1] first."""
    import colour
    return np.asarray(colour.models.eotf_inverse_sRGB(np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)),
                      dtype=np.float64)


def srgb_encode8(linear: np.ndarray) -> np.ndarray:
    """Linear values -> 8-bit sRGB codes, ``uint8(255 * srgb_encode(linear) + 0.5)``, bit for bit.

    Without colour-science's import: the codes come from the 255 thresholds of colour-science's curve
    (kept with its tables, :mod:`.datacache`); NaN gives 0.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    codes = np.searchsorted(cached_tables("srgb", _srgb_tables)["code8_from"], x, side="right")
    return np.where(np.isnan(x), 0, codes).astype(np.uint8)


def srgb_white_xy() -> np.ndarray:
    """CIE 1931 (x, y) of the sRGB white (D65 as IEC 61966-2-1 gives it)."""
    return cached_tables("srgb", _srgb_tables)["white_xy"].copy()


def linear_srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELAB (L*, a*, b*) of linear sRGB colours (..., 3), relative to the sRGB white with Y = 1.

    A neutral R = G = B has a* = b* = 0 to the rounding of the IEC matrix (|a*| about 0.004).
    """
    import colour
    xyz = linear_srgb_to_xyz(rgb)
    return np.asarray(colour.XYZ_to_Lab(xyz, srgb_white_xy()), dtype=np.float64)


def srgb_matrix_for_white(white_xyz: np.ndarray) -> np.ndarray:
    """3x3: XYZ relative to an adopted white ``white_xyz`` -> linear sRGB, taking that white to (1, 1, 1) exactly.

    A Bradford chromatic adaptation to the sRGB white (colour-science), the sRGB matrix, then the
    diagonal that absorbs the rounding of the IEC matrix (about 1e-4), so that white stays white.
    What a raw converter aims at for the colours it saw under ``white_xyz``.
    """
    import colour
    white = np.asarray(white_xyz, dtype=np.float64)
    srgb_white = np.asarray(colour.xy_to_XYZ(srgb_white_xy()), dtype=np.float64)
    cat = np.asarray(colour.adaptation.matrix_chromatic_adaptation_VonKries(white, srgb_white, "Bradford"))
    a = srgb_matrices()[0] @ cat
    return a / (a @ white)[:, None]
