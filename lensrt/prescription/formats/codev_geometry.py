"""The geometry commands of a CODE V sequence: mirrors, decenters and tilts, apertures.

Used by :mod:`.codev`; kept apart so that the syntax and glass work on that
reader and this one do not collide.

* ``REFL`` in the glass position of an ``S`` line: a mirror (the medium after
  it is the one before it).
* ``XDE``/``YDE``/``ZDE`` (lens units) and ``ADE``/``BDE``/``CDE`` (degrees):
  the surface's decenter, applied decenter first, then alpha, beta, gamma
  (:class:`~lensrt.prescription.geometry.CoordinateTransform`, order 0), of
  the type the surface names: basic (the default: the new frame holds for this
  and every later surface), ``DAR`` (decenter and return: for this surface
  only), ``REV`` (reverse: the surface stays in the frame before, and the
  inverse of the decenter applies after it), ``BEN`` (bend, for fold mirrors:
  the tilt applies again after the surface, so the axis follows the reflected
  beam). On ``SI`` the decenter places the image surface.
* Apertures: ``CIR r`` (the semi-diameter, as before); ``CIR OBS r``
  (a circular obscuration) and ``CIR HOL r`` (a hole: rays there do not meet
  the surface, so a sequential trace stops them -- lensrt treats it as an
  obscuration of this surface); ``REX``/``REY`` (rectangle half-widths),
  ``ELX``/``ELY`` (ellipse semi-axes), with ``OBS``/``HOL`` likewise;
  ``ADX``/``ADY`` (aperture decenter) and ``ARO`` (rotation, degrees) move them.
  Labels (``L'text'``) are ignored; ``EDG`` apertures are mechanical and ignored.
* ``RET Sk`` (coordinate return): the surface that carries it, and every later
  one, lies in the coordinate system of surface k (an earlier ``S`` surface):
  the frame in which surface k lies, its own decenter included. Its thickness
  then runs along surface k's z axis. lensrt writes it as the surface's
  ``transform_before`` (:func:`~lensrt.prescription.frames.transform_between`
  of the running frame and surface k's, :func:`apply_coordinate_returns`), so
  ``lens convert`` keeps it as an explicit frame change. Source: OpticStudio's
  CODE V conversion macro maps ``RET Sk`` to a coordinate break with a
  coordinate-return solve ("Orientation, XYZ") to surface k
  (``docs/guide/decentred.md``). ``RET`` with a decenter on the same surface,
  ``RET`` in a zoom file and ``RET`` on ``SI`` are refused (their meaning is
  not documented in any source found).
"""
from __future__ import annotations

import dataclasses
import re
from typing import Any

from ...errors import PrescriptionError
from ...units import deg_to_rad
from ..frames import frames_of_surfaces, transform_between
from ..geometry import CoordinateTransform, SurfaceAperture
from ..model import Surface

__all__ = ["GEOMETRY_COMMANDS", "geometry_command", "row_geometry", "new_row_geometry",
           "apply_coordinate_returns"]

_DECENTER = {"XDE": "x", "YDE": "y", "ZDE": "z", "ADE": "a", "BDE": "b", "CDE": "c"}
_TYPES = {"DAR": "dar", "REV": "rev", "BEN": "ben"}
_SHAPED = {"REX": ("rectangle", "a"), "REY": ("rectangle", "b"), "ELX": ("ellipse", "a"),
           "ELY": ("ellipse", "b")}
#: the commands read here
GEOMETRY_COMMANDS = set(_DECENTER) | set(_TYPES) | set(_SHAPED) | {"ADX", "ADY", "ARO", "RET"}


def new_row_geometry() -> dict[str, Any]:
    """The geometry entries every surface row starts with."""
    return dict(mirror=False, dec={}, dtype="basic", dec_line=None, cir_obs=[], shaped={}, shaped_obs=False,
                ap_dx=0.0, ap_dy=0.0, ap_rot=0.0, ret=None)


def _value(seq: Any, args: list[str], what: str, line: int) -> float:
    vals = [a for a in args if not a.upper().startswith("L'")]
    if not vals:
        raise seq.err(f"{what} without a value", line)
    return seq.num(vals[-1], what, line)


def geometry_command(seq: Any, name: str, args: list[str], line: int) -> bool:
    """Apply one geometry command to the current row of ``seq`` (a CODE V reader); False if not one."""
    if name not in GEOMETRY_COMMANDS:
        return False
    if name == "RET":
        coordinate_return(seq, args, line)
        return True
    row = seq.rows[-1] if seq.rows and seq.rows[-1]["kind"] == "SI" and name in _DECENTER else \
        seq.cur(name, line)
    if name in _DECENTER:
        row["dec"][_DECENTER[name]] = _value(seq, args, name, line)
        row["dec_line"] = row["dec_line"] or line
    elif name in _TYPES:
        if row["kind"] == "SI":
            raise seq.err(f"{name} on the image surface", line, "the image surface takes a basic decenter only")
        row["dtype"] = _TYPES[name]
    elif name in _SHAPED:
        shape, key = _SHAPED[name]
        if row["shaped"].get("shape", shape) != shape:
            raise seq.err(f"{name} mixes a rectangular and an elliptical aperture on one surface", line)
        row["shaped"]["shape"] = shape
        row["shaped"][key] = _value(seq, args, name, line)
        row["shaped"]["line"] = line
        row["shaped_obs"] = row["shaped_obs"] or any(a.upper() in ("OBS", "HOL") for a in args)
    else:
        row[{"ADX": "ap_dx", "ADY": "ap_dy", "ARO": "ap_rot"}[name]] = _value(seq, args, name, line)
    return True


def coordinate_return(seq: Any, args: list[str], line: int) -> None:
    """Record ``RET Sk`` on the current surface row of ``seq`` (checked and applied at assembly)."""
    if seq.rows and seq.rows[-1]["kind"] == "SI":
        raise seq.err("RET on the image surface", line, "decenter SI with XDE ... CDE instead")
    row = seq.cur("RET", line)
    if row["kind"] != "S":
        raise seq.err("RET on the object surface (SO)", line, "RET goes on an S surface after the one it returns to")
    number = sum(1 for r in seq.rows if r["kind"] == "S")
    if len(args) != 1 or not re.fullmatch(r"S\d+", args[0], re.IGNORECASE):
        raise seq.err(f"cannot read RET {' '.join(args)}".rstrip(), line,
                      "write 'RET Sk' with k the number of an earlier surface (e.g. RET S2)")
    k = int(args[0][1:])
    if not 1 <= k < number:
        raise seq.err(f"RET {args[0]} on surface {number}: surface {k} is not an earlier S surface", line,
                      f"RET returns to the coordinate system of one of surfaces 1 .. {number - 1}" if number > 1
                      else "surface 1 has no earlier surface to return to")
    row["ret"] = (k, line)


def apply_coordinate_returns(surfaces: list[Surface], rows: list[dict[str, Any]], path: str | None,
                             zoom: bool = False) -> list[Surface]:
    """The surfaces with each ``RET Sk`` turned into the ``transform_before`` that puts the surface in
    surface k's frame (``rows`` are the ``S`` rows, one per surface, in order)."""
    if not any(r["ret"] for r in rows):
        return surfaces
    out = list(surfaces)
    for j, r in enumerate(rows):
        if r["ret"] is None:
            continue
        k, line = r["ret"]
        if zoom:
            raise PrescriptionError("RET in a zoom file", path=path, line=line,
                                    hint="the return would change with the zoom positions; not supported")
        if r["dec"] or r["dtype"] != "basic":
            raise PrescriptionError(f"RET S{k} and a decenter on one surface", path=path, line=line,
                                    hint="put the decenter on the next surface (a plane dummy) after the return")
        frames = frames_of_surfaces([*out[:j], dataclasses.replace(out[j], transform_before=None)])
        (o, a), (ok, ak) = frames[j], frames[k - 1]
        out[j] = dataclasses.replace(out[j], transform_before=transform_between(o, a, ok, ak))
    return out


def _transform(row: dict[str, Any], f: float) -> CoordinateTransform | None:
    d = row["dec"]
    if not d:
        return None
    return CoordinateTransform(d.get("x", 0.0) * f, d.get("y", 0.0) * f, d.get("z", 0.0) * f,
                               deg_to_rad(d.get("a", 0.0)), deg_to_rad(d.get("b", 0.0)),
                               deg_to_rad(d.get("c", 0.0)), 0)


def _apertures(row: dict[str, Any], f: float, path: str | None) -> tuple[SurfaceAperture, ...]:
    dx, dy, rot = row["ap_dx"] * f, row["ap_dy"] * f, deg_to_rad(row["ap_rot"])
    out = [SurfaceAperture("circle", r * f, 0.0, dx, dy, rot, obscuration=True) for r in row["cir_obs"]]
    sh = row["shaped"]
    if sh:
        if "a" not in sh or "b" not in sh:
            missing = {"rectangle": ("REX", "REY"), "ellipse": ("ELX", "ELY")}[sh["shape"]][0 if "a" not in sh else 1]
            raise PrescriptionError(f"{sh['shape']} aperture without {missing}", path=path, line=sh["line"],
                                    hint="give both half-widths (X and Y)")
        out.append(SurfaceAperture(sh["shape"], abs(sh["a"]) * f, abs(sh["b"]) * f, dx, dy, rot,
                                   obscuration=row["shaped_obs"]))
    elif (dx or dy) and row.get("sd") is not None:
        # a decentred CIR: the circle moves off the axis, so it is a surface aperture
        out.append(SurfaceAperture("circle", row["sd"] * f, 0.0, dx, dy, rot))
        row["sd"] = None
    return tuple(out)


def row_geometry(row: dict[str, Any], f: float, path: str | None) -> dict[str, Any]:
    """The :class:`~lensrt.prescription.model.Surface` geometry fields of one ``S`` row."""
    t = _transform(row, f)
    before, after = t, None
    if t is not None and row["dtype"] == "dar":
        after = t.inverse()
    elif t is not None and row["dtype"] == "rev":
        before, after = None, t.inverse()
    elif t is not None and row["dtype"] == "ben":
        after = CoordinateTransform(tilt_x_rad=t.tilt_x_rad, tilt_y_rad=t.tilt_y_rad, tilt_z_rad=t.tilt_z_rad)
    return dict(mirror=row["mirror"], transform_before=before, transform_after=after,
                apertures=_apertures(row, f, path))


def image_transform(row: dict[str, Any] | None, f: float) -> CoordinateTransform | None:
    """The image surface's decenter (``SI`` with XDE ... CDE), or None."""
    return None if row is None else _transform(row, f)
