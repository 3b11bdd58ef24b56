"""The CIE standard observer: 1931 2-degree colour-matching functions and the 1924 photopic V(lambda).

Tables from colour-science (``MSDS_CMFS``, ``SDS_LEFS``), tabulated at 1 nm over 360-830 nm, zero
outside, linear between table entries; kept on disk per colour-science version (:mod:`.datacache`),
so a process reads them without importing colour-science.

References
----------
CIE 015:2018 Colorimetry, 4th edition; Rowlands, Field Guide to Photographic Science, p. 39-40.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .datacache import cached_tables
from .wavelengths import DEFAULT_GRID, WavelengthGrid, as_wavelengths_nm, tabulated_at

__all__ = ["CIE_1931_2DEG", "cie_xyz_cmfs", "photopic_v"]

#: colour-science's name of the observer lensrt uses everywhere
CIE_1931_2DEG = "CIE 1931 2 Degree Standard Observer"
_PHOTOPIC = "CIE 1924 Photopic Standard Observer"


def _observer_tables() -> dict[str, np.ndarray]:
    """colour-science's CIE 1931 2-degree CMFs and 1924 photopic V(lambda): wavelengths (nm) and values."""
    import colour
    cmfs = colour.MSDS_CMFS[CIE_1931_2DEG]
    lef = colour.SDS_LEFS[_PHOTOPIC]
    return {"cmfs_nm": np.asarray(cmfs.wavelengths, dtype=np.float64),
            "cmfs": np.asarray(cmfs.values, dtype=np.float64),
            "v_nm": np.asarray(lef.wavelengths, dtype=np.float64),
            "v": np.asarray(lef.values, dtype=np.float64)}


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
    t = cached_tables("observer", _observer_tables)
    return tabulated_at(t["cmfs_nm"], t["cmfs"], as_wavelengths_nm(where))


def photopic_v(where: WavelengthGrid | np.ndarray = DEFAULT_GRID) -> np.ndarray:
    """CIE 1924 photopic luminous efficiency V(lambda) at the wavelengths of ``where`` (0 outside 360-830 nm)."""
    if isinstance(where, WavelengthGrid):
        return _v_on(where).copy()
    t = cached_tables("observer", _observer_tables)
    return tabulated_at(t["v_nm"], t["v"], as_wavelengths_nm(where))
