"""Wavelength sampling for the render: piecewise-constant importance sampling over a scene's grid.

Everything else about spectra (grids, illuminants, the CIE observer, photometry, sRGB, charts,
reflectance bases) lives in :mod:`lensrt.colour`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..colour.wavelengths import WavelengthGrid
from ..errors import LensrtError

__all__ = ["WavelengthSampler"]


@dataclass(frozen=True)
class WavelengthSampler:
    """Piecewise-constant importance sampling of wavelengths over the grid's intervals.

    Interval i = [nm[i], nm[i+1]] has probability ``p[i]``; inside an interval
    the wavelength is uniform, so pdf(lambda) = p[i] / step_nm. ``cdf`` has
    n_intervals + 1 entries from 0 to 1 (what the kernel's binary search uses).
    """

    grid: WavelengthGrid
    cdf: np.ndarray
    label: str = "uniform"

    @classmethod
    def uniform(cls, grid: WavelengthGrid) -> "WavelengthSampler":
        m = grid.n - 1
        return cls(grid, np.linspace(0.0, 1.0, m + 1), "uniform")

    @classmethod
    def from_weight(cls, grid: WavelengthGrid, weight: np.ndarray, uniform_fraction: float = 0.1,
                    label: str = "weighted") -> "WavelengthSampler":
        """Sample in proportion to a non-negative ``weight`` on the grid, mixed with a uniform part.

        The uniform part (``uniform_fraction``, default 10 %) keeps the pdf
        positive wherever the integrand may be non-zero (defensive sampling).
        """
        w = np.asarray(weight, dtype=np.float64)
        if w.shape != (grid.n,) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise LensrtError("a wavelength sampling weight must be finite, non-negative, one value per grid point")
        if not 0.0 <= uniform_fraction <= 1.0:
            raise LensrtError(f"uniform fraction {uniform_fraction:g} is not within [0, 1]")
        mass = 0.5 * (w[:-1] + w[1:])
        total = mass.sum()
        m = grid.n - 1
        p = np.full(m, 1.0 / m) if total <= 0 else (1.0 - uniform_fraction) * mass / total + uniform_fraction / m
        cdf = np.concatenate([[0.0], np.cumsum(p)])
        cdf /= cdf[-1]
        return cls(grid, cdf, label)

    @property
    def probabilities(self) -> np.ndarray:
        """Probability of each grid interval."""
        return np.diff(self.cdf)

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wavelengths (nm) and their pdf (1/nm) for uniform numbers ``u`` in [0, 1)."""
        u = np.asarray(u, dtype=np.float64)
        p = self.probabilities
        i = np.clip(np.searchsorted(self.cdf, u, side="right") - 1, 0, len(p) - 1)
        frac = np.where(p[i] > 0, (u - self.cdf[i]) / np.where(p[i] > 0, p[i], 1.0), 0.5)
        lam = self.grid.min_nm + (i + np.clip(frac, 0.0, 1.0)) * self.grid.step_nm
        return lam, p[i] / self.grid.step_nm

    def pdf(self, wavelength_nm: np.ndarray) -> np.ndarray:
        """pdf (1/nm) at ``wavelength_nm``; 0 outside the grid's range."""
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        p = self.probabilities
        i = np.clip(np.floor((lam - self.grid.min_nm) / self.grid.step_nm).astype(int), 0, len(p) - 1)
        inside = (lam >= self.grid.min_nm) & (lam <= self.grid.max_nm)
        return np.where(inside, p[i] / self.grid.step_nm, 0.0)
