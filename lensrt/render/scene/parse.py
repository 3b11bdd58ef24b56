"""Checked reading of scene-file tables: numbers, vectors, spectra, with file/line/key in every error."""
from __future__ import annotations

import difflib
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ...colour import (Illuminant, WavelengthGrid, colorchecker_names, colorchecker_reflectances,
                       linear_rgb_to_reflectance, lines, parse_illuminant, photopic_v, planck, scale_to_luminous,
                       srgb_decode, tabulated)
from ...errors import LensrtDeprecationWarning, LensrtError
from ...units import LUMINOUS_EFFICACY_LM_PER_W
from .model import Spectrum

__all__ = ["Section", "parse_emission", "parse_reflectance", "parse_spectrum_shape", "RADIANCE", "INTENSITY",
           "IRRADIANCE"]

_REQUIRED = object()

#: emission kinds -> (unit, {normalisation key: photometric or scale})
RADIANCE = ("W/(m^2 sr nm)", {"luminance_cd_m2": "cd/m^2", "radiance_scale": None})
INTENSITY = ("W/(sr nm)", {"intensity_cd": "cd", "intensity_scale": None})
IRRADIANCE = ("W/(m^2 nm)", {"illuminance_lux": "lx", "irradiance_scale": None})


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class Section:
    """One table of the scene file, with where it is, for error messages."""

    def __init__(self, table: Any, name: str, path: Path | None, line: int | None, label: str | None = None) -> None:
        self.name, self.path, self.line = name, path, line
        self.label = label or f"[{name}]"
        if not isinstance(table, dict):
            raise self.error(f"{self.label} must be a table, not {table!r}")
        self.table = table

    @property
    def base_dir(self) -> Path:
        return self.path.parent if self.path is not None else Path.cwd()

    def error(self, message: str, key: str | None = None, hint: str | None = None) -> LensrtError:
        where = self.label + (f" key {key!r}" if key else "")
        return LensrtError(f"{where}: {message}", path=self.path, line=self.line, hint=hint)

    def sub(self, key: str) -> "Section":
        return Section(self.table[key], self.name, self.path, self.line, f"{self.label} {key}")

    def check_keys(self, allowed: set[str] | frozenset[str]) -> None:
        for key in self.table:
            if key not in allowed:
                close = difflib.get_close_matches(key, sorted(allowed), n=1)
                raise self.error(f"unknown key {key!r}", None, f"did you mean {close[0]!r}?" if close
                                 else f"allowed keys: {', '.join(sorted(allowed))}")

    def has(self, key: str) -> bool:
        return key in self.table

    def raw(self, key: str, default: Any = _REQUIRED) -> Any:
        if key in self.table:
            return self.table[key]
        if default is _REQUIRED:
            raise self.error("is missing", key)
        return default

    def number(self, key: str, default: Any = _REQUIRED, *, positive: bool = False, nonneg: bool = False,
               lo: float | None = None, hi: float | None = None, allow_inf: bool = False) -> Any:
        v = self.raw(key, default)
        if v is default and default is not _REQUIRED:
            return v
        if isinstance(v, str) and allow_inf and v.strip().lower() in ("inf", "infinity"):
            v = math.inf
        if not _is_number(v) or math.isnan(v) or (math.isinf(v) and not allow_inf):
            raise self.error(f"must be a finite number, not {v!r}", key)
        v = float(v)
        if positive and not v > 0:
            raise self.error(f"must be positive, not {v:g}", key)
        if nonneg and v < 0:
            raise self.error(f"must not be negative, not {v:g}", key)
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise self.error(f"{v:g} is outside [{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]", key)
        return v

    def integer(self, key: str, default: Any = _REQUIRED, *, lo: int | None = None, hi: int | None = None) -> Any:
        v = self.raw(key, default)
        if v is default and default is not _REQUIRED:
            return v
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.error(f"must be a whole number, not {v!r}", key)
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise self.error(f"{v} is outside {lo}..{hi}", key)
        return int(v)

    def string(self, key: str, default: Any = _REQUIRED, choices: tuple[str, ...] | None = None) -> Any:
        v = self.raw(key, default)
        if v is default and default is not _REQUIRED:
            return v
        if not isinstance(v, str):
            raise self.error(f"must be a string, not {v!r}", key)
        if choices is not None and v not in choices:
            raise self.error(f"{v!r} is not one of {', '.join(choices)}", key)
        return v

    def boolean(self, key: str, default: Any = _REQUIRED) -> Any:
        v = self.raw(key, default)
        if not isinstance(v, bool) and not (v is default and default is not _REQUIRED):
            raise self.error(f"must be true or false, not {v!r}", key)
        return v

    def vector(self, key: str, n: int, default: Any = _REQUIRED, *, positive: bool = False) -> Any:
        v = self.raw(key, default)
        if v is default and default is not _REQUIRED:
            return v
        if not isinstance(v, list) or len(v) != n or not all(_is_number(x) and math.isfinite(x) for x in v):
            raise self.error(f"must be a list of {n} finite numbers, not {v!r}", key)
        arr = np.asarray(v, dtype=np.float64)
        if positive and not np.all(arr > 0):
            raise self.error(f"must be positive numbers, not {v!r}", key)
        return arr

    def file(self, key: str) -> Path:
        v = self.string(key)
        p = Path(v)
        if not p.is_absolute():
            p = self.base_dir / p
        if not p.is_file():
            raise self.error(f"file {str(p)!r} does not exist", key, "paths are relative to the scene file")
        return p


def _table_spectrum(sec: Section, key: str, value: dict, grid: WavelengthGrid, hold_edges: bool) -> tuple[np.ndarray, str]:
    """``{nm = [...], values = [...]}`` or ``{file = "x.csv"}`` (two columns nm, value) -> grid values."""
    if "file" in value:
        p = Path(value["file"])
        p = p if p.is_absolute() else sec.base_dir / p
        if not p.is_file():
            raise sec.error(f"spectrum file {str(p)!r} does not exist", key, "paths are relative to the scene file")
        try:
            data = np.genfromtxt(p, delimiter=",", comments="#", invalid_raise=True)
            data = data[~np.isnan(data).any(axis=1)] if data.ndim == 2 else data
        except ValueError as err:
            raise sec.error(f"cannot read spectrum file {str(p)!r}: {err}", key) from None
        if data.ndim != 2 or data.shape[1] != 2:
            raise sec.error(f"spectrum file {str(p)!r} must have two comma-separated columns: nm, value", key)
        wl, vals, label = data[:, 0], data[:, 1], p.name
    else:
        wl = np.asarray(value.get("nm", []), dtype=object)
        vals = np.asarray(value.get("values", []), dtype=object)
        label = "tabulated"
        if len(wl) < 2 or len(wl) != len(vals) or not all(_is_number(x) for x in list(wl) + list(vals)):
            raise sec.error("a tabulated spectrum needs nm = [...] and values = [...], two or more numbers each, "
                            "of equal length", key)
        wl, vals = wl.astype(np.float64), vals.astype(np.float64)
    if not np.all(np.diff(wl) > 0) or not np.all(np.isfinite(vals)) or np.any(vals < 0):
        raise sec.error("spectrum wavelengths must increase and values be finite and non-negative", key)
    if hold_edges:
        return np.interp(grid.nm, wl, vals), label
    return np.interp(grid.nm, wl, vals, left=0.0, right=0.0), label


def parse_spectrum_shape(sec: Section, key: str, grid: WavelengthGrid) -> Illuminant:
    """A relative emission spectrum, as the :class:`~lensrt.colour.Illuminant` the stages share.

    Forms: the one illuminant syntax of :mod:`lensrt.colour.illuminants` (``"D65"``, ``"A"``,
    ``"FL2"``/``"F2"``, ``"LED-B3"``, ``"E"``, ``"planck:3200K"`` (Planck radiance in
    W/(m^2 sr nm)), ``"daylight:5000K"``, ``"lines:532"`` (one line)); ``{gaussian_nm = 589,
    fwhm_nm = 10}``, ``{line_nm = 532}``, ``{nm = [...], values = [...]}``, ``{file = "x.csv"}``;
    and, for one release, the old ``{blackbody_K = 3200}`` (a deprecation warning names ``"planck:3200K"``).
    """
    v = sec.raw(key)
    if isinstance(v, str):
        try:
            ill = parse_illuminant(v)
        except LensrtError as err:
            raise sec.error(err.message, key, err.hint) from None
        if not ill.continuous and (len(ill.lines_nm) != 1 or not grid.min_nm <= ill.lines_nm[0] <= grid.max_nm):
            raise sec.error(f"{v!r}: a scene light holds one spectral line, inside the scene's "
                            f"{grid.min_nm:g}-{grid.max_nm:g} nm", key, "give one line, e.g. lines:532")
        return ill
    if not isinstance(v, dict):
        raise sec.error(f"must be an illuminant name or a table, not {v!r}", key)
    forms = [k for k in ("blackbody_K", "gaussian_nm", "line_nm", "nm", "file") if k in v]
    if len(forms) != 1:
        raise sec.error("give exactly one of gaussian_nm (with fwhm_nm), line_nm, nm/values, file, "
                        "or a name such as \"planck:3200K\"", key)
    form = forms[0]
    inner = Section(v, sec.name, sec.path, sec.line, f"{sec.label} {key}")
    if form == "blackbody_K":
        inner.check_keys({"blackbody_K"})
        ill = planck(inner.number("blackbody_K", lo=100.0, hi=1.0e5))
        warnings.warn(f"{sec.path or 'scene'}: {sec.label} {key} = {{ blackbody_K = {ill.kelvin:g} }} is an old "
                      f"spelling (it goes in the next release): write {key} = \"{ill.name}\"",
                      LensrtDeprecationWarning, stacklevel=2)
        return ill
    if form == "gaussian_nm":
        inner.check_keys({"gaussian_nm", "fwhm_nm"})
        mu = inner.number("gaussian_nm", lo=grid.min_nm, hi=grid.max_nm)
        fwhm = inner.number("fwhm_nm", positive=True)
        sigma = fwhm / (2.0 * math.sqrt(2.0 * math.log(2.0)))
        return tabulated(grid.nm, np.exp(-0.5 * ((grid.nm - mu) / sigma) ** 2), f"gaussian {mu:g} nm, FWHM {fwhm:g} nm")
    if form == "line_nm":
        inner.check_keys({"line_nm"})
        return lines([inner.number("line_nm", lo=grid.min_nm, hi=grid.max_nm)])
    inner.check_keys({"nm", "values"} if form == "nm" else {"file"})
    vals, label = _table_spectrum(sec, key, v, grid, hold_edges=False)
    return tabulated(grid.nm, vals, label)


def parse_emission(sec: Section, kind: tuple[str, dict], grid: WavelengthGrid, *,
                   spectrum_key: str = "spectrum", flux_area_m2: float | None = None,
                   flux_solid_angle_sr: float | None = None) -> Spectrum:
    """An absolute emission spectrum from ``spectrum`` plus exactly one normalisation key.

    ``kind`` is :data:`RADIANCE`, :data:`INTENSITY` or :data:`IRRADIANCE`. A
    photometric key (cd/m^2, cd, lx) scales the spectrum so that
    K_m int S V dlambda equals it; a ``*_scale`` key multiplies the tabulated
    values (then read as W/(m^2 sr nm), W/(sr nm) or W/(m^2 nm)). ``flux_lm``
    is also accepted for a sphere (``flux_area_m2``: its surface, Lambertian:
    L = flux / (pi A)) and a point (``flux_solid_angle_sr`` = 4 pi: I = flux / 4 pi).
    """
    unit, keys = kind
    keys = dict(keys)
    if flux_area_m2 is not None or flux_solid_angle_sr is not None:
        keys["flux_lm"] = "lm"
    given = [k for k in keys if sec.has(k)]
    if len(given) != 1:
        raise sec.error(f"give exactly one of {', '.join(keys)}" + (f" (found {', '.join(given)})" if given else ""))
    key = given[0]
    shape = parse_spectrum_shape(sec, spectrum_key, grid)
    label, line_nm = shape.label, (None if shape.continuous else shape.lines_nm[0])
    rel = shape.values(grid) if line_nm is None else np.ones(grid.n)
    amount = sec.number(key, positive=True)
    if key == "flux_lm":
        photometric = amount / (math.pi * flux_area_m2) if flux_area_m2 is not None else amount / flux_solid_angle_sr
        pname = "cd/m^2" if flux_area_m2 is not None else "cd"
        text = f"{label}, {amount:g} lm"
    elif keys[key] is not None:
        photometric, pname, text = amount, keys[key], f"{label} at {amount:g} {keys[key]}"
    else:
        photometric, pname, text = None, None, f"{label} x {amount:g} {unit}"
    if line_nm is not None:
        unit = unit.replace(" nm)", ")")
        if photometric is not None:
            v = float(np.interp(line_nm, grid.nm, photopic_v(grid)))
            if v <= 0.0:
                raise sec.error(f"a line at {line_nm:g} nm is invisible (V = 0), so {key} cannot set its power",
                                key, "use a *_scale key")
            amount = photometric / (LUMINOUS_EFFICACY_LM_PER_W * v)
        return Spectrum(np.full(grid.n, amount), unit, text, line_nm, shape)
    if photometric is not None:
        try:
            values = scale_to_luminous(rel, photometric, grid, f"{sec.label} {spectrum_key}")
        except LensrtError as err:
            raise sec.error(err.message, key, err.hint) from None
        if key == "flux_lm":
            text += f" ({photometric:.4g} {pname})"
    else:
        values = rel * amount
    return Spectrum(values, unit, text, illuminant=shape)


def parse_reflectance(sec: Section, key: str, grid: WavelengthGrid) -> Spectrum:
    """A spectral reflectance in [0, 1].

    Forms: a number; ``{colorchecker = "dark skin"}`` or ``= 1..24`` (with
    optional ``chart``); ``{srgb = [r, g, b]}`` (encoded, 0-1) or
    ``{linear_rgb = [...]}`` via the Mallett-Yuksel 2019 basis;
    ``{nm = [...], values = [...]}``; ``{file = "x.csv"}``.
    """
    v = sec.raw(key)
    if _is_number(v):
        if not 0.0 <= v <= 1.0:
            raise sec.error(f"reflectance {v:g} is outside [0, 1]", key)
        return Spectrum(np.full(grid.n, float(v)), "1", f"reflectance {v:g}")
    if not isinstance(v, dict):
        raise sec.error(f"must be a number in [0, 1] or a table, not {v!r}", key)
    inner = Section(v, sec.name, sec.path, sec.line, f"{sec.label} {key}")
    if "colorchecker" in v:
        inner.check_keys({"colorchecker", "chart"})
        chart = inner.string("chart", "ColorChecker N Ohta")
        try:
            names = colorchecker_names(chart)
        except LensrtError as err:
            raise inner.error(err.message, "chart", err.hint) from None
        patch = v["colorchecker"]
        if _is_number(patch) and float(patch).is_integer() and 1 <= int(patch) <= len(names):
            idx = int(patch) - 1
        elif isinstance(patch, str) and patch in names:
            idx = names.index(patch)
        else:
            raise inner.error(f"{patch!r} is not a patch number 1-{len(names)} or a name", "colorchecker",
                              "patch names: " + ", ".join(names))
        return Spectrum(colorchecker_reflectances(grid, chart)[idx], "1", f"{chart} {names[idx]!r}")
    if "srgb" in v or "linear_rgb" in v:
        which = "srgb" if "srgb" in v else "linear_rgb"
        inner.check_keys({which})
        rgb = inner.vector(which, 3)
        if np.any(rgb < 0) or np.any(rgb > 1):
            raise inner.error("colour components must be within [0, 1]", which)
        lin = srgb_decode(rgb) if which == "srgb" else rgb
        return Spectrum(linear_rgb_to_reflectance(lin, grid), "1",
                        f"{which} ({', '.join(f'{x:.3g}' for x in rgb)}), Mallett-Yuksel 2019")
    if "nm" in v or "file" in v:
        inner.check_keys({"nm", "values"} if "nm" in v else {"file"})
        vals, label = _table_spectrum(sec, key, v, grid, hold_edges=True)
        if np.any(vals > 1.0 + 1e-9):
            raise sec.error(f"reflectance reaches {vals.max():g}; it must stay within [0, 1]", key)
        return Spectrum(np.clip(vals, 0.0, 1.0), "1", f"reflectance {label}")
    raise inner.error("give a number, colorchecker, srgb, linear_rgb, nm/values or file")
