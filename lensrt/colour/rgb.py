"""CIE XYZ <-> linear sRGB, the sRGB transfer curves and CIELAB of sRGB colours: the one copy in lensrt.

sRGB is IEC 61966-2-1: the primaries and D65 white as colour-science ships them
(``RGB_COLOURSPACES["sRGB"]``, its matrices) and its piecewise transfer curve
(12.92 x for x <= 0.0031308, 1.055 x^(1/2.4) - 0.055 above; colour-science's ``eotf_sRGB``
and ``eotf_inverse_sRGB``). XYZ here is relative to the D65 white, no adaptation.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .cmfs import CIE_1931_2DEG

__all__ = ["srgb_matrices", "xyz_to_linear_srgb", "linear_srgb_to_xyz", "srgb_encode", "srgb_decode",
           "srgb_white_xy", "srgb_matrix_for_white", "linear_srgb_to_lab"]


@lru_cache(maxsize=1)
def srgb_matrices() -> tuple[np.ndarray, np.ndarray]:
    """(XYZ -> linear sRGB, linear sRGB -> XYZ) 3x3 matrices of colour-science's sRGB colourspace."""
    import colour
    cs = colour.RGB_COLOURSPACES["sRGB"]
    a = np.asarray(cs.matrix_XYZ_to_RGB, dtype=np.float64)
    b = np.asarray(cs.matrix_RGB_to_XYZ, dtype=np.float64)
    a.flags.writeable = b.flags.writeable = False
    return a, b


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


def srgb_white_xy() -> np.ndarray:
    """CIE 1931 (x, y) of the sRGB white (D65 as IEC 61966-2-1 gives it)."""
    import colour
    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].whitepoint, dtype=np.float64)


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
