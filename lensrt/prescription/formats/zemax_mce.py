"""Zemax multi-configuration editor data (``MNUM`` and the operand rows after it).

A ``.zmx`` file with ``MNUM n c`` (n configurations, the current one c) lists
the editor's rows operand by operand, one line per configuration::

    MNUM 3 1
    THIC 5 1 1.86 0 0 0 1 1 1 0 0 "" 0      <- operand, number, configuration, value, ...
    THIC 5 2 25.27 ...
    THIC 5 3 48.678 ...
    MOFF 0 1 "" ...                          <- an empty (off) row

The lens data in the file hold the current configuration's values; each operand
gives its quantity's value in every configuration. Read (lens units converted to
mm, wavelengths from micrometres to nm, angles from degrees): ``THIC`` (surface
0 is the object distance), ``CRVT``, ``CONN``, ``GLSS``, ``SDIA``, ``STPS``
(the stop surface), ``APER`` (the system aperture's value), ``YFIE``/``XFIE``/
``FLWT`` (field point), ``WAVE``/``WLWT`` (wavelength), ``PRWV`` (primary
wavelength); ``MOFF`` rows and ``LTTL`` (the configuration's title, used as its
name) carry no optics. ``TEMP``/``PRES`` (temperature, pressure) are outside
lensrt's model: a file whose configurations differ only in them loads its first
configuration with a note; among other operands they are dropped with a note.
Any other operand is an error naming it.
"""
from __future__ import annotations

import math
import re
from typing import Callable

from ...errors import PrescriptionError
from ...units import NM_PER_UM, deg_to_rad
from ..configurations import ConfigOperand, MultiConfigLens
from ..materials import Material
from ..model import Lens
from ._common import parse_number

__all__ = ["MCE_OPERANDS", "MCE_IGNORED", "MCE_THERMAL", "MultiConfigReader"]

#: operand -> (configuration operand kind, what the number names)
MCE_OPERANDS: dict[str, tuple[str, str]] = {
    "THIC": ("thickness", "surface"), "CRVT": ("curvature", "surface"), "CONN": ("conic", "surface"),
    "GLSS": ("material", "surface"), "SDIA": ("semi_diameter", "surface"), "STPS": ("stop_surface", "none"),
    "APER": ("aperture", "none"), "YFIE": ("field_y", "field"), "XFIE": ("field_x", "field"),
    "FLWT": ("field_weight", "field"), "WAVE": ("wavelength", "wavelength"),
    "WLWT": ("wavelength_weight", "wavelength"), "PRWV": ("primary_wavelength", "none"),
}
#: rows without optics
MCE_IGNORED = {"MOFF": "an empty row", "LTTL": "the configuration's title"}
#: environment operands lensrt does not model
MCE_THERMAL = {"TEMP": "temperature", "PRES": "pressure"}
_ROW = re.compile(r"^([A-Z][A-Z0-9]{3})\s+(-?\d+)\s+(\d+)(\s|$)")


class MultiConfigReader:
    """Collects the rows after ``MNUM`` and builds a :class:`MultiConfigLens` over the base lens."""

    def __init__(self, path: str | None, count: int, current: int, line: int) -> None:
        if count < 1:
            raise PrescriptionError(f"MNUM {count}: a lens has at least one configuration", path=path, line=line)
        if not 1 <= current <= count:
            raise PrescriptionError(f"MNUM {count} {current}: the current configuration is not one of 1..{count}",
                                    path=path, line=line)
        self.path, self.count, self.current, self.line = path, count, current - 1, line
        self.rows: dict[tuple[str, int], dict[int, tuple[str, int]]] = {}
        self.order: list[tuple[str, int]] = []
        self.titles: dict[int, str] = {}
        self.thermal: list[str] = []

    def accepts(self, raw: str) -> bool:
        """True for a multi-configuration row (``OPER n config ...`` with config in 1..count)."""
        m = _ROW.match(raw.strip())
        return bool(m) and (m.group(1) in MCE_OPERANDS or m.group(1) in MCE_IGNORED or
                            m.group(1) in MCE_THERMAL or 1 <= int(m.group(3)) <= self.count)

    def add(self, raw: str, no: int) -> None:
        """Record one row; an operand lensrt cannot apply is an error naming it."""
        toks = raw.split()
        kw, number, config = toks[0].upper(), int(toks[1]), int(toks[2])
        value = toks[3] if len(toks) > 3 else ""
        if not 1 <= config <= self.count:
            raise PrescriptionError(f"{kw} {number}: configuration {config} is out of range (MNUM gives "
                                    f"{self.count})", path=self.path, line=no)
        if kw in MCE_IGNORED:
            if kw == "LTTL" and value.strip('"'):
                self.titles[config - 1] = " ".join(toks[3:]).split('"')[1] if value.startswith('"') else value
            return
        if kw in MCE_THERMAL:
            self.thermal.append(f"{kw} ({MCE_THERMAL[kw]}, line {no})")
            return
        if kw not in MCE_OPERANDS:
            raise PrescriptionError(f"multi-configuration operand {kw} is not supported", path=self.path, line=no,
                                    hint=f"lensrt reads {', '.join(MCE_OPERANDS)} (and MOFF, LTTL, TEMP, PRES); "
                                         "export the configuration you want as its own .zmx file")
        key = (kw, number)
        if key not in self.rows:
            self.rows[key] = {}
            self.order.append(key)
        if config - 1 in self.rows[key]:
            raise PrescriptionError(f"{kw} {number} gives configuration {config} twice", path=self.path, line=no)
        self.rows[key][config - 1] = (value.strip('"'), no)

    # -- assembly ----------------------------------------------------------------
    def operand(self, key: tuple[str, int], lens: Lens, unit_mm: float,
                glass: Callable[[str, int], Material]) -> ConfigOperand:
        kw, number = key
        rows = self.rows[key]
        missing = [c + 1 for c in range(self.count) if c not in rows]
        first_line = min(no for _, no in rows.values())
        if missing:
            raise PrescriptionError(f"{kw} {number} has no value for configuration {missing[0]} of {self.count}",
                                    path=self.path, line=first_line, hint="give the operand in every configuration")
        kind, names = MCE_OPERANDS[kw]
        index = number - 1 if names in ("surface", "field", "wavelength") else -1
        if kw == "THIC" and number == 0:
            kind, index = "object_distance", -1
        values = tuple(self.value(kw, kind, rows[c][0], rows[c][1], lens, unit_mm, glass) for c in range(self.count))
        if names == "surface" and not (kind == "object_distance") and not 1 <= number <= lens.n_surfaces:
            raise PrescriptionError(f"{kw} {number}: surface {number} is not a lens surface (the file has surfaces "
                                    f"1..{lens.n_surfaces} between the object and the image)",
                                    path=self.path, line=first_line)
        return ConfigOperand(kind, index, values, source=f"{kw} {number}", line=first_line)

    def value(self, kw: str, kind: str, tok: str, no: int, lens: Lens, unit_mm: float,
              glass: Callable[[str, int], Material]) -> object:
        if kind == "material":
            if not tok:
                raise PrescriptionError(f"{kw} without a glass name", path=self.path, line=no)
            return glass(tok, no)
        allow_inf = kind == "object_distance"
        v = parse_number(tok or "0", f"{kw} value", path=self.path, line=no, allow_inf=allow_inf)
        if kind == "object_distance":
            return math.inf if v >= 1e10 else v * unit_mm
        if kind in ("thickness", "semi_diameter"):
            return v * unit_mm
        if kind == "curvature":
            return v / unit_mm
        if kind == "aperture":
            return v * unit_mm if lens.aperture.kind == "epd" else v
        if kind in ("field_y", "field_x"):
            return deg_to_rad(v) if lens.fields.kind == "angle" else v * unit_mm
        if kind == "wavelength":
            return round(v * NM_PER_UM, 6)
        if kind == "stop_surface":
            return int(v) - 1
        if kind == "primary_wavelength":
            return int(v) - 1
        return v

    def build(self, lens: Lens, unit_mm: float, glass: Callable[[str, int], Material]) -> Lens | MultiConfigLens:
        """The configurations over ``lens`` (the file's current configuration)."""
        ops = tuple(self.operand(k, lens, unit_mm, glass) for k in self.order)
        if self.thermal:
            note = ("multi_configuration", "ignored temperature/pressure operands " + ", ".join(self.thermal[:4]) +
                    ": lensrt uses catalog indices at 20 C and 1 atm")
            lens = lens.with_note(*note)
            if not ops:
                return lens.with_note("multi_configuration", f"{self.count} configurations differ only in "
                                      "temperature/pressure: loaded as one lens (the first configuration's data)")
        names = tuple(self.titles.get(c, str(c + 1)) for c in range(self.count))
        if len(set(names)) != len(names):
            names = tuple(str(c + 1) for c in range(self.count))
        return MultiConfigLens(lens, names, ops, self.current).validate()
