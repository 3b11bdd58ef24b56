"""The geometry keywords of a Zemax ``.zmx`` file: coordinate breaks, mirrors, surface apertures.

Used by :mod:`.zemax`; kept apart so that the surface-type and glass work on
that reader and this one do not collide.

* ``TYPE COORDBRK`` with ``PARM 1..6`` = decenter x, decenter y (lens units),
  tilt about x, y, z (degrees), order (0: decenter then tilts x, y, z; else
  tilts z, y, x then decenter): a plane dummy surface whose
  ``transform_before`` is that change of frame; its thickness runs along the
  new z. Light is not refracted there (the medium does not change).
* ``GLAS MIRROR``: a mirror; the medium after it is the one before it.
* Surface apertures: ``CLAP rmin rmax`` (circular, annular when rmin > 0; ``CLAP rmin INF``, as
  optiland exports a central hole, passes everything outside rmin: an obscuration),
  ``OBSC rmin rmax`` (circular obscuration, annular when rmin > 0),
  ``SQAP xhalf yhalf`` (rectangular), ``ELAP xhalf yhalf`` (elliptical),
  each moved by ``OBDC x y`` (the aperture decenter). A centred circular
  ``CLAP 0 r`` stays the surface's semi-diameter, as before.
* ``SCBD 1 order 0 dx dy tx ty tz``: OpticStudio's surface-properties tilt/decenter
  "before surface": decenter x, y (lens units) and tilts about x, y, z (degrees)
  in the order of a COORDBRK's ``PARM 6`` (0: decenter then tilts x, y, z; 1:
  tilts z, y, x then decenter). On a lens surface it becomes the surface's
  ``transform_before`` and the frame stays moved for the surfaces after it (the
  "after surface" default: explicit zeros); on the image surface it becomes
  ``Lens.image_transform``. The .zmx layout is not published: the values'
  meaning is fixed by rayoptics' ``zmax_37992.zmx`` (a 90 deg off-axis parabola
  whose image plane is tilted 90 deg about x, so that the chief ray meets it
  normally), the flags' by D. Griffith's ACCOS-to-OpticStudio converter
  (MZDDE, ``ACCOSin.m``, BSD licence: it writes ``SCBD 1 <order> 0 ...``
  with the order it also gives a COORDBRK's PARM 6, and "after" lines as
  ``SCBD 2 ...``). An ``SCBD 2`` (after surface) line on a lens surface, and any
  other flags, are an error naming the construct.
* ``DIAM v flag``: flag 1 is a user-defined semi-diameter (OpticStudio's
  floating aperture), the kind that vignettes under the ``opticstudio``
  aperture rule.
"""
from __future__ import annotations

import math

from ...errors import PrescriptionError
from ...units import deg_to_rad
from ..geometry import CoordinateTransform, SurfaceAperture

__all__ = ["APERTURE_KEYWORDS", "coordbrk_transform", "surface_apertures", "aperture_entry", "scbd_transform"]

#: the surface-aperture keywords read here, and the shape each gives
APERTURE_KEYWORDS = {"CLAP": "circle", "OBSC": "circle", "SQAP": "rectangle", "ELAP": "ellipse"}


def coordbrk_transform(parm: dict[int, tuple[float, int]], unit_mm: float, path: str | None,
                       line: int) -> CoordinateTransform:
    """The frame change of a COORDBRK surface from its PARM 1..6 (lens units and degrees)."""
    bad = [i for i in parm if i > 6 and parm[i][0] != 0.0]
    if bad:
        raise PrescriptionError(f"COORDBRK PARM {bad[0]}: a coordinate break has parameters 1..6 only",
                                path=path, line=parm[bad[0]][1])
    v = {i: parm.get(i, (0.0, line))[0] for i in range(1, 7)}
    return CoordinateTransform(decenter_x_mm=v[1] * unit_mm, decenter_y_mm=v[2] * unit_mm,
                               tilt_x_rad=deg_to_rad(v[3]), tilt_y_rad=deg_to_rad(v[4]),
                               tilt_z_rad=deg_to_rad(v[5]), order=0 if v[6] == 0.0 else 1)


def aperture_entry(keyword: str, values: list[float], line: int, path: str | None) -> tuple[str, float, float, int]:
    """One aperture keyword's (keyword, first, second, line), checked."""
    if len(values) < 2:
        raise PrescriptionError(f"{keyword} needs two sizes", path=path, line=line,
                                hint=f"{keyword} <min radius or x half-width> <max radius or y half-width>")
    if any(math.isinf(v) for v in values[:1]) or any(v < 0.0 for v in values[:2]) or \
            (keyword not in ("CLAP", "OBSC") and math.isinf(values[1])):
        raise PrescriptionError(f"{keyword} {values[0]:g} {values[1]:g}: sizes must be finite and not negative",
                                path=path, line=line, hint="only the outer radius of CLAP/OBSC may be INF")
    if any(v != 0.0 for v in values[2:]):
        raise PrescriptionError(f"{keyword}: the aperture options {values[2:]} are not supported", path=path,
                                line=line, hint="lensrt reads the two sizes of the aperture")
    return keyword, values[0], values[1], line


def surface_apertures(entries: list[tuple[str, float, float, int]], decenter: tuple[float, float],
                      unit_mm: float, path: str | None) -> tuple[SurfaceAperture, ...]:
    """The surface's apertures from its aperture keywords, moved by OBDC (lens units)."""
    out = []
    dx, dy = decenter[0] * unit_mm, decenter[1] * unit_mm
    for kw, first, second, line in entries:
        try:
            if kw in ("CLAP", "OBSC"):
                rmin, rmax = first * unit_mm, second * unit_mm
                if math.isinf(rmax):  # no outer edge: a CLAP passes all but its inner disc, an OBSC blocks all
                    if kw == "OBSC":
                        raise PrescriptionError("OBSC with an infinite outer radius blocks every ray")
                    if rmin > 0.0:
                        out.append(SurfaceAperture("circle", rmin, 0.0, dx, dy, obscuration=True))
                    continue
                shape = "circle" if rmin == 0.0 else "annulus"
                out.append(SurfaceAperture(shape, rmax, rmin if rmin else 0.0, dx, dy,
                                           obscuration=kw == "OBSC"))
            else:
                out.append(SurfaceAperture(APERTURE_KEYWORDS[kw], first * unit_mm, second * unit_mm, dx, dy))
        except PrescriptionError as e:
            raise PrescriptionError(f"{kw}: {e.message}", path=path, line=line, hint=e.hint) from None
    return tuple(out)


def scbd_transform(values: list[float], line: int, unit_mm: float, path: str | None) -> CoordinateTransform:
    """The frame change before a surface from an ``SCBD 1 order 0 dx dy tx ty tz`` line (module docstring)."""
    flags, v = values[:3] + [0.0] * (3 - len(values[:3])), values[3:8] + [0.0] * (8 - len(values[:8]))
    if flags[0] != 1.0 or flags[1] not in (0.0, 1.0) or flags[2] != 0.0 or any(x != 0.0 for x in values[8:]):
        raise PrescriptionError("SCBD: a surface tilt/decenter whose flags or extra values lensrt cannot read "
                                f"({' '.join(f'{x:g}' for x in values[:3])}; read: '1 order 0' then decenter x, y "
                                "and tilts x, y, z)", path=path, line=line,
                                hint="write the frame change as a COORDBRK before the surface")
    return CoordinateTransform(decenter_x_mm=v[0] * unit_mm, decenter_y_mm=v[1] * unit_mm,
                               tilt_x_rad=deg_to_rad(v[2]), tilt_y_rad=deg_to_rad(v[3]), tilt_z_rad=deg_to_rad(v[4]),
                               order=int(flags[1]))
