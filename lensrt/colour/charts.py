"""Colour charts: the ColorChecker patch names and spectral reflectances colour-science ships.

The default data set is ``"ColorChecker N Ohta"`` (24 patches, 380-780 nm at 5 nm), row by row from
the top left (dark skin) to the bottom right (black). Reflectances are linear between table entries
and hold their edge values outside the table.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from .wavelengths import DEFAULT_GRID, WavelengthGrid, sd_at

__all__ = ["CHART", "colorchecker_names", "colorchecker_reflectances", "chart_names"]

#: the ColorChecker reflectance set used by default
CHART = "ColorChecker N Ohta"


def chart_names() -> tuple[str, ...]:
    """The ColorChecker data sets colour-science ships."""
    import colour
    return tuple(colour.SDS_COLOURCHECKERS)


def colorchecker_names(chart: str = CHART) -> tuple[str, ...]:
    """Patch names of a colour-science ColorChecker, row by row from the top left (dark skin)."""
    import colour
    if chart not in colour.SDS_COLOURCHECKERS:
        raise LensrtError(f"unknown ColorChecker data set {chart!r}",
                          hint="use one of " + ", ".join(repr(k) for k in chart_names()))
    return tuple(colour.SDS_COLOURCHECKERS[chart].keys())


def colorchecker_reflectances(where: WavelengthGrid | np.ndarray = DEFAULT_GRID, chart: str = CHART) -> np.ndarray:
    """The patch reflectances of a ColorChecker data set at the wavelengths of ``where`` (a grid or nm),
    shape (24, n), in the order of :func:`colorchecker_names`; edge values held outside the table."""
    import colour
    names = colorchecker_names(chart)
    sds = colour.SDS_COLOURCHECKERS[chart]
    return np.stack([sd_at(sds[k], where, hold_edges=True) for k in names])
