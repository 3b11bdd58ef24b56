"""Scene files (TOML) -> :class:`~lensrt.render.scene.model.Scene`, every key checked.

The format, frame and units are documented in docs/reference/scene-format.md and in
:mod:`lensrt.render.scene.model`. In short: positions and sizes in the unit of
``[scene] units`` (m, cm, mm), converted to mm here; the scene origin is the
first lens vertex, light travels toward +z, the scene lies at z < 0, +y is up;
emission in absolute radiometric units (set by a luminance, luminous
intensity, flux or illuminance through V(lambda) and K_m = 683 lm/W, or by a
scale on the tabulated spectrum).
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import LensrtError
from ...library import scenes_dir
from ...units import MM_PER_M, MM_PER_UNIT
from .model import (CameraSpec, MeshObject, Plane, PointLight, RenderSettings, Scene, SensorSpec,
                          SpectralSettings, SphereLight, Spectrum)
from ...colour import WavelengthGrid, colorchecker_names
from ...sensor.formats import parse_sensor_format
from .parse import INTENSITY, IRRADIANCE, RADIANCE, Section, parse_emission, parse_reflectance
from .textures import TEXTURE_KINDS, Texture, load_image_linear

__all__ = ["load_scene", "loads_scene", "resolve_scene_path", "builtin_scenes", "SCENE_UNITS"]

#: length units a scene file may use
SCENE_UNITS = ("m", "cm", "mm")
_LENS_SUFFIXES = (".toml", ".zmx", ".seq", ".dat", ".len")

_KEYS = {
    "": {"scene", "camera", "sensor", "spectral", "render", "illumination", "background", "light", "plane", "mesh"},
    "scene": {"name", "description", "units"},
    "camera": {"lens", "focus_distance", "focus_extension_mm", "f_number", "exposure_s", "lens_tilt_deg",
               "lens_swing_deg", "lens_shift_mm"},
    "sensor": {"format", "pixels", "preset", "noise", "iso"},
    "spectral": {"mode", "min_nm", "max_nm", "step_nm", "wavelength_nm", "sampling"},
    "render": {"samples_per_pixel", "seed", "time_budget_s", "target_rel_error", "diffraction"},
    "illumination": {"spectrum", "illuminance_lux", "irradiance_scale"},
    "background": {"spectrum", "luminance_cd_m2", "radiance_scale"},
    "light": {"name", "type", "position", "radius", "spectrum", "intensity_cd", "intensity_scale", "flux_lm",
              "luminance_cd_m2", "radiance_scale"},
    "plane": {"name", "center", "size", "normal", "up", "texture", "reflectance", "emission", "low", "high",
              "angle_deg", "square", "spokes", "cells", "line_width", "chart", "gap", "image", "image_encoding"},
    "mesh": {"name", "file", "scale", "rotation_deg", "position", "reflectance", "emission"},
}
_SPHERE_ONLY = ("radius", "luminance_cd_m2", "radiance_scale")
_POINT_ONLY = ("intensity_cd", "intensity_scale")
_EMISSION_KEYS = {"spectrum", "luminance_cd_m2", "radiance_scale"}
#: texture-specific plane keys, and the textures they apply to
_TEXTURE_KEYS = {"low": ("slanted_edge", "siemens_star", "grid"), "high": ("slanted_edge", "siemens_star", "grid"),
                 "angle_deg": ("slanted_edge",), "square": ("slanted_edge",), "spokes": ("siemens_star",),
                 "cells": ("grid",), "line_width": ("grid",), "chart": ("colorchecker",), "gap": ("colorchecker",),
                 "image": ("image",), "image_encoding": ("image",)}
#: default low/high levels: 4:1 for the slanted edge (ISO 12233 e-SFR low-contrast target)
_LEVELS = {"slanted_edge": (0.2, 0.8), "siemens_star": (0.05, 0.8), "grid": (0.05, 0.8)}


def builtin_scenes() -> list[Path]:
    """The scene files shipped in ``scenes/``, sorted by name."""
    return sorted(scenes_dir().glob("*.toml"))


def resolve_scene_path(name: str | Path | None) -> Path:
    """An existing scene file, or a built-in scene by name (``None`` = ``default``)."""
    p = Path("default" if name is None else name)
    if p.is_file():
        return p
    if p.parent == Path(".") and p.suffix in ("", ".toml"):
        cand = scenes_dir() / (p.stem + ".toml")
        if cand.is_file():
            return cand
    names = ", ".join(q.stem for q in builtin_scenes())
    raise LensrtError(f"no scene file or built-in scene named {str(name)!r}", hint=f"built-in scenes: {names}")


def load_scene(source: str | Path | None = None) -> Scene:
    """Load a scene file (or a built-in scene by name; ``None`` = the default scene)."""
    path = resolve_scene_path(source)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a UTF-8 BOM is accepted, as in lens files
    except OSError as err:
        raise LensrtError(f"cannot read scene file: {err.strerror}", path=path) from None
    except UnicodeDecodeError as err:
        raise LensrtError(f"not a text file (byte {err.start} is not UTF-8)", path=path,
                          hint="a scene is a TOML text file (see scenes/ for examples)") from None
    return loads_scene(text, path)


def _header_lines(text: str) -> tuple[dict[str, int], dict[str, list[int]]]:
    """1-based line of each ``[table]`` header and of each ``[[array]]`` entry."""
    tables: dict[str, int] = {}
    arrays: dict[str, list[int]] = {}
    for no, raw in enumerate(text.splitlines(), start=1):
        s = raw.split("#", 1)[0].strip()
        if s.startswith("[["):
            arrays.setdefault(s[2:].split("]]")[0].strip(), []).append(no)
        elif s.startswith("["):
            tables.setdefault(s[1:].split("]")[0].strip(), no)
    return tables, arrays


def loads_scene(text: str, path: str | Path | None = None) -> Scene:
    """Parse scene TOML ``text``; ``path`` (for messages and relative files) is optional."""
    path = Path(path) if path is not None else None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise LensrtError(f"not valid TOML: {err}", path=path) from None
    tables, arrays = _header_lines(text)

    def section(name: str) -> Section:
        sec = Section(doc.get(name, {}), name, path, tables.get(name))
        sec.check_keys(_KEYS[name])
        return sec

    def entries(name: str) -> list[Section]:
        rows = doc.get(name, [])
        if not isinstance(rows, list):
            raise LensrtError(f"{name} must be written as [[{name}]] tables", path=path, line=tables.get(name))
        lines = arrays.get(name, [])
        out = []
        for i, row in enumerate(rows):
            label = f"[[{name}]] #{i + 1}" + (f" ({row['name']!r})" if isinstance(row, dict) and "name" in row else "")
            sec = Section(row, name, path, lines[i] if i < len(lines) else None, label)
            sec.check_keys(_KEYS[name])
            out.append(sec)
        return out

    Section(doc, "", path, None, "the top level").check_keys(_KEYS[""])
    head = section("scene")
    units = head.string("units", "m", SCENE_UNITS)
    mm = MM_PER_UNIT[units]
    spectral = _spectral(section("spectral"))
    grid = spectral.grid
    camera = _camera(section("camera"), mm)
    sensor = _sensor(section("sensor"))
    render = _render(section("render"))
    points, spheres = [], []
    for sec in entries("light"):
        kind = sec.string("type", choices=("point", "sphere"))
        name = sec.string("name", f"light {len(points) + len(spheres) + 1}")
        pos = sec.vector("position", 3) * mm
        for key in (_SPHERE_ONLY if kind == "point" else _POINT_ONLY):
            if sec.has(key):
                raise sec.error(f"does not apply to a {kind} light", key)
        if kind == "point":
            points.append(PointLight(name, pos, parse_emission(sec, INTENSITY, grid, flux_solid_angle_sr=4 * math.pi)))
        else:
            r = sec.number("radius", positive=True) * mm
            area_m2 = 4.0 * math.pi * (r / MM_PER_M) ** 2
            spheres.append(SphereLight(name, pos, r, parse_emission(sec, RADIANCE, grid, flux_area_m2=area_m2)))
    planes = [_plane(sec, mm, grid, i) for i, sec in enumerate(entries("plane"))]
    meshes = [_mesh(sec, mm, grid, i) for i, sec in enumerate(entries("mesh"))]
    illum = section("illumination")
    illumination = parse_emission(illum, IRRADIANCE, grid) if illum.table else None
    bg = section("background")
    background = parse_emission(bg, RADIANCE, grid) if bg.table else None
    scene = Scene(name=head.string("name", path.stem if path else "scene"),
                  description=head.string("description", ""), path=path, units=units, camera=camera,
                  sensor=sensor, spectral=spectral, render=render, point_lights=tuple(points),
                  sphere_lights=tuple(spheres), planes=tuple(planes), meshes=tuple(meshes),
                  illumination=illumination, background=background)
    return _checked(scene, path)


def _spectral(sec: Section) -> SpectralSettings:
    mode = sec.string("mode", "auto", ("auto", "spectral", "monochromatic"))
    try:
        grid = WavelengthGrid(sec.number("min_nm", 380.0), sec.number("max_nm", 780.0),
                              sec.number("step_nm", 5.0, positive=True))
    except LensrtError as err:
        raise sec.error(err.message, None, err.hint) from None
    lam = sec.number("wavelength_nm", None, lo=grid.min_nm, hi=grid.max_nm)
    if mode == "monochromatic" and lam is None:
        raise sec.error("mode = \"monochromatic\" needs wavelength_nm", "wavelength_nm")
    if mode == "spectral" and lam is not None:
        raise sec.error("wavelength_nm applies to mode = \"monochromatic\" only", "wavelength_nm")
    sampling = sec.string("sampling", "auto", ("auto", "uniform", "cie", "scene", "camera"))
    return SpectralSettings(mode, grid, lam, sampling)


def _camera(sec: Section, mm: float) -> CameraSpec:
    lens = sec.string("lens", "dgauss_50mm_f2")
    lens_path = None
    p = Path(lens)
    if p.suffix.lower() in _LENS_SUFFIXES or len(p.parts) > 1:
        lens_path = p if p.is_absolute() else sec.base_dir / p
        if not lens_path.is_file():
            raise sec.error(f"lens file {str(lens_path)!r} does not exist", "lens",
                            "give a library lens name, or a path relative to the scene file")
    if sec.has("focus_distance") and sec.has("focus_extension_mm"):
        raise sec.error("give focus_distance or focus_extension_mm, not both")
    ext = sec.number("focus_extension_mm", None, nonneg=True)
    dist = None
    if ext is None:
        dist = sec.number("focus_distance", math.inf, positive=True, allow_inf=True) * mm
    fno = sec.number("f_number", None, lo=0.5, hi=1024.0)
    # tilt-shift: angles in degrees and the shift in mm whatever the scene's units (the key names say so)
    tilt = sec.number("lens_tilt_deg", 0.0, lo=-44.9, hi=44.9)
    swing = sec.number("lens_swing_deg", 0.0, lo=-44.9, hi=44.9)
    shift = sec.vector("lens_shift_mm", 2, np.zeros(2))
    return CameraSpec(lens, lens_path, dist, ext, fno, sec.number("exposure_s", 0.01, positive=True),
                      math.radians(tilt), math.radians(swing), (float(shift[0]), float(shift[1])))


def _sensor(sec: Section) -> SensorSpec:
    try:
        name, w, h = parse_sensor_format(sec.string("format", "full-frame"))
    except LensrtError as err:
        raise sec.error(err.message, "format", err.hint) from None
    px = sec.raw("pixels", [600, 400])
    if isinstance(px, int) and not isinstance(px, bool):
        px = [px, max(1, round(px * h / w))]
    if (not isinstance(px, list) or len(px) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 65536 for v in px)):
        raise sec.error(f"must be [width, height] in pixels (1-65536) or a width, not {px!r}", "pixels")
    pitch_x, pitch_y = 1000.0 * w / px[0], 1000.0 * h / px[1]
    if abs(pitch_x / pitch_y - 1.0) > 0.01:
        raise sec.error(f"{px[0]} x {px[1]} pixels on {w:g} x {h:g} mm give non-square photosites "
                        f"({pitch_x:.3g} x {pitch_y:.3g} um)", "pixels",
                        f"use about {px[0]} x {round(px[0] * h / w)}, or give the width only")
    preset = sec.string("preset", None)
    noise = sec.boolean("noise", preset is not None)
    if noise and preset is None:
        raise sec.error("sensor noise needs a sensor preset", "noise", "add preset = \"<name>\" or noise = false")
    return SensorSpec(name, w, h, px[0], px[1], preset, noise, sec.number("iso", None, positive=True))


def _render(sec: Section) -> RenderSettings:
    d = sec.raw("diffraction", "auto")
    if isinstance(d, bool):
        d = "on" if d else "off"
    if d not in ("auto", "on", "off"):
        raise sec.error(f"must be true, false or \"auto\", not {d!r}", "diffraction")
    return RenderSettings(sec.integer("samples_per_pixel", 16, lo=1, hi=1 << 24), sec.integer("seed", 0, lo=0),
                          sec.number("time_budget_s", None, positive=True),
                          sec.number("target_rel_error", None, positive=True), d)


def _plane(sec: Section, mm: float, grid: WavelengthGrid, i: int) -> Plane:
    name = sec.string("name", f"plane {i + 1}")
    center = sec.vector("center", 3) * mm
    w, h = (float(x) * mm for x in sec.vector("size", 2, positive=True))
    n = sec.vector("normal", 3, np.array([0.0, 0.0, 1.0]))
    up = sec.vector("up", 3, np.array([0.0, 1.0, 0.0]))
    if np.linalg.norm(n) == 0:
        raise sec.error("must not be the zero vector", "normal")
    n = n / np.linalg.norm(n)
    right = np.cross(up, n)
    if np.linalg.norm(right) < 1e-9:
        raise sec.error("is parallel to the normal", "up", "give an up direction that lies in the plane")
    right /= np.linalg.norm(right)
    up = np.cross(n, right)
    kind = sec.string("texture", "uniform", tuple(TEXTURE_KINDS))
    for key, kinds in _TEXTURE_KEYS.items():
        if sec.has(key) and kind not in kinds:
            raise sec.error(f"does not apply to texture = {kind!r}", key)
    tex = _texture(sec, kind, w, h)
    if sec.has("emission"):
        if sec.has("reflectance"):
            raise sec.error("a plane is emissive or reflective, not both", "reflectance")
        em = sec.sub("emission")
        em.check_keys(_EMISSION_KEYS)
        emission = parse_emission(em, RADIANCE, grid)
        return Plane(name, center, (w, h), n, right, up, tex, None, emission)
    if kind == "uniform" and not sec.has("reflectance"):
        raise sec.error("a uniform reflective plane needs reflectance (or emission)", "reflectance")
    tint = parse_reflectance(sec, "reflectance", grid) if sec.has("reflectance") else None
    if kind in ("colorchecker", "image") and tint is not None:
        raise sec.error(f"texture = {kind!r} brings its own reflectance", "reflectance")
    return Plane(name, center, (w, h), n, right, up, tex, tint, None)


def _texture(sec: Section, kind: str, w: float, h: float) -> Texture:
    lo, hi = _LEVELS.get(kind, (0.0, 1.0))
    low, high = sec.number("low", lo, lo=0.0, hi=1.0), sec.number("high", hi, lo=0.0, hi=1.0)
    short = min(w, h)
    if kind == "slanted_edge":
        ang = math.radians(sec.number("angle_deg", 5.0, lo=-45.0, hi=45.0))
        square = sec.number("square", 0.5, lo=0.01, hi=1.0)
        return Texture(kind, (ang, 0.5 * square * short, 0.0, 0.0), low, high)
    if kind == "siemens_star":
        return Texture(kind, (float(sec.integer("spokes", 36, lo=2, hi=10000)), 0.5 * short, 0.0, 0.0), low, high)
    if kind == "grid":
        cells = sec.raw("cells", [12, 8])
        if not (isinstance(cells, list) and len(cells) == 2 and all(isinstance(c, int) and c >= 1 for c in cells)):
            raise sec.error(f"must be [nx, ny] whole numbers of cells, not {cells!r}", "cells")
        cw, ch = w / cells[0], h / cells[1]
        lw = sec.number("line_width", 0.06, lo=0.0, hi=1.0)
        return Texture(kind, (cw, ch, 0.5 * lw * min(cw, ch), 0.0), low, high)
    if kind == "colorchecker":
        chart = sec.string("chart", "ColorChecker N Ohta")
        try:
            n_patches = len(colorchecker_names(chart))
        except LensrtError as err:
            raise sec.error(err.message, "chart", err.hint) from None
        if n_patches != 24:
            raise sec.error(f"{chart!r} does not have 24 patches", "chart")
        px, py = w / 6.0, h / 4.0
        gap = sec.number("gap", 0.15, lo=0.0, hi=0.9)
        return Texture(kind, (px, py, 0.5 * gap * min(px, py), 0.0), 0.0, 1.0, chart=chart)
    if kind == "image":
        p = sec.file("image")
        enc = sec.string("image_encoding", "srgb", ("srgb", "linear"))
        try:
            img = load_image_linear(p, enc)
        except LensrtError as err:
            raise sec.error(err.message, "image", err.hint) from None
        return Texture(kind, image_linear=img, source=str(p))
    return Texture("uniform", low=0.0, high=1.0)


def _mesh(sec: Section, mm: float, grid: WavelengthGrid, i: int) -> MeshObject:
    import trimesh
    name = sec.string("name", f"mesh {i + 1}")
    p = sec.file("file")
    try:
        tm = trimesh.load(str(p), force="mesh")
    except Exception as err:  # noqa: BLE001 - trimesh raises many types for a bad file
        raise sec.error(f"trimesh cannot read {str(p)!r}: {err}", "file",
                        "use OBJ, PLY, GLB/GLTF or STL") from None
    verts = np.asarray(getattr(tm, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(tm, "faces", np.zeros((0, 3))), dtype=np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise sec.error(f"{str(p)!r} has no triangles", "file")
    if not np.all(np.isfinite(verts)):
        raise sec.error(f"{str(p)!r} has non-finite vertex coordinates", "file")
    scale = sec.number("scale", 1.0, positive=True)
    rot = np.radians(sec.vector("rotation_deg", 3, np.zeros(3)))
    pos = sec.vector("position", 3, np.zeros(3))
    r = trimesh.transformations.euler_matrix(rot[0], rot[1], rot[2], axes="sxyz")[:3, :3]
    v_mm = ((verts * scale) @ r.T + pos) * mm
    if sec.has("emission"):
        if sec.has("reflectance"):
            raise sec.error("a mesh is emissive or reflective, not both", "reflectance")
        em = sec.sub("emission")
        em.check_keys(_EMISSION_KEYS)
        return MeshObject(name, str(p), v_mm, faces.astype(np.int32), None, parse_emission(em, RADIANCE, grid))
    return MeshObject(name, str(p), v_mm, faces.astype(np.int32), parse_reflectance(sec, "reflectance", grid), None)


def _checked(scene: Scene, path: Path | None) -> Scene:
    """Whole-scene checks: object space at z < 0, some light, line spectra, monochromatic settings."""
    def front(what: str, z_max_mm: float) -> None:
        if not z_max_mm < 0.0:
            raise LensrtError(f"{what} reaches z = {z_max_mm / 1000.0:.4g} m; the scene must lie at z < 0, in front "
                              "of the first lens vertex (the camera looks along -z at it, light travels toward +z)",
                              path=path)
    for p in scene.point_lights:
        front(f"point light {p.name!r}", p.position_mm[2])
    for s in scene.sphere_lights:
        front(f"sphere light {s.name!r}", s.center_mm[2] + s.radius_mm)
    for pl in scene.planes:
        front(f"plane {pl.name!r}", pl.corners_mm()[:, 2].max())
    for m in scene.meshes:
        front(f"mesh {m.name!r}", m.vertices_mm[:, 2].max())
    if not scene.emission_spectra():
        raise LensrtError("the scene has no light", path=path,
                          hint="add [illumination], a [[light]], an emissive plane or mesh, or a [background]")
    lines = {s.line_nm for s in scene.emission_spectra()}
    if any(x is not None for x in lines) and len(lines) > 1:
        raise LensrtError("line spectra (line_nm) cannot be mixed with other lines or continuous spectra", path=path,
                          hint="use {gaussian_nm = ..., fwhm_nm = ...} for narrow-band sources in a spectral scene")
    line = scene.line_nm
    sp = scene.spectral
    if line is not None and (sp.mode == "spectral" or (sp.wavelength_nm is not None and sp.wavelength_nm != line)):
        raise LensrtError(f"all the scene's light is a line at {line:g} nm; it renders monochromatic at that "
                          "wavelength", path=path, hint="remove mode/wavelength_nm from [spectral]")
    if sp.sampling == "camera" and scene.sensor.preset is None:
        raise LensrtError("[spectral] sampling = \"camera\" needs a [sensor] preset (its spectral response)", path=path)
    warnings = []
    for pl in scene.planes:
        facing = float(np.dot(pl.normal, -pl.center_mm))
        if pl.emissive and facing <= 0.0:
            warnings.append(f"emissive plane {pl.name!r} faces away from the camera and will look black")
    return dataclasses.replace(scene, warnings=tuple(warnings)) if warnings else scene
