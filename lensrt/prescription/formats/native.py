"""lensrt's native lens format: TOML, read with ``tomllib``, written by :func:`write_native`.

Lengths are always mm and angles degrees (the key says so); every key is
checked, so a typo is an error, never silently ignored. Example::

    [lens]
    name = "Double Gauss F/2"
    source = "CODE V sample lens ag_dblgauss.seq"

    [system]
    object_distance_mm = inf          # or a number
    image_radius_mm = -80.0           # optional: a spherical image surface (or image_curvature_per_mm)
    catalogs = ["Schott"]             # search order for bare glass names (optional)

    [aperture]
    type = "epd"                      # epd | image_fno | object_na | float_by_stop
    value = 50.0

    [iris]                            # optional
    blades = 7                        # 0 = circular
    rotation_deg = 0.0

    [fields]
    type = "angle"                    # angle | object_height | paraxial_image_height | real_image_height
    y = [0.0, 10.0, 14.0]             # degrees for angles, mm for heights
    weights = [1.0, 1.0, 1.0]

    [wavelengths]
    nm = [656.3, 587.6, 486.1]
    primary_nm = 587.6

    [[surface]]
    radius_mm = 56.20238              # inf for a plane (or curvature_per_mm = ...)
    thickness_mm = 8.75
    material = "N-SSK2_SCHOTT"        # or "air", {glass=, catalog=}, {nd=, vd=}, {index=}
    semi_diameter_mm = 25.0           # optional: computed when absent
    conic = 0.0                       # optional
    asphere = { A4 = 1.2e-6 }         # optional even asphere, coefficient of r^4 (mm^-3) ...
    shape = { kind = "odd", coefficients = [0.0, 0.0, 1e-4] }  # optional: odd, qbfs, qcon, biconic,
                                      # toroidal (native_shapes; docs/guide/surface-types.md)
    stop = true                       # exactly one surface
"""
from __future__ import annotations

import difflib
import math
import re
import tomllib
from pathlib import Path
from typing import Any

from ...errors import PrescriptionError, UnknownGlassError, located
from ..configurations import MultiConfigLens
from ..focusing import UNIT_FOCUS
from ..glass_lookup import lookup_any, user_catalogs
from ..limits import check_asphere_power, check_catalog_names
from ..materials import AIR, CATALOGS, CatalogGlass, ConstantIndex, Material, ModelGlass, parse_material
from ..model import Aperture, Fields, Iris, Lens, Surface, Wavelengths
from .native_config import dumps_configurations, dumps_focus, parse_configurations, parse_focus
from .native_geometry import (SURFACE_KEYS, SYSTEM_KEYS, read_surface_geometry, read_system_geometry,
                              write_surface_geometry, write_system_geometry)
from .native_shapes import read_shape, write_shape

__all__ = ["read_native", "loads_native", "write_native", "dumps_native"]

_KEYS = {
    "": {"format", "version", "lens", "system", "aperture", "iris", "fields", "wavelengths", "surface",
         "focus", "configuration"},
    "lens": {"name", "source", "notes"},
    "system": {"object_distance_mm", "object_material", "catalogs", "image_radius_mm", "image_curvature_per_mm"}
    | SYSTEM_KEYS,
    "aperture": {"type", "value"},
    "iris": {"blades", "rotation_deg", "roundness", "obstruction_ratio"},
    "fields": {"type", "y", "x", "weights"},
    "wavelengths": {"nm", "weights", "primary_nm"},
    "surface": {"radius_mm", "curvature_per_mm", "thickness_mm", "material", "semi_diameter_mm",
                "conic", "asphere", "stop", "label", "shape"} | SURFACE_KEYS,
}
_ASPH_KEY = re.compile(r"^A(\d+)$")
#: the native format's name and version, as written in every file
FORMAT_NAME, FORMAT_VERSION = "lensrt-lens", 1


def _check_keys(table: dict, section: str, line: int | None, path: str | None) -> None:
    allowed = _KEYS[section]
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, sorted(allowed), n=1)
            where = f"[{section}]" if section else "the top level"
            raise PrescriptionError(f"unknown key {key!r} in {where}", path=path, line=line,
                                    hint=f"did you mean {close[0]!r}?" if close else
                                    f"allowed keys: {', '.join(sorted(allowed))}")


def _section_lines(text: str, array: str = "surface") -> tuple[dict[str, int], list[int]]:
    """1-based line of each ``[section]`` header and of each ``[[array]]`` header."""
    sections: dict[str, int] = {}
    surfaces: list[int] = []
    for no, raw in enumerate(text.splitlines(), start=1):
        s = raw.strip()
        if s.startswith("[[") and s.split("]]")[0][2:].strip() == array:
            surfaces.append(no)
        elif s.startswith("[") and not s.startswith("[["):
            sections.setdefault(s[1:].split("]")[0].strip(), no)
    return sections, surfaces


def _float_list(value: Any, what: str) -> tuple[float, ...]:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (float(value),)
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise PrescriptionError(f"{what} must be a list of numbers, not {value!r}")
    return tuple(float(v) for v in value)


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise PrescriptionError(f"{what} must be a number, not {value!r}")
    return float(value)


def _material_spec(spec: object, catalogs: list[str] | None) -> Material:
    """:func:`parse_material`, and for a glass name no vendor catalog holds: the same name (exactly, or an
    alias such as ``CAF2``, ``F_SILICA``, ``GERMANIUM``) in the refractiveindex.info database or a user .agf."""
    try:
        return parse_material(spec, catalogs)
    except UnknownGlassError:
        name = spec if isinstance(spec, str) else spec.get("glass") if isinstance(spec, dict) else None
        found = lookup_any(str(name), user_catalogs()) if name else None
        if found is None:
            raise
        return found


def _surface(row: dict, catalogs: list[str] | None, line: int | None) -> Surface:
    if "radius_mm" in row and "curvature_per_mm" in row:
        raise PrescriptionError("give radius_mm or curvature_per_mm, not both")
    if "radius_mm" in row:
        r = _number(row["radius_mm"], "radius_mm")
        if r == 0.0 or math.isnan(r):
            raise PrescriptionError(f"radius_mm = {r!r} is not a radius", hint="use inf for a plane")
        c = 0.0 if math.isinf(r) else 1.0 / r
    else:
        c = _number(row.get("curvature_per_mm", 0.0), "curvature_per_mm")
    if "thickness_mm" not in row:
        raise PrescriptionError("surface has no thickness_mm", hint="add thickness_mm = <mm to the next surface>")
    asph_table = row.get("asphere", {})
    if not isinstance(asph_table, dict):
        raise PrescriptionError("asphere must be a table like { A4 = 1e-6, A6 = -2e-9 }")
    coeffs: dict[int, float] = {}
    for key, val in asph_table.items():
        m = _ASPH_KEY.match(key)
        if not m or int(m.group(1)) < 2 or int(m.group(1)) % 2:
            raise PrescriptionError(f"aspheric coefficient key {key!r} is not A2, A4, A6, ...")
        check_asphere_power(int(m.group(1)), f"asphere key {key}")
        coeffs[int(m.group(1))] = _number(val, key)
    asphere = tuple(coeffs.get(p, 0.0) for p in range(2, 2 + 2 * (max(coeffs) // 2), 2)) if coeffs else ()
    stop = row.get("stop", False)
    if not isinstance(stop, bool):
        raise PrescriptionError(f"stop must be true or false, not {stop!r}")
    sd = row.get("semi_diameter_mm")
    return Surface(
        curvature_per_mm=c,
        thickness_mm=_number(row["thickness_mm"], "thickness_mm"),
        material=_material_spec(row.get("material", "air"), catalogs),
        semi_diameter_mm=None if sd is None else _number(sd, "semi_diameter_mm"),
        conic=_number(row.get("conic", 0.0), "conic"),
        asphere=asphere,
        shape=read_shape(row.get("shape")),
        is_stop=stop,
        label=str(row.get("label", "")),
        line=line,
        **read_surface_geometry(row),
    )


def _check_format(doc: dict, text: str, path: str | None) -> None:
    """``format`` and ``version`` at the top level, when given, must be the ones this reader knows."""
    def line_of(key: str) -> int | None:
        m = re.search(rf"^[ \t]*{key}[ \t]*=", text, re.M)
        return text.count("\n", 0, m.start()) + 1 if m else None
    fmt = doc.get("format", FORMAT_NAME)
    if fmt != FORMAT_NAME:
        raise PrescriptionError(f"format = {fmt!r} is not a lensrt lens", path=path, line=line_of("format"),
                                hint=f'a native lens file says format = "{FORMAT_NAME}"')
    ver = doc.get("version", FORMAT_VERSION)
    if isinstance(ver, bool) or not isinstance(ver, int) or not 1 <= ver <= FORMAT_VERSION:
        raise PrescriptionError(f"version = {ver!r}: this lensrt reads version {FORMAT_VERSION} of the native format",
                                path=path, line=line_of("version"),
                                hint="upgrade lensrt for a newer file, or fix the version number")


def loads_native(text: str, path: str | Path | None = None) -> Lens | MultiConfigLens:
    """Parse native TOML text into a :class:`Lens` (semi-diameters may be left to compute).

    A file with ``[[configuration]]`` tables gives a
    :class:`~lensrt.prescription.configurations.MultiConfigLens`
    (:mod:`lensrt.prescription.formats.native_config`).
    """
    spath = str(path) if path is not None else None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        m = re.search(r"line (\d+)", str(err))
        raise PrescriptionError(f"not valid TOML: {err}", path=spath, line=int(m.group(1)) if m else None,
                                hint="see the native format in docs/reference/lens-format.md") from None
    sections, surface_lines = _section_lines(text)
    _check_keys(doc, "", None, spath)
    _check_format(doc, text, spath)
    if "surface" not in doc:
        raise PrescriptionError("no [[surface]] tables: this is not a lensrt lens file", path=spath,
                                hint="a native lens lists its surfaces as [[surface]] tables")
    for sec in ("lens", "system", "aperture", "iris", "fields", "wavelengths"):
        if sec in doc:
            if not isinstance(doc[sec], dict):
                raise PrescriptionError(f"{sec} must be a [{sec}] table", path=spath)
            _check_keys(doc[sec], sec, sections.get(sec), spath)
    lens_t, sys_t = doc.get("lens", {}), doc.get("system", {})
    catalogs = sys_t.get("catalogs")
    if catalogs is not None and (not isinstance(catalogs, list) or not all(isinstance(c, str) for c in catalogs)):
        raise PrescriptionError("catalogs must be a list of catalog names", path=spath, line=sections.get("system"))
    if catalogs is not None:
        with located(spath, sections.get("system")):
            check_catalog_names(catalogs, CATALOGS)

    rows = doc["surface"]
    if not isinstance(rows, list) or not rows:
        raise PrescriptionError("surface must be an array of [[surface]] tables", path=spath)
    surfaces = []
    for i, row in enumerate(rows):
        line = surface_lines[i] if i < len(surface_lines) else None
        with located(spath, line):
            if not isinstance(row, dict):
                raise PrescriptionError(f"surface {i + 1} is not a table")
            _check_keys(row, "surface", line, spath)
            surfaces.append(_surface(row, catalogs, line))

    with located(spath, sections.get("aperture")):
        ap = doc.get("aperture", {"type": "float_by_stop", "value": 0.0})
        aperture = Aperture(str(ap.get("type", "epd")), _number(ap.get("value", 0.0), "aperture value"))
    with located(spath, sections.get("iris")):
        ir = doc.get("iris", {})
        blades = ir.get("blades", 0)
        if isinstance(blades, bool) or not isinstance(blades, int):
            raise PrescriptionError(f"iris blades must be an integer, not {blades!r}")
        iris = Iris(blades, math.radians(_number(ir.get("rotation_deg", 0.0), "rotation_deg")),
                    _number(ir.get("roundness", 0.0), "roundness"),
                    _number(ir.get("obstruction_ratio", 0.0), "obstruction_ratio"))
    with located(spath, sections.get("fields")):
        fd = doc.get("fields", {"y": [0.0]})
        kind = str(fd.get("type", "angle"))
        scale = math.pi / 180.0 if kind == "angle" else 1.0
        y = tuple(v * scale for v in _float_list(fd.get("y", [0.0]), "fields.y"))
        x = tuple(v * scale for v in _float_list(fd["x"], "fields.x")) if "x" in fd else ()
        w = _float_list(fd["weights"], "fields.weights") if "weights" in fd else ()
        fields = Fields(kind, y, x, w)
    with located(spath, sections.get("wavelengths")):
        wd = doc.get("wavelengths", {"nm": [587.5618]})
        nm = _float_list(wd.get("nm", [587.5618]), "wavelengths.nm")
        primary = 0
        if "primary_nm" in wd:
            p = _number(wd["primary_nm"], "primary_nm")
            if p not in nm:
                raise PrescriptionError(f"primary_nm = {p:g} is not one of nm = {list(nm)}")
            primary = nm.index(p)
        elif len(nm) > 1:
            primary = len(nm) // 2
        wavelengths = Wavelengths(nm, _float_list(wd["weights"], "wavelengths.weights") if "weights" in wd else (),
                                  primary)
    with located(spath, sections.get("system")):
        dist = _number(sys_t.get("object_distance_mm", math.inf), "object_distance_mm")
        obj_mat = _material_spec(sys_t.get("object_material", "air"), catalogs)
        geometry = read_system_geometry(sys_t)
        geometry["image_curvature_per_mm"] = _image_curvature(sys_t)
    notes = lens_t.get("notes", {})
    if not isinstance(notes, dict):
        raise PrescriptionError("lens.notes must be a table of strings", path=spath, line=sections.get("lens"))
    with located(spath, sections.get("focus")):
        focus = parse_focus(doc["focus"]) if "focus" in doc else UNIT_FOCUS
    with located(spath, None):
        lens = Lens(surfaces=tuple(surfaces), aperture=aperture, fields=fields, wavelengths=wavelengths,
                    object_distance_mm=dist, object_material=obj_mat, iris=iris,
                    name=str(lens_t.get("name", "")), source=str(lens_t.get("source", "")),
                    notes=tuple((str(k), str(v)) for k, v in notes.items()), path=spath, focus=focus, **geometry)
    if "configuration" not in doc:
        return lens
    with located(spath, None):
        return parse_configurations(lens, doc["configuration"], _section_lines(text, "configuration")[1], catalogs)


def _image_curvature(sys_t: dict) -> float:
    """``image_radius_mm`` (0 or inf: a plane) or ``image_curvature_per_mm`` of ``[system]``; 0 without either."""
    if "image_radius_mm" in sys_t and "image_curvature_per_mm" in sys_t:
        raise PrescriptionError("both image_radius_mm and image_curvature_per_mm in [system]", hint="give one")
    if "image_curvature_per_mm" in sys_t:
        return _number(sys_t["image_curvature_per_mm"], "image_curvature_per_mm")
    r = _number(sys_t.get("image_radius_mm", math.inf), "image_radius_mm")
    return 0.0 if r == 0.0 or math.isinf(r) else 1.0 / r


def read_native(path: str | Path, text: str | None = None) -> Lens | MultiConfigLens:
    """Read a native TOML lens file."""
    if text is None:
        text = Path(path).read_text(encoding="utf-8")
    return loads_native(text, path)


# ---------------------------------------------------------------------------
# writer

def _f(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    r = repr(float(x))
    return r


def _deg(angle_rad: float) -> str:
    """Degrees text that reads back (``x * pi / 180``) to exactly ``angle_rad``.

    ``degrees(radians(x))`` is not always ``x`` in floating point, so the
    neighbours of ``degrees(angle_rad)`` are tried; every angle a reader
    produced from degrees is found within a few ulps.
    """
    d = math.degrees(angle_rad)
    up = down = d
    for _ in range(8):
        for cand in (up, down):
            if cand * (math.pi / 180.0) == angle_rad:
                return _f(cand)
        up, down = math.nextafter(up, math.inf), math.nextafter(down, -math.inf)
    return _f(d)


def _s(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _material(m: Material) -> str:
    if m.is_air and not isinstance(m, ConstantIndex):
        return '"air"'
    if isinstance(m, CatalogGlass) and not m.source.startswith("opticalglass") and m.source:
        # a glass of the database, a user .agf or a CODE V PRV block: its packed formula travels with the lens
        rng = "" if m.range_nm is None else f", range_nm = [{_f(m.range_nm[0])}, {_f(m.range_nm[1])}]"
        return (f"{{ glass = {_s(m.name)}, catalog = {_s(m.catalog)}, source = {_s(m.source)}, "
                f"formula = {_s(m.formula)}, coefficients = [{', '.join(repr(float(c)) for c in m.coefficients)}]"
                f"{rng}, range_is_limit = {'true' if m.range_is_limit else 'false'} }}")
    if isinstance(m, CatalogGlass):
        return f"{{ glass = {_s(m.name)}, catalog = {_s(m.catalog)} }}"
    if isinstance(m, ModelGlass):
        name = "" if m.name == ModelGlass(m.nd, m.vd).name else f", name = {_s(m.name)}"
        return f"{{ nd = {_f(m.nd)}, vd = {_f(m.vd)}{name} }}"
    if isinstance(m, ConstantIndex):
        name = "" if m.name == ConstantIndex(m.n, exotic=m.exotic).name else f", name = {_s(m.name)}"
        return f"{{ index = {_f(m.n)}{name}{', exotic = true' if m.exotic else ''} }}"
    raise PrescriptionError(f"cannot write material {m!r} in the native format")


def dumps_native(lens: Lens | MultiConfigLens) -> str:
    """The native TOML text of ``lens``; :func:`loads_native` gives back an equal lens.

    Computed (automatic) semi-diameters are not written, so they are computed
    again on load. A :class:`MultiConfigLens` is written as its shared lens, its
    ``[focus]`` table and its ``[[configuration]]`` tables.
    """
    family = lens if isinstance(lens, MultiConfigLens) else None
    lens = family.base if family is not None else lens
    out = ["# lensrt lens prescription (native TOML; lengths in mm, angles in degrees)",
           f'format = "{FORMAT_NAME}"', f"version = {FORMAT_VERSION}", "", "[lens]", f"name = {_s(lens.name)}",
           f"source = {_s(lens.source)}"]
    notes = [(k, v) for k, v in lens.notes]
    if notes:
        out.append("notes = { " + ", ".join(f"{_s(k)} = {_s(v)}" for k, v in notes) + " }")
    out += ["", "[system]", f"object_distance_mm = {_f(lens.object_distance_mm)}"]
    if lens.object_material != AIR:
        out.append(f"object_material = {_material(lens.object_material)}")
    if lens.image_curvature_per_mm != 0.0:
        out.append(f"image_curvature_per_mm = {_f(lens.image_curvature_per_mm)}")
    out += write_system_geometry(lens)
    out += ["", "[aperture]", f"type = {_s(lens.aperture.kind)}", f"value = {_f(lens.aperture.value)}"]
    ir = lens.iris
    out += ["", "[iris]", f"blades = {ir.blades}", f"rotation_deg = {_deg(ir.rotation_rad)}"]
    if ir.roundness:
        out.append(f"roundness = {_f(ir.roundness)}")
    if ir.obstruction_ratio:
        out.append(f"obstruction_ratio = {_f(ir.obstruction_ratio)}")
    fd = lens.fields
    conv = _deg if fd.kind == "angle" else _f
    out += ["", "[fields]", f"type = {_s(fd.kind)}",
            "y = [" + ", ".join(conv(v) for v in fd.y) + "]"]
    if any(fd.x):
        out.append("x = [" + ", ".join(conv(v) for v in fd.x) + "]")
    out.append("weights = [" + ", ".join(_f(v) for v in fd.weights) + "]")
    wl = lens.wavelengths
    out += ["", "[wavelengths]", "nm = [" + ", ".join(_f(v) for v in wl.nm) + "]",
            "weights = [" + ", ".join(_f(v) for v in wl.weights) + "]", f"primary_nm = {_f(wl.primary_nm)}"]
    for i, s in enumerate(lens.surfaces):
        out += ["", f"[[surface]]  # {i + 1}" + (" (stop)" if s.is_stop else "")]
        c = s.curvature_per_mm
        if c == 0.0:
            out.append("radius_mm = inf")
        elif 1.0 / (1.0 / c) == c:
            out.append(f"radius_mm = {_f(1.0 / c)}")
        else:
            out.append(f"curvature_per_mm = {_f(c)}  # R = {1.0 / c:.10g} mm")
        out.append(f"thickness_mm = {_f(s.thickness_mm)}")
        out.append(f"material = {_material(s.material)}")
        if s.semi_diameter_mm is not None and not s.semi_diameter_auto:
            out.append(f"semi_diameter_mm = {_f(s.semi_diameter_mm)}")
        if s.conic:
            out.append(f"conic = {_f(s.conic)}")
        if s.asphere:
            out.append("asphere = { " + ", ".join(f"A{2 * k + 2} = {_f(a)}" for k, a in enumerate(s.asphere)
                                                   if a != 0.0) + " }")
        out += write_shape(s.shape, _f)
        if s.is_stop:
            out.append("stop = true")
        if s.label:
            out.append(f"label = {_s(s.label)}")
        out += write_surface_geometry(s)
    out += dumps_focus(lens.focus, _f)
    if family is not None:
        out += dumps_configurations(family, _f, _deg, _material)
    return "\n".join(out) + "\n"


def write_native(lens: Lens | MultiConfigLens, path: str | Path) -> None:
    """Write ``lens`` to ``path`` in the native format."""
    Path(path).write_text(dumps_native(lens), encoding="utf-8")
