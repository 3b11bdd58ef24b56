"""The CIE standard observer: 1931 2-degree colour-matching functions and the 1924 photopic V(lambda).

Tables from colour-science (``MSDS_CMFS``, ``SDS_LEFS``), tabulated at 1 nm over 360-830 nm, zero
outside, linear between table entries.

References
----------
CIE 015:2018 Colorimetry, 4th edition; Rowlands, Field Guide to Photographic Science, p. 39-40.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .wavelengths import DEFAULT_GRID, WavelengthGrid, as_wavelengths_nm, sd_at

__all__ = ["CIE_1931_2DEG", "cie_xyz_cmfs", "photopic_v"]

#: colour-science's name of the observer lensrt uses everywhere
CIE_1931_2DEG = "CIE 1931 2 Degree Standard Observer"
_PHOTOPIC = "CIE 1924 Photopic Standard Observer"


@lru_cache(maxsize=16)
def _cmfs_on(grid: WavelengthGrid) -> np.ndarray:
    return cie_xyz_cmfs(grid.nm)


@lru_cache(maxsize=16)
def _v_on(grid: WavelengthGrid) -> np.ndarray:
    return photopic_v(grid.nm)


def cie_xyz_cmfs(where: WavelengthGrid | np.ndarray = DEFAULT_GRID) -> np.ndarray:
    """CIE 1931 2-degree x-bar, y-bar, z-bar at the wavelengths of ``where`` (a grid or nm), shape (3, n)."""
    if isinstance(where, WavelengthGrid):
        return _cmfs_on(where).copy()
    import colour
    return sd_at(colour.MSDS_CMFS[CIE_1931_2DEG], as_wavelengths_nm(where))


def photopic_v(where: WavelengthGrid | np.ndarray = DEFAULT_GRID) -> np.ndarray:
    """CIE 1924 photopic luminous efficiency V(lambda) at the wavelengths of ``where`` (0 outside 360-830 nm)."""
    if isinstance(where, WavelengthGrid):
        return _v_on(where).copy()
    import colour
    return sd_at(colour.SDS_LEFS[_PHOTOPIC], as_wavelengths_nm(where))
