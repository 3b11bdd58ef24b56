"""The geometry keys of the native TOML format: mirrors, coordinate transforms, surface apertures, ideal lenses.

Per surface (all optional)::

    mirror = true
    ideal_focal_mm = 50.0             # an ideal paraxial lens of this focal length (a plane: no radius)
    ideal_opd_mode = 0                # OpticStudio's OPD mode of TYPE PARAXIAL (kept for the record)
    semi_diameter_fixed = true        # a user-defined semi-diameter (vignettes under the opticstudio rule)
    transform_before = { decenter_x_mm = 1.0, decenter_y_mm = 0.0, decenter_z_mm = 0.0,
                         tilt_x_deg = 3.0, tilt_y_deg = 0.0, tilt_z_deg = 0.0, order = 0 }
    transform_after = { ... }         # the same keys
    apertures = [ { shape = "circle", a_mm = 4.0, obscuration = true },
                  { shape = "rectangle", a_mm = 20.0, b_mm = 10.0, decenter_y_mm = 5.0, rotation_deg = 0.0 } ]

and in ``[system]``: ``aperture_rule = "opticstudio"`` (default
``"every_surface"``) and ``image_transform = { ... }``. Angles are written so
that they read back to the same radians bit for bit (:func:`degree_text`).
"""
from __future__ import annotations

import math
from typing import Any

from ...errors import PrescriptionError
from ..geometry import CoordinateTransform, SurfaceAperture
from ..model import Lens, Surface

__all__ = ["SURFACE_KEYS", "SYSTEM_KEYS", "read_surface_geometry", "write_surface_geometry",
           "read_system_geometry", "write_system_geometry", "degree_text"]

SURFACE_KEYS = {"mirror", "semi_diameter_fixed", "transform_before", "transform_after", "apertures",
                "ideal_focal_mm", "ideal_opd_mode"}
SYSTEM_KEYS = {"aperture_rule", "image_transform"}
_TRANSFORM_KEYS = {"decenter_x_mm", "decenter_y_mm", "decenter_z_mm", "tilt_x_deg", "tilt_y_deg", "tilt_z_deg",
                   "order"}
_APERTURE_KEYS = {"shape", "a_mm", "b_mm", "decenter_x_mm", "decenter_y_mm", "rotation_deg", "obscuration"}
_RAD_PER_DEG = math.pi / 180.0


def _f(x: float) -> str:
    return repr(float(x))


def degree_text(angle_rad: float) -> str:
    """Degrees text that reads back (``x * pi / 180``) to exactly ``angle_rad`` (nearest ulps tried)."""
    d = math.degrees(angle_rad)
    up = down = d
    for _ in range(8):
        for cand in (up, down):
            if cand * _RAD_PER_DEG == angle_rad:
                return _f(cand)
        up, down = math.nextafter(up, math.inf), math.nextafter(down, -math.inf)
    return _f(d)


def _number(table: dict, key: str, what: str) -> float:
    v = table.get(key, 0.0)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PrescriptionError(f"{what}.{key} must be a number, not {v!r}")
    return float(v)


def _flag(row: dict, key: str) -> bool:
    v = row.get(key, False)
    if not isinstance(v, bool):
        raise PrescriptionError(f"{key} must be true or false, not {v!r}")
    return v


def _table(value: Any, what: str, keys: set[str]) -> dict:
    if not isinstance(value, dict):
        raise PrescriptionError(f"{what} must be a table like {{ {', '.join(sorted(keys))} }}")
    bad = [k for k in value if k not in keys]
    if bad:
        raise PrescriptionError(f"unknown key {bad[0]!r} in {what}", hint=f"allowed keys: {', '.join(sorted(keys))}")
    return value


def _transform(value: Any, what: str) -> CoordinateTransform:
    t = _table(value, what, _TRANSFORM_KEYS)
    order = t.get("order", 0)
    if isinstance(order, bool) or order not in (0, 1):
        raise PrescriptionError(f"{what}.order must be 0 or 1, not {order!r}")
    return CoordinateTransform(*(_number(t, k, what) for k in ("decenter_x_mm", "decenter_y_mm", "decenter_z_mm")),
                               *(_number(t, k, what) * _RAD_PER_DEG for k in ("tilt_x_deg", "tilt_y_deg",
                                                                              "tilt_z_deg")), order)


def _aperture(value: Any) -> SurfaceAperture:
    a = _table(value, "an aperture", _APERTURE_KEYS)
    ob = a.get("obscuration", False)
    if not isinstance(ob, bool):
        raise PrescriptionError(f"aperture obscuration must be true or false, not {ob!r}")
    return SurfaceAperture(str(a.get("shape", "circle")), _number(a, "a_mm", "aperture"), _number(a, "b_mm", "aperture"),
                           _number(a, "decenter_x_mm", "aperture"), _number(a, "decenter_y_mm", "aperture"),
                           _number(a, "rotation_deg", "aperture") * _RAD_PER_DEG, ob)


def read_surface_geometry(row: dict) -> dict[str, Any]:
    """The :class:`Surface` geometry fields of one ``[[surface]]`` table."""
    aps = row.get("apertures", [])
    if not isinstance(aps, list):
        raise PrescriptionError("apertures must be a list of tables")
    ideal: dict[str, Any] = {}
    if "ideal_focal_mm" in row:
        ideal["ideal_focal_mm"] = _number(row, "ideal_focal_mm", "surface")
    mode = row.get("ideal_opd_mode", 0)
    if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode <= 3:
        raise PrescriptionError(f"ideal_opd_mode must be 0, 1, 2 or 3, not {mode!r}")
    if mode and "ideal_focal_mm" not in row:
        raise PrescriptionError("ideal_opd_mode without ideal_focal_mm", hint="an OPD mode belongs to an ideal lens")
    return dict(**ideal, ideal_opd_mode=mode, mirror=_flag(row, "mirror"),
                semi_diameter_fixed=_flag(row, "semi_diameter_fixed"),
                transform_before=_transform(row["transform_before"], "transform_before")
                if "transform_before" in row else None,
                transform_after=_transform(row["transform_after"], "transform_after")
                if "transform_after" in row else None,
                apertures=tuple(_aperture(a) for a in aps))


def read_system_geometry(sys_t: dict) -> dict[str, Any]:
    """``aperture_rule`` and ``image_transform`` of the ``[system]`` table."""
    return dict(aperture_rule=str(sys_t.get("aperture_rule", "every_surface")),
                image_transform=_transform(sys_t["image_transform"], "image_transform")
                if "image_transform" in sys_t else None)


def _transform_text(t: CoordinateTransform) -> str:
    parts = [f"decenter_x_mm = {_f(t.decenter_x_mm)}", f"decenter_y_mm = {_f(t.decenter_y_mm)}",
             f"decenter_z_mm = {_f(t.decenter_z_mm)}", f"tilt_x_deg = {degree_text(t.tilt_x_rad)}",
             f"tilt_y_deg = {degree_text(t.tilt_y_rad)}", f"tilt_z_deg = {degree_text(t.tilt_z_rad)}",
             f"order = {t.order}"]
    return "{ " + ", ".join(parts) + " }"


def _aperture_text(a: SurfaceAperture) -> str:
    parts = [f'shape = "{a.shape}"', f"a_mm = {_f(a.a)}", f"b_mm = {_f(a.b)}",
             f"decenter_x_mm = {_f(a.decenter_x_mm)}", f"decenter_y_mm = {_f(a.decenter_y_mm)}",
             f"rotation_deg = {degree_text(a.rotation_rad)}", f"obscuration = {'true' if a.obscuration else 'false'}"]
    return "{ " + ", ".join(parts) + " }"


def write_surface_geometry(s: Surface) -> list[str]:
    """The geometry lines of one ``[[surface]]`` table (none for a plain refracting surface)."""
    out = []
    if s.mirror:
        out.append("mirror = true")
    if s.ideal_focal_mm is not None:
        out.append(f"ideal_focal_mm = {_f(s.ideal_focal_mm)}")
        if s.ideal_opd_mode:
            out.append(f"ideal_opd_mode = {s.ideal_opd_mode}")
    if s.semi_diameter_fixed:
        out.append("semi_diameter_fixed = true")
    if s.transform_before is not None:
        out.append(f"transform_before = {_transform_text(s.transform_before)}")
    if s.transform_after is not None:
        out.append(f"transform_after = {_transform_text(s.transform_after)}")
    if s.apertures:
        out.append("apertures = [" + ", ".join(_aperture_text(a) for a in s.apertures) + "]")
    return out


def write_system_geometry(lens: Lens) -> list[str]:
    """The geometry lines of ``[system]`` (none for the defaults)."""
    out = []
    if lens.aperture_rule != "every_surface":
        out.append(f'aperture_rule = "{lens.aperture_rule}"')
    if lens.image_transform is not None:
        out.append(f"image_transform = {_transform_text(lens.image_transform)}")
    return out
