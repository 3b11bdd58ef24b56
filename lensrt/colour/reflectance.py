"""Spectral reflectances of RGB colours: the Mallett & Yuksel (2019) sRGB basis.

A linear sRGB colour (r, g, b) in [0, 1] becomes the reflectance ``r B_r + g B_g + b B_b``:
non-negative, at most 1 (the three curves sum to 1 at every wavelength), and it reproduces
(r, g, b) under D65. The basis is tabulated by colour-science over 380-780 nm (kept on disk per
colour-science version, :mod:`.datacache`); edge values are held outside.

References
----------
Mallett, I. and Yuksel, C. (2019), Spectral Primary Decomposition for Rendering with sRGB
Reflectance, Eurographics Symposium on Rendering.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .datacache import cached_tables
from .wavelengths import DEFAULT_GRID, WavelengthGrid, as_wavelengths_nm, tabulated_at

__all__ = ["mallett2019_basis", "linear_rgb_to_reflectance"]


def _basis_tables() -> dict[str, np.ndarray]:
    """colour-science's Mallett-Yuksel basis: wavelengths (nm) and the (n, 3) table."""
    import colour
    sd = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    return {"nm": np.asarray(sd.wavelengths, dtype=np.float64), "values": np.asarray(sd.values, dtype=np.float64)}


@lru_cache(maxsize=8)
def _basis_on(grid: WavelengthGrid) -> np.ndarray:
    t = cached_tables("mallett2019", _basis_tables)
    return tabulated_at(t["nm"], t["values"], as_wavelengths_nm(grid), hold_edges=True)


def mallett2019_basis(grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Mallett & Yuksel (2019) sRGB reflectance basis on ``grid``, shape (3, n), rows r, g, b."""
    return _basis_on(grid).copy()


def linear_rgb_to_reflectance(rgb: np.ndarray, grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Spectral reflectance of linear sRGB colours (last axis, clipped to [0, 1]) by Mallett-Yuksel 2019."""
    c = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0)
    return c @ mallett2019_basis(grid)
