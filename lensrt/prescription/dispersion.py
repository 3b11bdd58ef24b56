"""Pack published dispersion formulas into lensrt's general formula (exactly, or not at all).

lensrt's kernels evaluate one formula for every material
(:mod:`lensrt.prescription.materials`)::

    n^2(w) = p0 + p1 w^2 + p2 w^4 + sum_{k=1..6} p_{k+2} w^(-2k)
             + sum_{j=0..2} p_{9+j} w^2 / (w^2 - p_{12+j}),      w in micrometres

:class:`PackBuilder` collects the terms of a catalog's formula (a constant, even
powers of w, Sellmeier poles ``B w^2 / (w^2 - C)`` and "Handbook" poles
``B / (w^2 - C)``, which equal ``(B / C) (w^2 / (w^2 - C) - 1)``) and refuses,
with :class:`NotRepresentable`, any term the general formula cannot hold
(odd powers, a fourth pole, Herzberger or Cauchy-in-n formulas). Nothing is
fitted here: a packed formula is the published one, term for term.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["PackBuilder", "NotRepresentable", "fit_power_series"]

DISPERSION_WIDTH = 15
_POWER_SLOT = {0: 0, 2: 1, 4: 2, -2: 3, -4: 4, -6: 5, -8: 6, -10: 7, -12: 8}


class NotRepresentable(ValueError):
    """A dispersion formula with a term lensrt's general formula cannot hold."""


@dataclass
class PackBuilder:
    """Accumulates the terms of n^2(w) (w in micrometres) into the packed coefficient row."""

    p: list[float] = field(default_factory=lambda: [0.0] * DISPERSION_WIDTH)
    poles: int = 0

    def power(self, coefficient: float, exponent: float) -> "PackBuilder":
        """Add ``coefficient * w**exponent`` (exponent one of 0, 2, 4, -2, ..., -12)."""
        if coefficient == 0.0:
            return self
        e = float(exponent)
        if not e.is_integer() or int(e) not in _POWER_SLOT:
            raise NotRepresentable(f"a w^{exponent:g} term")
        self.p[_POWER_SLOT[int(e)]] += float(coefficient)
        return self

    def sellmeier(self, b: float, c_um2: float) -> "PackBuilder":
        """Add ``b w^2 / (w^2 - c_um2)``; a pole at zero is a constant ``b``."""
        if b == 0.0:
            return self
        if c_um2 == 0.0:
            return self.power(b, 0)
        for j in range(self.poles):  # the same pole twice: add the strengths
            if self.p[12 + j] == float(c_um2):
                self.p[9 + j] += float(b)
                return self
        if self.poles == 3:
            raise NotRepresentable("more than three Sellmeier poles")
        self.p[9 + self.poles] = float(b)
        self.p[12 + self.poles] = float(c_um2)
        self.poles += 1
        return self

    def handbook(self, b: float, c_um2: float) -> "PackBuilder":
        """Add ``b / (w^2 - c_um2)`` = ``(b/c) w^2/(w^2 - c) - b/c`` (or ``b w^-2`` when c = 0)."""
        if b == 0.0:
            return self
        if c_um2 == 0.0:
            return self.power(b, -2)
        return self.sellmeier(b / c_um2, c_um2).power(-b / c_um2, 0)

    def packed(self) -> tuple[float, ...]:
        return tuple(self.p)


def fit_power_series(wavelength_nm: list[float], index: list[float],
                     max_terms: int = 6) -> tuple[tuple[float, ...], float]:
    """Least-squares fit of n^2 = a0 + a1 w^2 + a2 w^-2 + a3 w^-4 (+ a4 w^-6 + a5 w^-8) to tabulated indices.

    Used for CODE V private glasses (``PRV``), which give indices at listed
    wavelengths only, and for tabulated glasses. The number of terms is at most
    the number of points and at most ``max_terms`` (six, the Schott formula, by
    default; fewer keep a fit through a few rounded table values smooth).
    Returns the packed row and the largest residual in n over the given points.
    """
    import numpy as np

    w = np.asarray(wavelength_nm, dtype=np.float64) / 1000.0
    n = np.asarray(index, dtype=np.float64)
    exps = [0, 2, -2, -4, -6, -8][:max(1, min(6, max_terms, len(w)))]
    a = np.column_stack([w ** e for e in exps])
    coef, *_ = np.linalg.lstsq(a, n * n, rcond=None)
    b = PackBuilder()
    for c, e in zip(coef, exps):
        b.power(float(c), e)
    resid = float(np.max(np.abs(np.sqrt(a @ coef) - n)))
    return b.packed(), resid
