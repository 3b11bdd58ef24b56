"""Colour charts: the ColorChecker patch names and spectral reflectances colour-science ships.

The default data set is ``"ColorChecker N Ohta"`` (24 patches, 380-780 nm at 5 nm), row by row from
the top left (dark skin) to the bottom right (black). Reflectances are linear between table entries
and hold their edge values outside the table. The tables are kept on disk per colour-science version
(:mod:`.datacache`).
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import LensrtError
from .datacache import cached_tables
from .wavelengths import DEFAULT_GRID, WavelengthGrid, as_wavelengths_nm, tabulated_at

__all__ = ["CHART", "colorchecker_names", "colorchecker_reflectances", "chart_names"]

#: the ColorChecker reflectance set used by default
CHART = "ColorChecker N Ohta"


def _chart_tables() -> dict[str, np.ndarray]:
    """colour-science's ColorChecker sets: ``charts``; per set i ``patches<i>``; per patch j ``nm<i>_<j>``,
    ``values<i>_<j>``."""
    import colour
    out = {"charts": np.array(list(colour.SDS_COLOURCHECKERS))}
    for i, sds in enumerate(colour.SDS_COLOURCHECKERS.values()):
        out[f"patches{i}"] = np.array(list(sds.keys()))
        for j, sd in enumerate(sds.values()):
            out[f"nm{i}_{j}"] = np.asarray(sd.wavelengths, dtype=np.float64)
            out[f"values{i}_{j}"] = np.asarray(sd.values, dtype=np.float64)
    return out


def chart_names() -> tuple[str, ...]:
    """The ColorChecker data sets colour-science ships."""
    return tuple(str(c) for c in cached_tables("colorcheckers", _chart_tables)["charts"])


def _chart_index(chart: str) -> int:
    """Index of data set ``chart`` in :func:`chart_names`, matched as colour-science's mapping does
    (exactly, else ignoring case, else ignoring case, spaces and punctuation)."""
    charts = chart_names()
    for canon in (lambda s: s, str.lower, lambda s: re.sub(r"[^0-9a-z]", "", s.lower())):
        hits = [i for i, c in enumerate(charts) if canon(c) == canon(str(chart))]
        if hits:
            return hits[0]
    raise LensrtError(f"unknown ColorChecker data set {chart!r}",
                      hint="use one of " + ", ".join(repr(k) for k in charts))


def colorchecker_names(chart: str = CHART) -> tuple[str, ...]:
    """Patch names of a colour-science ColorChecker, row by row from the top left (dark skin)."""
    t = cached_tables("colorcheckers", _chart_tables)
    return tuple(str(p) for p in t[f"patches{_chart_index(chart)}"])


def colorchecker_reflectances(where: WavelengthGrid | np.ndarray = DEFAULT_GRID, chart: str = CHART) -> np.ndarray:
    """The patch reflectances of a ColorChecker data set at the wavelengths of ``where`` (a grid or nm),
    shape (24, n), in the order of :func:`colorchecker_names`; edge values held outside the table."""
    names = colorchecker_names(chart)
    i = _chart_index(chart)
    t = cached_tables("colorcheckers", _chart_tables)
    nm = as_wavelengths_nm(where)
    return np.stack([tabulated_at(t[f"nm{i}_{j}"], t[f"values{i}_{j}"], nm, hold_edges=True)
                     for j in range(len(names))])
