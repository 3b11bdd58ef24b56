"""Rays for the paraxial-against-real analyses, built on the public pieces of :mod:`lensrt.trace`.

Field points here are named by their *object-space* value: a field angle
theta (rad, object at infinity) or an object height h (mm, finite object),
along an azimuth (default +y, the meridional plane y-z). A positive angle is
a beam rising toward +y (the object at -y) and images at +y; a positive object
height is at +y and images at -y through a positive lens (as in
:mod:`lensrt.trace.aiming`). Angles may pass 90 degrees (fisheyes).

Close (differential) rays sit beside a chief ray: offset by +-delta across a
collimated beam, or turned by +-epsilon about a finite object point, in the
tangential (meridional) and sagittal directions. Their foci converge to the
Coddington foci as delta -> 0 with an O(delta^2) error (the symmetric pair
cancels the O(delta) term), see :mod:`lensrt.analysis.compare.focus`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..paraxial import FirstOrder, first_order, paraxial_system, trace_ynu
from ..prescription.model import Lens
from ..trace import RayBatch, RayResult, kernel_to_stop, trace
from ..trace.aiming import FieldPoint, aim_many, aim_rays, beam_basis, field_point, pupil_geometry

__all__ = ["FieldSpec", "lens_fields", "field_spec", "object_field_point", "aim_batch", "aim_batches", "chief_batch", "chief_batches",
           "trace64", "trace64_many", "close_ray_batch", "meridional_intersection_z", "axis_crossing_z", "plane_crossing_z",
           "paraxial_chief", "first_orders", "exit_pupil_point_z_mm", "field_unit", "field_key", "field_display",
           "FIELD_KEYS", "CLOSE_RAY_FRACTION", "pupil_grid_rays",
           "pupil_grid_rays_many"]

#: close rays sit this fraction of the entrance-pupil radius beside the chief ray
CLOSE_RAY_FRACTION = 1e-4


@dataclass(frozen=True)
class FieldSpec:
    """One radial field point of a lens.

    Attributes
    ----------
    hy : float
        Normalised (polar) field, ``value / lens.fields.max_radial``.
    value : float
        In the lens's field unit: rad for angle fields, mm for heights.
    object_value : float
        Object space: angle (rad) for an object at infinity, height (mm) otherwise.
    infinite : bool
        Object at infinity.
    label : str
        E.g. "14.00 deg" or "12.500 mm".
    """

    hy: float
    value: float
    object_value: float
    infinite: bool
    label: str


def field_unit(lens: Lens) -> str:
    """'deg' for angle fields, else 'mm'."""
    return "deg" if lens.fields.kind == "angle" else "mm"


#: JSON key / column name of a field value in the lens's own field unit, by field kind
FIELD_KEYS = {"angle": "field_deg", "object_height": "object_height_mm",
              "paraxial_image_height": "paraxial_image_height_mm", "real_image_height": "real_image_height_mm"}


def field_key(lens: Lens) -> str:
    """Name of the lens's field values with their unit (``field_deg``, ``object_height_mm``, ...)."""
    return FIELD_KEYS[lens.fields.kind]


def field_display(lens: Lens, spec: "FieldSpec") -> float:
    """A field value in the lens's field unit at the edge: degrees for angles, mm for heights."""
    return math.degrees(spec.value) if lens.fields.kind == "angle" else spec.value


def _label(lens: Lens, value: float) -> str:
    return f"{math.degrees(value):.2f} deg" if lens.fields.kind == "angle" else f"{value:.3f} mm"


def field_spec(lens: Lens, hy: float, value: float | None = None) -> FieldSpec:
    """The field point at normalised field ``hy`` (along +y); ``value`` (lens field unit) if known exactly."""
    fp = field_point(lens, 0.0, float(hy))
    value = float(hy) * lens.fields.max_radial if value is None else float(value)
    if fp.infinite and lens.fields.kind == "angle":
        obj = value
    elif fp.infinite:
        dx, dy, dz = fp.direction
        obj = math.atan2(math.hypot(dx, dy), dz)
    else:
        obj = math.hypot(fp.point_mm[0], fp.point_mm[1])
    return FieldSpec(float(hy), value, float(obj), fp.infinite, _label(lens, value))


def lens_fields(lens: Lens, extra: Sequence[float] | None = None) -> list[FieldSpec]:
    """The lens's radial field points (sorted, duplicates dropped) plus ``extra`` (lens field units)."""
    fmax = lens.fields.max_radial
    values = {round(math.hypot(x, y), 12) for x, y in zip(lens.fields.x, lens.fields.y)}
    for v in extra or ():
        if not math.isfinite(v) or v < 0:
            raise LensrtError(f"field value {v!r} must be a non-negative number in the lens's field unit")
        values.add(round(float(v), 12))
    if fmax <= 0.0:
        return [field_spec(lens, 0.0)]
    return [field_spec(lens, v / fmax, v) for v in sorted(values)]


def object_field_point(lens: Lens, object_value: float, azimuth_rad: float = math.pi / 2) -> FieldPoint:
    """Field point at object-space value (angle rad or height mm) along ``azimuth_rad`` (from +x)."""
    ca, sa = math.cos(azimuth_rad), math.sin(azimuth_rad)
    if abs(ca) < 1e-15:
        ca = 0.0
    if math.isinf(lens.object_distance_mm):
        s, c = math.sin(object_value), math.cos(object_value)
        return FieldPoint(True, (s * ca, s * sa, c), None)
    return FieldPoint(False, None, (object_value * ca, object_value * sa, -lens.object_distance_mm))


def aim_batch(lens: Lens, fp: FieldPoint, px, py, wavelength_nm: float, aim: str = "real",
              device: str | None = None) -> RayBatch:
    """Rays of field point ``fp`` at pupil coordinates (px, py) (see :mod:`lensrt.trace.aiming`)."""
    to_stop = None if aim == "paraxial" else kernel_to_stop(lens, device)
    o, d, ok = aim_rays(lens, fp, np.atleast_1d(px), np.atleast_1d(py), float(wavelength_nm), aim, to_stop)
    return RayBatch(o, d, float(wavelength_nm), ok)


def aim_batches(lens: Lens, jobs: Sequence[tuple[FieldPoint, object, object, float]], aim: str = "real",
                device: str | None = None) -> list[RayBatch]:
    """Several :func:`aim_batch` calls in one: ``jobs`` holds (field point, px, py, wavelength_nm) each, and
    every job's rays are aimed together (one trace per Newton step for all of them), the same rays as
    :func:`aim_batch` job by job."""
    fps, index, parts = [], {}, []
    if not jobs:
        return []
    for fp, px, py, w in jobs:
        px, py = np.broadcast_arrays(np.atleast_1d(np.asarray(px, dtype=np.float64)),
                                     np.atleast_1d(np.asarray(py, dtype=np.float64)))
        f = index.setdefault(fp, len(fps))
        if f == len(fps):
            fps.append(fp)
        parts.append((f, px.ravel(), py.ravel(), float(w)))
    rows = np.concatenate([np.full(len(px), f, dtype=np.intp) for f, px, _, _ in parts])
    wl = np.concatenate([np.full(len(px), w) for _, px, _, w in parts])
    px_all, py_all = np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts])
    if aim == "real":
        o, d, ok = _aim_real(lens, fps, rows, px_all, py_all, wl, device)
    else:
        to_stop = None if aim == "paraxial" else kernel_to_stop(lens, device)
        o, d, ok = aim_many(lens, fps, rows, px_all, py_all, wl, aim, to_stop)
    ends = np.cumsum([0] + [len(p[1]) for p in parts])
    return [RayBatch(o[a:b], d[a:b], w, ok[a:b]) for (_, _, _, w), a, b in zip(parts, ends[:-1], ends[1:])]


def chief_batch(lens: Lens, fps: Sequence[FieldPoint], wavelength_nm: float,
                device: str | None = None) -> RayBatch:
    """Real chief rays (through the centre of the real stop) of several field points."""
    fps = list(fps)
    n = len(fps)
    o, d, ok = _aim_real(lens, fps, np.arange(n), np.zeros(n), np.zeros(n), np.full(n, float(wavelength_nm)), device)
    return RayBatch(o, d, float(wavelength_nm), ok)


#: rays already aimed by real-ray aiming on the kernel tracer: per (lens, device), a ray per (field point, px, py,
#: wavelength) -- the analyses of a comparison aim many of the same rays (the chief rays of their field points
#: above all). Each ray's Newton run (and continuation in field) is its own, the same bits whatever is aimed
#: beside it, so a ray found here is the ray aiming gives. At most _AIMED_LENSES lenses and _AIMED_KEPT rays each.
_AIMED: dict = {}
_AIMED_LENSES = 8
_AIMED_KEPT = 1 << 15


def _aim_real(lens: Lens, fps: list, rows: np.ndarray, px: np.ndarray, py: np.ndarray, wl: np.ndarray,
              device: str | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``aim_many(..., "real", kernel_to_stop(lens, device))`` for the rays not aimed yet; the others from the cache."""
    n = len(rows)
    known = _AIMED.setdefault((lens, device), {})
    if len(_AIMED) > _AIMED_LENSES:  # the oldest lens out
        del _AIMED[next(iter(_AIMED))]
    keys = [(fps[r], float(a), float(b), float(w)) for r, a, b, w in zip(rows, px, py, wl)]
    miss = np.array([i for i, k in enumerate(keys) if k not in known], dtype=np.intp)
    if len(miss):
        o, d, ok = aim_many(lens, fps, rows[miss], px[miss], py[miss], wl[miss], "real", kernel_to_stop(lens, device))
        if len(known) + len(miss) > _AIMED_KEPT:
            known.clear()
        for j, i in enumerate(miss):
            known[keys[i]] = (o[j], d[j], bool(ok[j]))
    got = [known[k] for k in keys]
    return (np.array([g[0] for g in got]).reshape(n, 3), np.array([g[1] for g in got]).reshape(n, 3),
            np.array([g[2] for g in got], dtype=bool).reshape(n))


def chief_batches(lens: Lens, fps: Sequence[FieldPoint], wavelengths_nm: Sequence[float],
                  device: str | None = None) -> list[RayBatch]:
    """:func:`chief_batch` at each of several wavelengths (one RayBatch per wavelength), aimed in one solve."""
    fps = list(fps)
    wls = [float(w) for w in wavelengths_nm]
    parts = aim_batches(lens, [(fp, 0.0, 0.0, w) for w in wls for fp in fps], "real", device)
    out = []
    for j, w in enumerate(wls):
        part = parts[j * len(fps):(j + 1) * len(fps)]
        out.append(RayBatch(np.concatenate([c.origin_mm for c in part]).reshape(-1, 3),
                            np.concatenate([c.direction for c in part]).reshape(-1, 3), w,
                            np.concatenate([c.aimed for c in part]).astype(bool)))
    return out


def trace64(lens: Lens, rays: RayBatch, device: str | None = None, *, clip: bool = False,
            plane_z_mm: float | None = None) -> RayResult:
    """Store-kernel trace in float64 (the analyses' precision)."""
    return trace(lens, rays, "float64", device, clip=clip, plane_z_mm=plane_z_mm)


def trace64_many(lens: Lens, batches: Sequence[RayBatch], device: str | None = None, *, clip: bool = False,
                 plane_z_mm: float | None = None) -> list[RayResult]:
    """:func:`trace64` of several batches (any wavelengths) in one trace (one launch): one result per batch,
    the same as tracing them one by one."""
    batches = list(batches)
    if not batches:
        return []
    joined = RayBatch(np.concatenate([b.origin_mm for b in batches]), np.concatenate([b.direction for b in batches]),
                      np.concatenate([b.wavelength_nm for b in batches]), np.concatenate([b.aimed for b in batches]))
    res = trace64(lens, joined, device, clip=clip, plane_z_mm=plane_z_mm)
    ends = np.cumsum([0] + [len(b) for b in batches])
    return [res.part(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]


def close_ray_batch(lens: Lens, chief: RayBatch, fps: Sequence[FieldPoint],
                    fraction: float = CLOSE_RAY_FRACTION) -> RayBatch:
    """Three close rays per chief ray: tangential +delta, tangential -delta, sagittal +delta.

    Rows 3k, 3k+1, 3k+2 belong to chief ray k. For a collimated beam the ray is
    moved by delta = ``fraction`` x r_EP across the beam; from a finite object
    point it is turned by delta / (distance to the entrance pupil) about that point.
    """
    geom = pupil_geometry(lens)
    delta = fraction * geom.ep_radius_mm
    o, d = [], []
    for k, fp in enumerate(fps):
        d0 = chief.direction[k]
        e1, e2 = beam_basis(d0)
        if fp.infinite:
            o0 = chief.origin_mm[k]
            o += [o0 + delta * e2, o0 - delta * e2, o0 + delta * e1]
            d += [d0, d0, d0]
        else:
            p = np.asarray(fp.point_mm, dtype=np.float64)
            eps = delta / max(abs(geom.ep_z_mm - p[2]), 1e-9)
            for v in (d0 + eps * e2, d0 - eps * e2, d0 + eps * e1):
                o.append(p)
                d.append(v / np.linalg.norm(v))
    return RayBatch(np.array(o), np.array(d), float(chief.wavelength_nm[0]))


def meridional_intersection_z(p1: np.ndarray, v1: np.ndarray, p2: np.ndarray, v2: np.ndarray) -> np.ndarray:
    """z where two rays' projections on the y-z plane cross (rows of (n, 3) arrays)."""
    det = v1[:, 1] * (-v2[:, 2]) - (-v2[:, 1]) * v1[:, 2]
    by, bz = p2[:, 1] - p1[:, 1], p2[:, 2] - p1[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (by * (-v2[:, 2]) - (-v2[:, 1]) * bz) / det
    return p1[:, 2] + s * v1[:, 2]


def plane_crossing_z(p: np.ndarray, v: np.ndarray, axis: int) -> np.ndarray:
    """z where rays (n, 3) cross the plane {coordinate ``axis`` = 0} (0: x = 0, 1: y = 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return p[:, 2] - p[:, axis] * v[:, 2] / v[:, axis]


def axis_crossing_z(p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """z where meridional rays (x = 0) cross the axis (y = 0)."""
    return plane_crossing_z(p, v, 1)


def paraxial_chief(lens: Lens, fo: FirstOrder, object_value: float) -> tuple[float, float]:
    """Paraxial chief ray of an object-space field value: (height at the paraxial image plane (mm), image slope).

    Through the centre of the paraxial entrance pupil; an angle uses u0 = tan(theta)
    (NaN at and beyond 90 degrees, where a paraxial image height does not exist).
    """
    sysm = paraxial_system(lens, fo.wavelength_nm)
    z_ep = fo.entrance_pupil_z_mm
    if fo.object_distance_mm is None:
        if abs(object_value) >= 0.5 * math.pi:
            return math.nan, math.nan
        u0 = math.tan(object_value)
        y1 = -u0 * z_ep
    else:
        dist = fo.object_distance_mm
        u0 = -object_value / (z_ep + dist)
        y1 = object_value + u0 * dist
    ray = trace_ynu(sysm, y1, u0)
    return ray.height_at(fo.image_distance_mm), float(ray.u[-1])


def first_orders(lens: Lens, wavelengths_nm: Sequence[float]) -> dict[float, FirstOrder]:
    """:func:`lensrt.paraxial.first_order` at each wavelength (nm)."""
    return {float(w): first_order(lens, float(w)) for w in wavelengths_nm}


def exit_pupil_point_z_mm(lens: Lens, p: np.ndarray, v: np.ndarray, wavelength_nm: float) -> float:
    """z where a chief ray (image-space point ``p``, direction ``v``) crosses the axis; paraxial XP on axis."""
    from ..paraxial import first_order
    vr = math.hypot(v[0], v[1])
    if math.hypot(p[0], p[1]) < 1e-9:
        return first_order(lens, wavelength_nm).exit_pupil_z_mm
    if vr < 1e-12:
        return math.inf  # image-space telecentric
    s = -(p[0] * v[0] + p[1] * v[1]) / (vr * vr)
    return float(p[2] + s * v[2])


def pupil_grid_rays(lens: Lens, fp: FieldPoint, wavelength_nm: float, n: int, device: str | None = None) -> RayBatch:
    """A square n x n grid of rays over the box of the real pupil of ``fp`` (vignetted rays fail when traced)."""
    rays = pupil_grid_rays_many(lens, [(fp, wavelength_nm)], n, device)[0]
    if rays is None:
        raise LensrtError("no ray of this field point passes the lens")
    return rays


def pupil_grid_rays_many(lens: Lens, jobs: Sequence[tuple[FieldPoint, float]], n: int,
                         device: str | None = None) -> list[RayBatch | None]:
    """:func:`pupil_grid_rays` of several (field point, wavelength nm) jobs, the same rays, their pupil boxes
    found in one batched search (None for a job whose field point no ray passes)."""
    from ..trace.aiming import ray_through_point
    from ..trace.stream import pupil_boxes
    jobs = list(jobs)
    boxes = pupil_boxes(lens, [fp for fp, _ in jobs], device=device, coarse=64, fine=32,
                        field_wavelengths_nm=[float(w) for _, w in jobs])
    out: list[RayBatch | None] = []
    for (fp, wavelength_nm), box in zip(jobs, boxes):
        if box.area_mm2 <= 0:
            out.append(None)
            continue
        a = box.a0 + (np.arange(n) + 0.5) * (box.a1 - box.a0) / n
        b = box.b0 + (np.arange(n) + 0.5) * (box.b1 - box.b0) / n
        A, B = np.meshgrid(a, b, indexing="ij")
        o, d = ray_through_point(fp, box.points(A.ravel(), B.ravel()))
        out.append(RayBatch(o, d, wavelength_nm))
    return out
