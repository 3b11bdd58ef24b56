"""CODE V paraxial solves, applied at load time: ``CUY UMY``/``UCY``, ``THI HMY``/``HCY``, ``PIM``.

A solve makes a curvature or a thickness follow from a paraxial ray
instead of being typed in (CODE V reference manual, "Solves"):

* ``CUY UMY u`` / ``CUY UCY u``: the curvature of this surface such that the
  paraxial marginal (chief) ray leaves it with slope ``u`` (dy/dz in the
  medium after the surface);
* ``THI HMY h`` / ``THI HCY h``: the thickness after this surface such that
  the paraxial marginal (chief) ray meets the next surface at height ``h``
  (lens units);
* ``PIM``: the paraxial image solve, ``THI HMY 0`` on its surface -- the next
  surface (the image) lies at the paraxial focus.

The rays are CODE V's paraxial marginal and chief rays at the reference
wavelength: the marginal ray from the axial object point through the rim of
the entrance pupil (``EPD``), the chief ray from the largest Y field through
the centre of the stop. The trace is the ynu trace of the Field Guide
(``n'u' = nu - y c (n' - n)``, ``y' = y + t u'``) with signed indices after
mirrors, in the reader's own few lines (the reader sits below
:mod:`lensrt.paraxial`). Solves are applied in surface order and repeated
until the values settle (a solve before the stop moves the pupil the others
use). The written value on the S line is CODE V's own solved value: where the
re-solved one agrees within ``SAME_REL`` it is kept digit for digit; where it
differs (other glass data, a hand-edited file) the solved value is used and a
``solve`` warning says by how much.

Not read, each with an error naming the construct: solves on other surfaces
(``CUY S3 UMY``), marginal-ray solves to a non-zero value with ``FNO``/``NAO``
apertures (``PIM`` and ``HMY 0`` do not depend on the ray's scale and are
read), chief-ray solves with image-height fields, and solve kinds other than
those above. In zoom files and in lenses with decenters or tilts the reader
keeps the written values (CODE V's solutions) with a ``keyword_ignored``
warning instead of re-solving. ``PIM`` after the lens data (a system command,
rayoptics' ``threemir.seq``) is the image solve on the last surface.
"""
from __future__ import annotations

import math
from dataclasses import replace

from ...errors import PrescriptionError
from ..model import Aperture, Fields, LoadWarning, Surface

__all__ = ["SOLVE_KINDS", "apply_solves"]

#: solve keyword -> (what it sets, which ray): the solves this reader applies
SOLVE_KINDS = {"UMY": ("curvature", "marginal"), "UCY": ("curvature", "chief"),
               "HMY": ("thickness", "marginal"), "HCY": ("thickness", "chief"), "PIM": ("thickness", "marginal")}
_MAX_ROUNDS = 50
#: a re-solved value this close (relative) to the written one confirms it and the written digits are kept
SAME_REL = 1e-9


def _trace(surfaces: list[Surface], n: list[float], y1: float, u0: float) -> tuple[list[float], list[float]]:
    """Heights at each surface and slopes before it of the ray (y1 at surface 1, slope u0 before it);
    the slopes list has one more entry, the slope after the last surface."""
    ys, us = [], [u0]
    y, u = y1, u0
    for k, s in enumerate(surfaces):
        u = (n[k] * u - y * s.curvature_per_mm * (n[k + 1] - n[k])) / n[k + 1]
        ys.append(y)
        us.append(u)
        y = y + s.thickness_mm * u
    return ys, us


def _rays(surfaces: list[Surface], n: list[float], stop: int, d0: float, aperture: Aperture,
          fields: Fields) -> dict[str, tuple[list[float], list[float]]]:
    """CODE V's paraxial marginal and chief rays (see the module docstring)."""
    a = _trace(surfaces, n, 1.0, 0.0)[0][stop]   # y at the stop per unit height at surface 1
    b = _trace(surfaces, n, 0.0, 1.0)[0][stop]   # ... per unit slope before surface 1
    half = aperture.value / 2.0 if aperture.kind == "epd" else 1.0  # scale-free solves only (apply_solves)
    if math.isinf(d0):
        marginal = _trace(surfaces, n, half, 0.0)
    else:
        if a == 0.0:
            raise PrescriptionError("solve: the stop is imaged to infinity in object space (no entrance pupil)")
        z_ep = b / a                               # entrance pupil behind surface 1
        u0 = half / (d0 + z_ep)
        marginal = _trace(surfaces, n, u0 * d0, u0)
    out = {"marginal": marginal}
    h = max(fields.y, key=abs) if fields.y else 0.0
    if a == 0.0 and (fields.kind != "angle" or not math.isinf(d0)):
        return out
    if fields.kind == "angle":
        u0 = math.tan(h)
        out["chief"] = _trace(surfaces, n, -u0 * b / a if a else 0.0, u0)
    elif fields.kind == "object_height" and not math.isinf(d0):
        u0 = -h * a / (a * d0 + b)
        out["chief"] = _trace(surfaces, n, h + u0 * d0, u0)
    return out


def _solve_one(surfaces: list[Surface], n: list[float], k: int, kind: str, value: float,
               rays: dict) -> Surface:
    what, ray = SOLVE_KINDS[kind]
    if ray not in rays:
        raise PrescriptionError(f"{kind}: a chief-ray solve needs angle fields (or object heights at a finite "
                                "object)", hint="write the solved value instead")
    ys, us = rays[ray]
    s = surfaces[k]
    if what == "curvature":
        if ys[k] == 0.0 or n[k + 1] == n[k]:
            raise PrescriptionError(f"CUY {kind}: the {ray} ray meets the surface on the axis (or the indices "
                                    "are equal): no curvature gives the slope", hint="write the curvature")
        c = (n[k] * us[k] - n[k + 1] * value) / (ys[k] * (n[k + 1] - n[k]))  # n'u' = nu - y c (n' - n)
        return replace(s, curvature_per_mm=c)
    if us[k + 1] == 0.0:
        raise PrescriptionError(f"{kind}: the {ray} ray leaves the surface parallel to the axis: no thickness "
                                "gives the height", hint="write the thickness")
    return replace(s, thickness_mm=(value - ys[k]) / us[k + 1])


def apply_solves(surfaces: list[Surface], solves: dict[int, list[tuple[str, float, int]]], *, stop: int,
                 object_distance_mm: float, object_index: float, indices: list[float], aperture: Aperture,
                 fields: Fields, unit_mm: float, defocus_mm: float,
                 path: str | None) -> tuple[list[Surface], list[LoadWarning]]:
    """The surfaces with every solve applied, and a ``solve`` warning where a value moved.

    ``solves`` maps a 0-based surface to its (kind, value in file units, line); ``indices`` are the
    unsigned indices after each surface at the reference wavelength; ``defocus_mm`` (the SI
    thickness) stays added to the last thickness after a PIM there.
    """
    if not solves:
        return surfaces, []
    first = min(ln for v in solves.values() for _, _, ln in v)
    scaled = [ln for v in solves.values() for kind, value, ln in v if SOLVE_KINDS[kind][1] == "marginal" and value]
    if aperture.kind != "epd" and scaled:  # PIM and HMY 0 do not depend on the marginal ray's scale
        raise PrescriptionError(f"a marginal-ray solve to a non-zero value with a {aperture.kind} aperture is not "
                                "supported", path=path, line=scaled[0],
                                hint="give the aperture as EPD or write the solved values")
    if any(s.transform_before is not None or s.transform_after is not None for s in surfaces):
        raise PrescriptionError("a paraxial solve in a lens with decenters or tilts is not supported", path=path,
                                line=first, hint="write the solved values")
    n, sign = [object_index], 1.0
    for s, idx in zip(surfaces, indices):
        sign = -sign if s.mirror else sign
        n.append(sign * idx)
    out = list(surfaces)
    last = len(out) - 1
    for _ in range(_MAX_ROUNDS):
        moved = 0.0
        for k in sorted(solves):
            for kind, value, line in solves[k]:
                scale = unit_mm if SOLVE_KINDS[kind][0] == "thickness" else 1.0
                try:
                    rays = _rays(out, n, stop, object_distance_mm, aperture, fields)
                    new = _solve_one(out, n, k, kind, value * scale, rays)
                except PrescriptionError as e:
                    raise PrescriptionError(e.message, path=path, line=line, hint=e.hint) from None
                if k == last and SOLVE_KINDS[kind][0] == "thickness":
                    new = replace(new, thickness_mm=new.thickness_mm + defocus_mm)
                moved = max(moved, abs(new.curvature_per_mm - out[k].curvature_per_mm) * 1e3,
                            abs(new.thickness_mm - out[k].thickness_mm))
                out[k] = new
        if moved < 1e-13:
            break
    found = []
    for k in sorted(solves):
        a, b = surfaces[k], out[k]
        for what, old, new in (("curvature_per_mm", a.curvature_per_mm, b.curvature_per_mm),
                               ("thickness_mm", a.thickness_mm, b.thickness_mm)):
            if abs(new - old) <= SAME_REL * max(1.0, abs(old)):
                out[k] = replace(out[k], **{what: old})  # the solve confirms the written value: keep its digits
            else:
                found.append(LoadWarning("solve", f"surface {k + 1}: the solve gives {what.split('_')[0]} "
                                         f"{new:.10g} (the file writes {old:.10g}: other glass data than the "
                                         "file's author used?)", k, solves[k][0][2]))
    return out, found
