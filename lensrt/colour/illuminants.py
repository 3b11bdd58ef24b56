"""Named light spectra for every stage: CIE illuminants, Planck radiators, CIE daylight, spectral lines.

One syntax, read by :func:`parse_illuminant` wherever a user names a light (scene files, ``psf``/``mtf``
``--spectrum``, ``bokeh --spectrum``, the sensor and the ISP):

=======================  ==========================================================================
``"D65"``, ``"A"``,      a CIE illuminant colour-science ships (case-insensitive; ``F1``-``F12`` are
``"FL2"``/``"F2"``, ...  ``FL1``-``FL12``; ``E`` is equal energy), as tabulated (D65 is 100 at 560 nm)
``"planck:3200K"``       a Planck radiator, spectral radiance in W / (m^2 sr nm) (100-100000 K)
``"daylight:5000K"``     CIE daylight (the D series) at a correlated colour temperature of 4000-25000 K,
                         nominal as CIE 015 gives it: ``daylight:6500K`` is D65 (CCT 6504 K, c2 = 1.4388e-2)
``"lines:486.1,587.6"``  equal-power spectral lines (nm)
=======================  ==========================================================================

The result is an :class:`Illuminant`, an object that stages pass to one another (never a display
label to be parsed back). Old spellings still work for one release, each with a
:class:`~lensrt.errors.LensrtDeprecationWarning` naming the new one: ``blackbody:3200`` / ``bb:3200``
(now ``planck:3200K``), and a bare colour temperature ``3200``, ``"3200K"`` (CIE daylight from 4000 K
up, Planck below, as the sensor read them: now ``daylight:5000K`` or ``planck:3200K``).

References
----------
CIE 015:2018 Colorimetry (illuminants, D series); Rowlands, Field Guide to Photographic Science, p. 37.
"""
from __future__ import annotations

import difflib
import re
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..errors import LensrtDeprecationWarning, LensrtError
from .datacache import cached_tables
from .wavelengths import WavelengthGrid, as_wavelengths_nm, tabulated_at

__all__ = ["Illuminant", "parse_illuminant", "spectrum", "illuminant_names", "cie_illuminant", "planck",
           "daylight", "lines", "tabulated", "planck_radiance", "ILLUMINANT_SYNTAX", "PLANCK_RANGE_K",
           "DAYLIGHT_RANGE_K"]

#: one line for error messages and ``--help``
ILLUMINANT_SYNTAX = ("D65, A, F2/FL2, any CIE illuminant colour-science ships (LED-B3, HP1, E, ...), "
                     "planck:3200K, daylight:5000K or lines:486.1,587.6")
#: temperatures a Planck radiator may have (K)
PLANCK_RANGE_K = (100.0, 1.0e5)
#: correlated colour temperatures of the CIE daylight series (K)
DAYLIGHT_RANGE_K = (4000.0, 25000.0)
#: CIE 015: the D series' nominal temperatures use c2 = 1.4380e-2 m K, today's is 1.4388e-2
_C2_RATIO = 1.4388 / 1.4380


@dataclass(frozen=True, eq=False)
class Illuminant:
    """A light spectrum by what it is, evaluated at any wavelengths.

    Attributes
    ----------
    name : str
        Its spelling in the one syntax (``"D65"``, ``"planck:3200K"``, ...); for a table, a free label.
    kind : str
        ``"cie"``, ``"planck"``, ``"daylight"``, ``"lines"`` or ``"table"``.
    kelvin : float or None
        Temperature of a Planck radiator, or correlated colour temperature of CIE daylight.
    lines_nm, line_weights : tuple of float
        A line spectrum's wavelengths (nm) and relative powers.
    table_nm, table_values : ndarray or None
        A tabulated spectrum (CIE, daylight, or given), linear between entries, 0 outside.
    """

    name: str
    kind: str
    kelvin: float | None = None
    lines_nm: tuple[float, ...] = ()
    line_weights: tuple[float, ...] = ()
    table_nm: np.ndarray | None = field(default=None, repr=False)
    table_values: np.ndarray | None = field(default=None, repr=False)

    @property
    def continuous(self) -> bool:
        """False for a line spectrum (it has no values per nm)."""
        return self.kind != "lines"

    @property
    def label(self) -> str:
        """What it is, for people."""
        if self.kind == "cie":
            return f"CIE {self.name}"
        if self.kind == "planck":
            return f"Planck {self.kelvin:g} K"
        if self.kind == "daylight":
            return f"CIE daylight {self.kelvin:g} K"
        if self.kind == "lines":
            return "lines " + ", ".join(f"{v:g}" for v in self.lines_nm) + " nm"
        return self.name

    @property
    def range_nm(self) -> tuple[float, float] | None:
        """The tabulated range (nm), or None for Planck's law and lines."""
        if self.table_nm is None:
            return None
        return float(self.table_nm[0]), float(self.table_nm[-1])

    def values(self, where: WavelengthGrid | np.ndarray, strict: bool = False) -> np.ndarray:
        """Spectral power at the wavelengths of ``where`` (a grid or nm).

        CIE and daylight tables as tabulated (100 at 560 nm), Planck in W / (m^2 sr nm), a given
        table in its own unit; 0 outside a table, or, with ``strict``, an error there.
        """
        nm = as_wavelengths_nm(where)
        if self.kind == "lines":
            raise LensrtError(f"{self.label} is a line spectrum: it has no power per nm",
                              hint="use a continuous spectrum (D65, planck:3200K, ...) here")
        if self.kind == "planck":
            return planck_radiance(self.kelvin, nm)
        lo, hi = self.range_nm
        if strict and nm.size and (nm.min() < lo - 1e-9 or nm.max() > hi + 1e-9):
            raise LensrtError(f"{self.label} is tabulated over {lo:g}-{hi:g} nm only",
                              hint="choose wavelengths inside it (e.g. with --band)")
        return tabulated_at(self.table_nm, self.table_values, nm)

    def relative(self, where: WavelengthGrid | np.ndarray) -> np.ndarray:
        """:meth:`values` scaled to a maximum of 1 over ``where``."""
        v = self.values(where)
        top = float(np.max(v)) if v.size else 0.0
        if not top > 0.0:
            raise LensrtError(f"{self.label} has no power at the wavelengths asked for")
        return v / top


def _cie_tables() -> dict[str, np.ndarray]:
    """colour-science's CIE illuminants: ``names``, and ``nm<i>`` / ``values<i>`` of the i-th name's table."""
    import colour
    out = {"names": np.array(list(colour.SDS_ILLUMINANTS.keys()))}
    for i, sd in enumerate(colour.SDS_ILLUMINANTS.values()):
        out[f"nm{i}"] = np.asarray(sd.wavelengths, dtype=np.float64)
        out[f"values{i}"] = np.asarray(sd.values, dtype=np.float64)
    return out


@lru_cache(maxsize=1)
def illuminant_names() -> tuple[str, ...]:
    """Names of the CIE illuminants colour-science ships (D65, A, FL1-FL12, LED-B1 ..., HP1 ...)."""
    return tuple(str(n) for n in cached_tables("cie_illuminants", _cie_tables)["names"])


def planck_radiance(kelvin: float, where: WavelengthGrid | np.ndarray) -> np.ndarray:
    """Planck spectral radiance of a blackbody, W / (m^2 sr nm), at ``where`` (colour-science, n = 1)."""
    import colour
    t = _kelvin_in(kelvin, PLANCK_RANGE_K, "Planck radiator")
    nm = as_wavelengths_nm(where)
    # colour.planck_law takes metres and returns W / (sr m^2 m): times 1e-9 per nm
    return np.asarray(colour.colorimetry.planck_law(nm * 1e-9, t), dtype=np.float64).reshape(nm.shape) * 1e-9


def cie_illuminant(name: str) -> Illuminant:
    """A CIE illuminant colour-science ships, by name (case-insensitive; ``F2`` is ``FL2``)."""
    key = name.strip()
    if re.fullmatch(r"[Ff]([1-9]|1[0-2])", key):
        key = "FL" + key[1:]
    match = [k for k in illuminant_names() if k.lower() == key.lower()]
    if not match:
        close = difflib.get_close_matches(key, illuminant_names(), n=3)
        raise LensrtError(f"unknown illuminant {name!r}",
                          hint=("did you mean " + ", ".join(close) + "? " if close else "")
                          + "use " + ILLUMINANT_SYNTAX)
    i = illuminant_names().index(match[0])
    t = cached_tables("cie_illuminants", _cie_tables)
    return Illuminant(match[0], "cie", table_nm=t[f"nm{i}"].copy(), table_values=t[f"values{i}"].copy())


def planck(kelvin: float) -> Illuminant:
    """A Planck radiator at ``kelvin`` (spectral radiance in W / (m^2 sr nm))."""
    t = _kelvin_in(kelvin, PLANCK_RANGE_K, "Planck radiator")
    return Illuminant(f"planck:{t:.12g}K", "planck", kelvin=t)


def daylight(kelvin: float) -> Illuminant:
    """CIE daylight at the nominal correlated colour temperature ``kelvin`` (``daylight(6500)`` is D65)."""
    import colour
    t = _kelvin_in(kelvin, DAYLIGHT_RANGE_K, "CIE daylight")
    xy = colour.temperature.CCT_to_xy_CIE_D(t * _C2_RATIO)
    sd = colour.sd_CIE_illuminant_D_series(xy)
    return Illuminant(f"daylight:{t:.12g}K", "daylight", kelvin=t,
                      table_nm=np.asarray(sd.wavelengths, dtype=np.float64),
                      table_values=np.asarray(sd.values, dtype=np.float64))


def lines(wavelengths_nm, weights=None) -> Illuminant:
    """Spectral lines at ``wavelengths_nm`` (nm) with relative powers ``weights`` (default equal)."""
    nm = tuple(float(v) for v in np.atleast_1d(wavelengths_nm))
    w = tuple(1.0 for _ in nm) if weights is None else tuple(float(v) for v in np.atleast_1d(weights))
    if not nm or len(w) != len(nm) or not all(np.isfinite(nm)) or min(nm) <= 0:
        raise LensrtError(f"a line spectrum needs one or more positive wavelengths (nm), not {list(nm)}",
                          hint="e.g. lines:486.1,587.6,656.3")
    if any(v < 0 for v in w) or not sum(w) > 0:
        raise LensrtError("line powers must be non-negative with a positive sum")
    return Illuminant("lines:" + ",".join(f"{v:.12g}" for v in nm), "lines", lines_nm=nm, line_weights=w)


def tabulated(wavelength_nm: np.ndarray, values: np.ndarray, label: str = "tabulated") -> Illuminant:
    """A spectrum given as a table (increasing wavelengths in nm, non-negative values)."""
    nm = np.asarray(wavelength_nm, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if nm.ndim != 1 or nm.shape != v.shape or nm.size < 2 or not np.all(np.diff(nm) > 0) \
            or not np.all(np.isfinite(v)) or np.any(v < 0):
        raise LensrtError(f"spectrum {label!r} must be two or more non-negative values at increasing wavelengths")
    return Illuminant(label, "table", table_nm=nm, table_values=v)


def spectrum(name: str | float | Illuminant, where: WavelengthGrid | np.ndarray) -> np.ndarray:
    """Spectral power of ``name`` (see the module docstring) at the wavelengths of ``where``."""
    return parse_illuminant(name).values(where)


def parse_illuminant(spec: str | float | Illuminant, *, bare_numbers: str = "kelvin") -> Illuminant:
    """The :class:`Illuminant` a user named (module docstring); an :class:`Illuminant` passes through.

    ``bare_numbers``: what a deprecated bare number means where it was accepted before, ``"kelvin"``
    (a colour temperature, as the sensor and ISP read it) or ``"nm"`` (wavelengths, as ``bokeh`` read
    ``"550"`` or ``"486.1,587.6"``).
    """
    if isinstance(spec, Illuminant):
        return spec
    if isinstance(spec, (int, float, np.integer, np.floating)) and not isinstance(spec, bool):
        return _deprecated_number(float(spec), str(spec), bare_numbers)
    if not isinstance(spec, str):
        raise LensrtError(f"an illuminant is named by a string such as 'D65' or 'planck:3200K', not {spec!r}")
    text = spec.strip()
    head, sep, tail = text.partition(":")
    head = head.strip().lower()
    if sep and head == "planck":
        return planck(_kelvin_text(tail, text))
    if sep and head == "daylight":
        return daylight(_kelvin_text(tail, text))
    if sep and head == "lines":
        return lines(_numbers_text(tail, text))
    if sep and head in ("blackbody", "bb"):
        ill = planck(_kelvin_text(tail, text))
        _warn(text, ill.name, stacklevel=3)
        return ill
    if re.fullmatch(r"[0-9.eE+-]+\s*[kK]", text):
        return _deprecated_number(_kelvin_text(text, text), text, "kelvin")
    if re.fullmatch(r"[0-9.]+(\s*,\s*[0-9.]+)*\s*,?", text):
        if bare_numbers == "nm":
            ill = lines(_numbers_text(text, text))
            _warn(text, ill.name, stacklevel=3)
            return ill
        return _deprecated_number(_kelvin_text(text, text), text, bare_numbers)
    return cie_illuminant(text)


def _deprecated_number(value: float, text: str, bare_numbers: str) -> Illuminant:
    """A bare number: wavelengths (``bare_numbers="nm"``) or the sensor's old CCT rule."""
    if bare_numbers == "nm":
        ill = lines([value])
    elif value >= DAYLIGHT_RANGE_K[0]:
        ill = daylight(value)
    else:
        ill = planck(_kelvin_in(value, (1000.0, DAYLIGHT_RANGE_K[0]), "colour temperature"))
    _warn(text, ill.name, "a bare colour temperature reads as CIE daylight from 4000 K up and a Planck "
                          "radiator below; " if bare_numbers != "nm" else "")
    return ill


def _warn(old: str, new: str, why: str = "", stacklevel: int = 4) -> None:
    """The deprecation note for an old spelling; ``stacklevel`` points at the caller of parse_illuminant."""
    warnings.warn(f"illuminant {old!r} is an old spelling ({why}it goes in the next release): write {new!r}",
                  LensrtDeprecationWarning, stacklevel=stacklevel)


def _kelvin_text(text: str, whole: str) -> float:
    t = text.strip()
    if t[-1:] in ("K", "k"):
        t = t[:-1]
    try:
        return float(t)
    except ValueError:
        raise LensrtError(f"cannot read a temperature in {whole!r}",
                          hint="write it in kelvin as planck:3200K or daylight:5000K (blackbody:K is the old "
                               "spelling)") from None


def _numbers_text(text: str, whole: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise LensrtError(f"cannot read wavelengths in {whole!r}", hint="write lines:486.1,587.6 (nm)") from None


def _kelvin_in(kelvin: float, bounds: tuple[float, float], what: str) -> float:
    t = float(kelvin)
    if not bounds[0] <= t <= bounds[1]:
        raise LensrtError(f"{what} temperature {t:g} K is outside {bounds[0]:g}-{bounds[1]:g} K")
    return t
