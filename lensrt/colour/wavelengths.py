"""Wavelength grids and tabulated data on them: the one place lensrt resamples a spectrum.

A scene's spectra are arrays sampled on one uniform :class:`WavelengthGrid`
(default 380-780 nm in 5 nm steps), wavelength axis last. Between grid points
a spectrum is the linear interpolant, and every integral over wavelength on a
grid is the trapezoid rule over it (:attr:`WavelengthGrid.weights_nm`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError

__all__ = ["WavelengthGrid", "DEFAULT_GRID", "STANDARD_WAVELENGTHS_NM", "as_wavelengths_nm", "tabulated_at",
           "sd_at"]


@dataclass(frozen=True)
class WavelengthGrid:
    """A uniform wavelength grid, ``min_nm`` to ``max_nm`` inclusive in steps of ``step_nm``."""

    min_nm: float = 380.0
    max_nm: float = 780.0
    step_nm: float = 5.0

    def __post_init__(self) -> None:
        lo, hi, st = float(self.min_nm), float(self.max_nm), float(self.step_nm)
        if not (200.0 <= lo < hi <= 2000.0):
            raise LensrtError(f"wavelength range {lo:g}-{hi:g} nm is not an increasing range within 200-2000 nm")
        if not st > 0.0:
            raise LensrtError(f"wavelength step {st:g} nm must be positive")
        n = (hi - lo) / st
        if abs(n - round(n)) > 1e-6 or round(n) < 1:
            raise LensrtError(f"wavelength step {st:g} nm does not divide the range {lo:g}-{hi:g} nm",
                              hint="choose a step that divides max_nm - min_nm")

    @property
    def n(self) -> int:
        """Number of grid points."""
        return int(round((self.max_nm - self.min_nm) / self.step_nm)) + 1

    @property
    def nm(self) -> np.ndarray:
        """The grid's wavelengths (nm), float64."""
        return self.min_nm + self.step_nm * np.arange(self.n, dtype=np.float64)

    @property
    def weights_nm(self) -> np.ndarray:
        """Trapezoid weights (nm): ``integral f dlambda = sum(f * weights_nm)``."""
        w = np.full(self.n, self.step_nm)
        w[0] = w[-1] = 0.5 * self.step_nm
        return w

    def shape(self):  # -> colour.SpectralShape
        """The grid as a colour-science ``SpectralShape``."""
        import colour
        return colour.SpectralShape(self.min_nm, self.max_nm, self.step_nm)

    def interp(self, values: np.ndarray, wavelength_nm: np.ndarray | float) -> np.ndarray:
        """Linear interpolant of grid ``values`` (wavelength axis last) at ``wavelength_nm``; 0 outside."""
        v = np.asarray(values, dtype=np.float64)
        w = np.asarray(wavelength_nm, dtype=np.float64)
        if v.ndim == 1:
            return np.interp(w, self.nm, v, left=0.0, right=0.0)
        return np.stack([np.interp(w, self.nm, row, left=0.0, right=0.0)
                         for row in v.reshape(-1, self.n)]).reshape(v.shape[:-1] + np.shape(w))


#: the default scene grid, 380-780 nm in 5 nm steps
DEFAULT_GRID = WavelengthGrid()
#: the 5 nm grid 380..780 nm on which colour-science's camera and ColorChecker data are given (the sensor's)
STANDARD_WAVELENGTHS_NM = DEFAULT_GRID.nm


def as_wavelengths_nm(where: WavelengthGrid | np.ndarray | float) -> np.ndarray:
    """The wavelengths (nm, float64) of a :class:`WavelengthGrid` or of an array of wavelengths."""
    if isinstance(where, WavelengthGrid):
        return where.nm
    return np.asarray(where, dtype=np.float64)


def tabulated_at(table_nm: np.ndarray, values: np.ndarray, wavelength_nm: np.ndarray,
                 hold_edges: bool = False) -> np.ndarray:
    """Tabulated data (``values`` at increasing ``table_nm``; a trailing axis per column for a 2-D table)
    linearly interpolated at ``wavelength_nm``; outside the table 0, or the edge value with ``hold_edges``."""
    t = np.asarray(table_nm, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    kw = {} if hold_edges else {"left": 0.0, "right": 0.0}
    if v.ndim == 1:
        return np.interp(wl, t, v, **kw)
    return np.stack([np.interp(wl, t, v[:, i], **kw) for i in range(v.shape[1])])


def sd_at(sd, where: WavelengthGrid | np.ndarray, hold_edges: bool = False) -> np.ndarray:
    """A colour-science (multi-)spectral distribution at the wavelengths of ``where``: (n,), or (k, n)
    for a multi-spectral one (one row per column of the table)."""
    return tabulated_at(sd.wavelengths, sd.values, as_wavelengths_nm(where), hold_edges)
