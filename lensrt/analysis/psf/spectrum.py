"""The spectrum a PSF integrates: a lens file's wavelengths, chosen lines, or a spectral power distribution.

A :class:`SpectrumChoice` serves both PSF methods:

* the *geometric* PSF samples each ray's wavelength inside the stream kernel
  (:meth:`SpectrumChoice.trace_spectrum`): discrete lines with their weights,
  or -- for an SPD -- a piecewise-constant density over 5 nm bins of the band,
  sampled continuously within each bin;
* the *diffraction* PSF sums monochromatic PSFs on one grid
  (:attr:`SpectrumChoice.lines_nm`, :attr:`SpectrumChoice.line_weights`): the
  lines themselves, or for an SPD the midpoints of ``n_lines`` equal bins of
  the band, each weighted by the SPD's power in its bin (midpoint rule).

Weights are relative spectral power (radiometric, as tabulated by the CIE or
Planck's law); a detector's spectral response would multiply them. SPDs are
named in the one illuminant syntax of :mod:`lensrt.colour.illuminants`
(``D65``, ``A``, ``FL2``, ``planck:5500K``, ``daylight:5000K``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...colour import parse_illuminant
from ...errors import LensrtError
from ...prescription.model import Lens

__all__ = ["SpectrumChoice", "lens_spectrum", "line_spectrum", "spd_spectrum", "parse_spectrum", "parse_band"]

#: bin width (nm) of the piecewise-constant density the kernel samples an SPD from
SPD_BIN_NM = 5.0


@dataclass(frozen=True)
class SpectrumChoice:
    """A spectrum for PSFs (see the module docstring); picklable, hashable.

    Attributes
    ----------
    name : str
        How it was asked for ("lens", "550 nm", "D65 400-700 nm", ...).
    lines_nm, line_weights : tuple of float
        Wavelengths (nm) and normalised weights for monochromatic sums.
    edges_nm, power : tuple of float or None
        For an SPD: bin edges (nm) and the power in each bin, sampled continuously by the kernel.
    """

    name: str
    lines_nm: tuple[float, ...]
    line_weights: tuple[float, ...]
    edges_nm: tuple[float, ...] | None = None
    power: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if len(self.lines_nm) == 0 or len(self.lines_nm) != len(self.line_weights):
            raise LensrtError("a spectrum needs at least one wavelength and one weight per wavelength")
        w = np.asarray(self.line_weights, dtype=np.float64)
        if np.any(w < 0) or not w.sum() > 0 or not np.all(np.isfinite(w)):
            raise LensrtError("spectral weights must be non-negative with a positive sum")
        nm = np.asarray(self.lines_nm, dtype=np.float64)
        if np.any(nm < 200.0) or np.any(nm > 20000.0) or not np.all(np.isfinite(nm)):
            raise LensrtError(f"wavelengths {list(self.lines_nm)} nm must lie within 200..20000 nm")
        object.__setattr__(self, "line_weights", tuple(float(v) for v in w / w.sum()))

    @property
    def continuous(self) -> bool:
        return self.edges_nm is not None

    @property
    def primary_nm(self) -> float:
        """The heaviest line (the reference wavelength for grids and chief rays)."""
        return float(self.lines_nm[int(np.argmax(self.line_weights))])

    @property
    def min_nm(self) -> float:
        return float(self.edges_nm[0]) if self.continuous else float(min(self.lines_nm))

    @property
    def max_nm(self) -> float:
        return float(self.edges_nm[-1]) if self.continuous else float(max(self.lines_nm))

    def trace_spectrum(self):
        """The :class:`lensrt.trace.sampling.Spectrum` the stream kernel samples."""
        from ...trace.sampling import spectrum_continuous, spectrum_discrete
        if self.continuous:
            return spectrum_continuous(np.asarray(self.edges_nm), np.asarray(self.power))
        return spectrum_discrete(np.asarray(self.lines_nm), np.asarray(self.line_weights))

    def to_dict(self) -> dict:
        out = {"name": self.name, "wavelengths_nm": list(self.lines_nm), "weights": list(self.line_weights),
               "sampled": "continuously within bins" if self.continuous else "discrete lines"}
        if self.continuous:
            out["band_nm"] = [self.min_nm, self.max_nm]
            out["bin_nm"] = float(self.edges_nm[1] - self.edges_nm[0])
        return out


def lens_spectrum(lens: Lens) -> SpectrumChoice:
    """The lens file's wavelengths and weights."""
    return SpectrumChoice("lens", tuple(float(v) for v in lens.wavelengths.nm),
                          tuple(float(v) for v in lens.wavelengths.weights))


def line_spectrum(wavelengths_nm: Sequence[float], weights: Sequence[float] | None = None) -> SpectrumChoice:
    """Chosen lines (equal weights unless given)."""
    nm = tuple(float(v) for v in wavelengths_nm)
    w = tuple(1.0 for _ in nm) if weights is None else tuple(float(v) for v in weights)
    return SpectrumChoice(", ".join(f"{v:g}" for v in nm) + " nm", nm, w)


def spd_spectrum(name: str, band_nm: tuple[float, float] = (400.0, 700.0), n_lines: int = 7) -> SpectrumChoice:
    """An SPD over ``band_nm``: 5 nm bins for the kernel, ``n_lines`` midpoint lines for diffraction."""
    lo, hi = (float(v) for v in band_nm)
    if not (200.0 <= lo < hi <= 20000.0):
        raise LensrtError(f"band {lo:g}-{hi:g} nm is not an increasing range within 200-20000 nm")
    if n_lines < 1:
        raise LensrtError("an SPD needs at least one diffraction line")
    nbins = max(1, int(math.ceil((hi - lo) / SPD_BIN_NM - 1e-9)))
    edges = np.linspace(lo, hi, nbins + 1)
    fine = np.linspace(lo, hi, 20 * nbins + 1)  # trapezoid over 0.25 nm steps (5 nm bins)
    ill = parse_illuminant(name)
    label, vals = ill.name, ill.values(fine, strict=True)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (vals[1:] + vals[:-1]) * np.diff(fine))])
    power = np.diff(np.interp(edges, fine, cum))
    line_edges = np.linspace(lo, hi, n_lines + 1)
    line_power = np.diff(np.interp(line_edges, fine, cum))
    mids = 0.5 * (line_edges[1:] + line_edges[:-1])
    if not power.sum() > 0:
        raise LensrtError(f"{label} has no power in {lo:g}-{hi:g} nm")
    return SpectrumChoice(f"{label} {lo:g}-{hi:g} nm", tuple(float(v) for v in mids),
                          tuple(float(v) for v in np.maximum(line_power, 0.0)),
                          tuple(float(v) for v in edges), tuple(float(v) for v in np.maximum(power, 0.0)))


def parse_band(text: str | None) -> tuple[float, float]:
    """``"400:700"`` -> (400.0, 700.0) nm (default 400-700 nm)."""
    if text is None:
        return (400.0, 700.0)
    try:
        lo, hi = (float(v) for v in text.replace("-", ":").split(":"))
    except ValueError:
        raise LensrtError(f"bad band {text!r}", hint="give it as MIN:MAX in nm, e.g. 400:700") from None
    return lo, hi


def parse_spectrum(lens: Lens, wavelengths_nm: Sequence[float] | None = None, spectrum: str | None = None,
                   band_nm: tuple[float, float] = (400.0, 700.0), n_lines: int = 7) -> SpectrumChoice:
    """The CLI's choice: explicit ``wavelengths_nm`` lines, a named ``spectrum``, or the lens file's."""
    if wavelengths_nm and spectrum and spectrum.lower() != "lens":
        raise LensrtError("give --wavelength-nm or --spectrum, not both")
    if wavelengths_nm:
        return line_spectrum(wavelengths_nm)
    if spectrum is None or spectrum.lower() == "lens":
        return lens_spectrum(lens)
    return spd_spectrum(spectrum, band_nm, n_lines)
