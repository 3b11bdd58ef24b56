"""The light of a bokeh source: a spectrum to sample rays from and CIE XYZ channels to bin them in.

A bokeh source is a point of spectral radiant intensity ``I(lambda) = k S(lambda)``
(W / (sr nm)); ``S`` is a shape (a CIE illuminant, a blackbody, spectral lines)
and ``k`` makes its luminous intensity ``K_m int I ybar dlambda`` equal to
``intensity_cd``. The stream kernel accumulates CIE 1931 X, Y, Z directly:

* wavelengths are drawn with density ``p(lambda)`` proportional to
  ``S(lambda) (xbar + ybar + zbar)(lambda)`` (importance sampling by the eye's
  total response: no rays are spent where the observer sees nothing), piecewise
  constant over a 1 nm grid from 380 to 780 nm;
* each ray lands in three channels with weights ``t_c = cbar / (xbar + ybar + zbar)``
  (the :class:`~lensrt.trace.stream.Channels` table, linear between grid points),
  so ``E_p[t_c]`` is proportional to ``int S cbar dlambda``.

Colour-matching functions: CIE 1931 2-degree standard observer, from
colour-science via :mod:`lensrt.colour` (tabulated at 1 nm). Illuminants in the one syntax of
:mod:`lensrt.colour.illuminants`. :class:`BokehLight` keeps the exact expectations the
kernel's tables imply (``mean_t``), so the Y of a whole spot is exactly
``intensity_cd`` times its solid angle, whatever the table's resolution.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...colour import WavelengthGrid, cie_xyz_cmfs, parse_illuminant
from ...errors import LensrtError

__all__ = ["BokehLight", "bokeh_light", "SPECTRUM_HELP", "CMF_RANGE_NM"]

#: the channel table's wavelength range (nm) and step
CMF_RANGE_NM = (380.0, 780.0)
_STEP_NM = 1.0
SPECTRUM_HELP = ("D65 (default), A, E, any CIE illuminant colour-science ships (FL2, LED-B3, ...), "
                 "planck:3200K (a Planck radiator), daylight:5000K (CIE daylight), lines:486.1,587.6,656.3 "
                 "(equal-weight lines in nm), or lens (the lens file's wavelengths and weights)")


@dataclass(frozen=True)
class BokehLight:
    """Spectrum and XYZ channel table of a bokeh source (module docstring).

    Attributes
    ----------
    label : str
        What the user asked for (``"D65"``, ``"blackbody:3200"``, ``"550"``...).
    mode : int
        0: discrete lines ``nm`` with probabilities ``power / power.sum()``;
        1: bins with edges ``nm`` and ``power`` per bin (uniform inside).
    nm, power : ndarray
        The sampling spectrum (importance-weighted by xbar + ybar + zbar).
    table : ndarray (3, n)
        Channel weights t_X, t_Y, t_Z on the grid ``table_nm0 + k * table_dnm``.
    mean_t : ndarray (3,)
        E_p[t_c]: the expected channel weight of one ray under the sampling density.
    mean_t2 : ndarray (3,)
        E_p[t_c^2] (for the Poisson noise estimate).
    """

    label: str
    mode: int
    nm: np.ndarray
    power: np.ndarray
    table: np.ndarray
    table_nm0: float
    table_dnm: float
    mean_t: np.ndarray
    mean_t2: np.ndarray
    line_nm: tuple[float, ...] = ()

    def spectrum(self):
        """The :class:`lensrt.trace.sampling.Spectrum` for :func:`lensrt.trace.stream.stream`."""
        from ...trace.sampling import spectrum_continuous, spectrum_discrete
        if self.mode == 0:
            return spectrum_discrete(self.nm, self.power)
        return spectrum_continuous(self.nm, self.power)

    def channels(self):
        """The XYZ :class:`lensrt.trace.stream.Channels`."""
        from ...trace.stream import Channels
        return Channels(self.table, self.table_nm0, self.table_dnm)

    @property
    def chromaticity_xy(self) -> tuple[float, float]:
        """CIE 1931 (x, y) of the source as the kernel's tables define it."""
        s = float(self.mean_t.sum())
        return float(self.mean_t[0] / s), float(self.mean_t[1] / s)

    @property
    def kappa(self) -> np.ndarray:
        """E[t^2] / E[t]^2 per channel: the factor by which spectral sampling inflates Poisson noise."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.mean_t > 0, self.mean_t2 / self.mean_t ** 2, np.inf)

    @property
    def wavelength_range_nm(self) -> tuple[float, float]:
        """Shortest and longest wavelength a ray can have (nm)."""
        if self.mode == 0:
            return float(self.nm.min()), float(self.nm.max())
        nz = np.nonzero(self.power > 0)[0]
        return float(self.nm[nz[0]]), float(self.nm[nz[-1] + 1])

    def to_dict(self) -> dict:
        x, y = self.chromaticity_xy
        return {"spectrum": self.label, "sampling": "importance by xbar+ybar+zbar (CIE 1931 2 deg)",
                "wavelength_range_nm": list(self.wavelength_range_nm), "chromaticity_xy": [x, y],
                "lines_nm": list(self.line_nm)}


def _table_at(table: np.ndarray, nm0: float, dnm: float, wl: np.ndarray) -> np.ndarray:
    """The kernel's channel lookup (linear between grid points, 0 outside), for the host."""
    grid = nm0 + dnm * np.arange(table.shape[1])
    return np.stack([np.interp(wl, grid, row, left=0.0, right=0.0) for row in table])


def bokeh_light(spec: str = "D65", lens=None) -> BokehLight:
    """The :class:`BokehLight` for a spectrum name (see :data:`SPECTRUM_HELP`).

    ``lens`` is needed for ``"lens"`` (its wavelengths and weights).
    """
    grid = WavelengthGrid(CMF_RANGE_NM[0], CMF_RANGE_NM[1], _STEP_NM)
    nm, cmf = grid.nm, cie_xyz_cmfs(grid)
    total = cmf.sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        table = np.where(total > 0, cmf / np.where(total > 0, total, 1.0), 0.0)
    text = str(spec).strip()
    lines: np.ndarray | None = None
    line_w: np.ndarray | None = None
    if text.lower() == "lens":
        if lens is None:
            raise LensrtError("the 'lens' spectrum needs a lens")
        lines = np.asarray(lens.wavelengths.nm, dtype=np.float64)
        line_w = np.asarray(lens.wavelengths.weights, dtype=np.float64)
    else:
        ill = parse_illuminant(text, bare_numbers="nm")   # old bare wavelengths ("550") still read as lines
        if not ill.continuous:
            lines, line_w = np.asarray(ill.lines_nm), np.asarray(ill.line_weights)
    if lines is not None:
        if len(lines) == 0 or np.any(~np.isfinite(lines)):
            raise LensrtError(f"spectrum {spec!r} has no wavelengths")
        resp = _table_at(cmf, nm[0], _STEP_NM, lines).sum(axis=0)
        power = line_w * resp
        if not np.any(power > 0):
            raise LensrtError(f"spectrum {spec!r}: no line lies where the eye sees (380-780 nm)",
                              hint="give visible wavelengths, or a continuous spectrum such as D65")
        keep = power > 0
        lines, power = lines[keep], power[keep]
        t = _table_at(table, nm[0], _STEP_NM, lines)
        p = power / power.sum()
        return BokehLight(text, 0, lines, power, table, float(nm[0]), _STEP_NM, t @ p, (t * t) @ p,
                          tuple(float(v) for v in lines))
    s = ill.values(nm)   # a continuous shape on the 1 nm grid
    g = s * total
    power = 0.5 * (g[:-1] + g[1:]) * _STEP_NM
    if not np.any(power > 0):
        raise LensrtError(f"spectrum {spec!r} has no power where the eye sees (380-780 nm)")
    p = power / power.sum()
    # E_p[t] and E_p[t^2] with t linear inside each bin and uniform density there (exact)
    a, b = table[:, :-1], table[:, 1:]
    mean_t = (0.5 * (a + b)) @ p
    mean_t2 = ((a * a + a * b + b * b) / 3.0) @ p
    edges = np.asarray(nm, dtype=np.float64)
    if not math.isclose(edges[1] - edges[0], _STEP_NM):
        raise AssertionError("wavelength grid")  # pragma: no cover
    return BokehLight(text, 1, edges, power, table, float(nm[0]), _STEP_NM, mean_t, mean_t2)
