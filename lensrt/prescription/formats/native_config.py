"""The native format's ``[focus]`` table and ``[[configuration]]`` tables (read and write).

Example (a two-position zoom whose middle group focuses)::

    [focus]
    type = "group"                    # unit | group | floating
    gaps = [5, 10]                    # surface numbers whose thickness changes
    signs = [1, -1]                   # group: change = sign * travel
    # floating: distances_mm = [inf, 700]  and  thickness_mm = [[9.2, 0.6], [8.15, 1.65]]

    [[configuration]]
    name = "wide"
    current = true                    # optional: the configuration a plain load gives
    thickness_mm = { 5 = 1.86, 10 = 36.928 }
    [[configuration]]
    name = "tele"
    thickness_mm = { 5 = 48.678, 10 = 1.536 }

Per-configuration keys: ``name``, ``current``, ``object_distance_mm``, and the
tables by surface number ``thickness_mm``, ``radius_mm``, ``curvature_per_mm``,
``conic``, ``material``, ``semi_diameter_mm``; ``stop`` (surface number),
``aperture_value``, ``fields_y``/``fields_x`` (degrees for angles, mm for heights),
``field_weights``, ``wavelengths_nm``, ``wavelength_weights``, ``primary_nm``. A
key given in one configuration must be given in every one (with the same
surfaces), so nothing silently falls back to the shared value.
"""
from __future__ import annotations

import difflib
import math
from typing import Any

from ...errors import PrescriptionError, located
from ..configurations import ConfigOperand, MultiConfigLens
from ..focusing import FocusMechanism
from ..materials import parse_material
from ..model import Lens

__all__ = ["CONFIG_KEYS", "FOCUS_KEYS", "parse_focus", "parse_configurations", "dumps_focus",
           "dumps_configurations"]

FOCUS_KEYS = {"type", "gaps", "signs", "distances_mm", "thickness_mm"}
CONFIG_KEYS = {"name", "current", "object_distance_mm", "thickness_mm", "radius_mm", "curvature_per_mm", "conic",
               "material", "semi_diameter_mm", "stop", "aperture_value", "fields_y", "fields_x", "field_weights",
               "wavelengths_nm", "wavelength_weights", "primary_nm"}
_SURFACE_TABLES = {"thickness_mm": "thickness", "radius_mm": "curvature", "curvature_per_mm": "curvature",
                   "conic": "conic", "material": "material", "semi_diameter_mm": "semi_diameter"}
_LISTS = {"fields_y": "field_y", "fields_x": "field_x", "field_weights": "field_weight",
          "wavelengths_nm": "wavelength", "wavelength_weights": "wavelength_weight"}


def _num(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PrescriptionError(f"{what} must be a number, not {v!r}")
    return float(v)


def _check(table: dict, allowed: set[str], where: str) -> None:
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, sorted(allowed), n=1)
            raise PrescriptionError(f"unknown key {key!r} in {where}",
                                    hint=f"did you mean {close[0]!r}?" if close else
                                    f"allowed keys: {', '.join(sorted(allowed))}")


def parse_focus(table: Any) -> FocusMechanism:
    """A :class:`FocusMechanism` from the ``[focus]`` table (1-based surface numbers in the file)."""
    if not isinstance(table, dict):
        raise PrescriptionError("focus must be a [focus] table")
    _check(table, FOCUS_KEYS, "[focus]")
    gaps = table.get("gaps", [])
    if not isinstance(gaps, list) or not all(isinstance(g, int) and not isinstance(g, bool) and g >= 1 for g in gaps):
        raise PrescriptionError(f"focus gaps must be a list of surface numbers (1, 2, ...), not {gaps!r}")
    rows = table.get("thickness_mm", [])
    if not isinstance(rows, list) or not all(isinstance(r, list) for r in rows):
        raise PrescriptionError("focus thickness_mm must be a list of rows, one per distance")
    return FocusMechanism(
        str(table.get("type", "unit")), tuple(g - 1 for g in gaps),
        tuple(_num(s, "focus sign") for s in table.get("signs", [])),
        tuple(_num(d, "focus distance") for d in table.get("distances_mm", [])),
        tuple(tuple(_num(v, "focus thickness") for v in r) for r in rows))


def _surface_key(key: str, table: str) -> int:
    try:
        n = int(key)
    except ValueError:
        raise PrescriptionError(f"{table} key {key!r} is not a surface number", hint="e.g. { 5 = 1.86 }") from None
    if n < 1:
        raise PrescriptionError(f"{table} key {key!r}: surface numbers start at 1")
    return n - 1


def _value(key: str, v: Any, lens: Lens, catalogs: list[str] | None) -> Any:
    if key == "material":
        return parse_material(v, catalogs)
    x = _num(v, key)
    if key == "radius_mm":
        if x == 0.0:
            raise PrescriptionError("radius_mm = 0 is not a radius", hint="use inf for a plane")
        return 0.0 if math.isinf(x) else 1.0 / x
    return x


def _operands_of(rows: list[dict], lens: Lens, catalogs: list[str] | None) -> list[tuple[str, int, str, list]]:
    """(kind, index, key, values) per quantity; every configuration must give the same keys."""
    first = rows[0]
    out: list[tuple[str, int, str, list]] = []
    angle = math.pi / 180.0 if lens.fields.kind == "angle" else 1.0
    for key in sorted(k for k in first if k not in ("name", "current")):
        for i, row in enumerate(rows):
            if key not in row:
                raise PrescriptionError(f"configuration {i + 1} has no {key} (configuration 1 gives it)",
                                        hint="give a changing quantity in every configuration")
        if key in _SURFACE_TABLES:
            surf = sorted(first[key])
            for i, row in enumerate(rows):
                if not isinstance(row[key], dict) or sorted(row[key]) != surf:
                    raise PrescriptionError(f"configuration {i + 1}: {key} must name the same surfaces as "
                                            f"configuration 1 ({', '.join(surf)})")
            for s in surf:
                vals = [_value(key, row[key][s], lens, catalogs) for row in rows]
                out.append((_SURFACE_TABLES[key], _surface_key(s, key), f"{key} {s}", vals))
        elif key in _LISTS:
            n = len(first[key]) if isinstance(first[key], list) else -1
            for i, row in enumerate(rows):
                if not isinstance(row[key], list) or len(row[key]) != n:
                    raise PrescriptionError(f"configuration {i + 1}: {key} must be a list of {n} numbers")
            scale = angle if key.startswith("fields_") else 1.0
            for j in range(n):
                out.append((_LISTS[key], j, f"{key}[{j + 1}]", [_num(row[key][j], key) * scale for row in rows]))
        elif key == "stop":
            out.append(("stop_surface", -1, "stop", [int(_num(row[key], key)) - 1 for row in rows]))
        elif key == "primary_nm":
            out.append(("primary_wavelength", -1, key, [_primary(row, lens) for row in rows]))
        elif key == "object_distance_mm":
            out.append(("object_distance", -1, key, [_num(row[key], key) for row in rows]))
        elif key == "aperture_value":
            out.append(("aperture", -1, key, [_num(row[key], key) for row in rows]))
    return out


def _primary(row: dict, lens: Lens) -> int:
    nm = row.get("wavelengths_nm", list(lens.wavelengths.nm))
    p = _num(row["primary_nm"], "primary_nm")
    if p not in nm:
        raise PrescriptionError(f"primary_nm = {p:g} is not one of the configuration's wavelengths {nm}")
    return nm.index(p)


def parse_configurations(lens: Lens, rows: Any, lines: list[int], catalogs: list[str] | None) -> MultiConfigLens:
    """A :class:`MultiConfigLens` from the ``[[configuration]]`` tables over the shared ``lens``."""
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise PrescriptionError("configuration must be an array of [[configuration]] tables", path=lens.path)
    for i, row in enumerate(rows):
        with located(lens.path, lines[i] if i < len(lines) else None):
            _check(row, CONFIG_KEYS, "[[configuration]]")
    names = [str(row.get("name", i + 1)) for i, row in enumerate(rows)]
    current = [i for i, row in enumerate(rows) if row.get("current", False) is True]
    if len(current) > 1:
        raise PrescriptionError(f"{len(current)} configurations say current = true", path=lens.path,
                                line=lines[current[1]] if current[1] < len(lines) else None, hint="mark one")
    with located(lens.path, lines[0] if lines else None):
        ops = [ConfigOperand(kind, idx, tuple(vals), source=src, line=lines[0] if lines else None)
               for kind, idx, src, vals in _operands_of(rows, lens, catalogs)]
    return MultiConfigLens(lens, tuple(names), tuple(ops), current[0] if current else 0).validate()


# ---------------------------------------------------------------------------
# writer

def dumps_focus(focus: FocusMechanism, fmt: Any) -> list[str]:
    """Lines of the ``[focus]`` table (empty for unit focusing); ``fmt`` formats a float."""
    if focus.is_unit:
        return []
    out = ["", "[focus]", f'type = "{focus.kind}"', "gaps = [" + ", ".join(str(g + 1) for g in focus.gaps) + "]"]
    if focus.kind == "group":
        out.append("signs = [" + ", ".join(fmt(s) for s in focus.signs) + "]")
    else:
        out.append("distances_mm = [" + ", ".join(fmt(d) for d in focus.distances_mm) + "]")
        out.append("thickness_mm = [" + ", ".join("[" + ", ".join(fmt(v) for v in row) + "]"
                                                  for row in focus.thickness_mm) + "]")
    return out


def dumps_configurations(family: MultiConfigLens, fmt: Any, fmt_deg: Any, fmt_material: Any) -> list[str]:
    """Lines of the ``[[configuration]]`` tables of ``family``."""
    out: list[str] = []
    for i, name in enumerate(family.names):
        out += ["", "[[configuration]]", f"name = {_quote(name)}"]
        if i == family.current:
            out.append("current = true")
        tables: dict[str, list[str]] = {}
        lists: dict[str, list[str]] = {}
        for op in family.operands:
            v = op.values[i]
            if op.kind in ("thickness", "conic", "semi_diameter", "curvature", "material"):
                key = {"thickness": "thickness_mm", "conic": "conic", "semi_diameter": "semi_diameter_mm",
                       "curvature": "curvature_per_mm", "material": "material"}[op.kind]
                text = fmt_material(v) if op.kind == "material" else fmt(v)
                tables.setdefault(key, []).append(f"{op.index + 1} = {text}")
            elif op.kind in ("field_y", "field_x", "field_weight", "wavelength", "wavelength_weight"):
                lists[{v2: k for k, v2 in _LISTS.items()}[op.kind]] = []
            elif op.kind == "stop_surface":
                out.append(f"stop = {int(v) + 1}")
            elif op.kind == "primary_wavelength":
                nm = family.configuration(i + 1).wavelengths.nm
                out.append(f"primary_nm = {fmt(nm[int(v)])}")
            else:
                out.append(f"{'object_distance_mm' if op.kind == 'object_distance' else 'aperture_value'} = {fmt(v)}")
        out += [f"{k} = {{ " + ", ".join(v) + " }" for k, v in tables.items()]
        if lists:
            lens = family.configuration(i + 1)
            angle = fmt_deg if lens.fields.kind == "angle" else fmt
            full = {"fields_y": [angle(v) for v in lens.fields.y], "fields_x": [angle(v) for v in lens.fields.x],
                    "field_weights": [fmt(v) for v in lens.fields.weights],
                    "wavelengths_nm": [fmt(v) for v in lens.wavelengths.nm],
                    "wavelength_weights": [fmt(v) for v in lens.wavelengths.weights]}
            out += [f"{k} = [" + ", ".join(full[k]) + "]" for k in lists]
    return out


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'
