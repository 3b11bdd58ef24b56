"""Rays named by field and pupil coordinates, and ray aiming (host, float64).

Field (Hx, Hy) and pupil (Px, Py) are normalised coordinates in [-1, 1], as
in Zemax and optiland. The field is *polar*: the radial field value is
``|H| * lens.fields.max_radial`` along the azimuth ``atan2(Hy, Hx)`` -- linear
in angle for angle fields, in object height for height fields, in image height
for image-height fields. (For a field on one axis this is Zemax's convention;
the polar form also holds beyond 90 degrees, where fisheyes work.) A positive
field angle gives a ray rising toward +y (CODE V and Zemax: the object point
lies at -y); a positive object height puts the object point at +y.

Three ways to aim a ray at the pupil (``aim``):

``"paraxial"``
    through the point (Px, Py) * r_EP of the paraxial entrance pupil plane
    (primary wavelength), Zemax's "ray aiming off";
``"chief"``
    the chief ray is aimed at the centre of the real stop; the pupil offset
    (Px, Py) * r_EP is then added in the paraxial entrance-pupil plane. This is
    CODE V's default (its ``ssp`` listings), good for moderate fields;
``"real"``
    iterated (Newton's method) until the ray meets the real stop at
    (Px, Py) * R_stop -- Zemax's "real ray aiming"; needed for wide-angle
    lenses and fisheyes, whose real pupil is far from the paraxial one.

The stop radius R_stop is the stop's clear semi-diameter when the aperture
floats by stop size, and otherwise the height at the stop of the real axial
marginal ray entering at the specified entrance-pupil radius (CODE V's
choice: the specified EPD holds exactly on axis).

Ray origins lie on the object-space wavefront through the first vertex (the
plane perpendicular to the beam for an object at infinity, the sphere centred
on the object point otherwise), so optical path lengths of one field point
share a reference and stay small numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from .reference import trace_reference
from .status import OK

__all__ = ["AIM_MODES", "FieldPoint", "PupilGeometry", "field_point", "pupil_geometry", "beam_basis", "aim_many",
           "ray_through_point", "rays_through_points", "aim_rays", "chief_rays", "reference_to_stop", "ToStop"]

AIM_MODES = ("paraxial", "chief", "real")

#: continuation in field for rays that Newton's method cannot aim directly: base steps from the
#: axis to the field, and how often a step may be halved for a ray that loses the path
_CONTINUATION_STEPS = 8
_CONTINUATION_HALVINGS = 4

#: to_stop(origins (n, 3), directions (n, 3), wavelength_nm (n,)) -> (x (n,), y (n,), ok (n,) bool):
#: where each ray meets the stop surface (stop frame), traced without clipping
ToStop = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class FieldPoint:
    """An object-space field point: a beam direction (object at infinity) or an object point."""

    infinite: bool
    #: unit direction of the collimated beam (infinite) -- else None
    direction: tuple[float, float, float] | None
    #: object point in the lens frame, mm (finite) -- else None
    point_mm: tuple[float, float, float] | None


@dataclass(frozen=True)
class PupilGeometry:
    """Paraxial entrance pupil (primary wavelength) and the real stop radius."""

    ep_z_mm: float
    ep_radius_mm: float
    stop_index: int
    stop_radius_mm: float
    wavelength_nm: float


def _radial_to_object(lens: Lens, value: float) -> float:
    """Convert a radial field value in the lens's unit to object space (angle rad or height mm)."""
    kind = lens.fields.kind
    if kind in ("angle", "object_height"):
        return value
    from ..paraxial import first_order, paraxial_system
    from ..paraxial.first_order import field_slope_and_height
    fo = first_order(lens)
    sysm = paraxial_system(lens)
    u0, y1 = field_slope_and_height(lens, 1.0, lens.object_distance_mm, fo.entrance_pupil_z_mm, sysm,
                                    fo.entrance_pupil_diameter_mm)
    infinite = math.isinf(lens.object_distance_mm)
    per_unit = u0 if infinite else y1 - u0 * lens.object_distance_mm  # object slope/height per mm of image
    if kind == "paraxial_image_height":
        return math.atan(value * per_unit) if infinite else value * per_unit
    return _real_image_height_to_object(lens, value, per_unit)


def _real_image_height_to_object(lens: Lens, value: float, per_unit: float) -> float:
    """Object-space field whose real chief ray reaches image height ``value`` (secant iteration)."""
    if value == 0.0:
        return 0.0
    infinite = math.isinf(lens.object_distance_mm)
    geom = pupil_geometry(lens)

    def height(obj: float) -> float:
        fp = _field_point_object(lens, obj, 0.0, 1.0)
        o, d = aim_rays(lens, fp, np.zeros(1), np.zeros(1), geom.wavelength_nm, "real")[:2]
        r = trace_reference(lens, o[0], d[0], geom.wavelength_nm, clip=False)
        if r.status != OK:
            raise LensrtError(f"no real chief ray reaches image height {value:g} mm")
        return r.y_mm

    def obj_of(v: float) -> float:
        return math.atan(v * per_unit) if infinite else v * per_unit

    x0, x1 = obj_of(0.9 * value), obj_of(value)
    f0, f1 = height(x0) - value, height(x1) - value
    for _ in range(30):
        if abs(f1) < 1e-10 or f1 == f0:
            break
        x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
        f1 = height(x1) - value
    if abs(f1) > 1e-6:
        raise LensrtError(f"cannot find the field of real image height {value:g} mm")
    return x1


def _field_point_object(lens: Lens, radial: float, ca: float, sa: float) -> FieldPoint:
    """Field point at object-space radial value ``radial`` along the unit azimuth (ca, sa)."""
    if math.isinf(lens.object_distance_mm):
        s, c = math.sin(radial), math.cos(radial)
        return FieldPoint(True, (s * ca, s * sa, c), None)
    return FieldPoint(False, None, (radial * ca, radial * sa, -lens.object_distance_mm))


def field_point(lens: Lens, hx: float, hy: float) -> FieldPoint:
    """The field point named by normalised field coordinates (module docstring).

    An angle field with a finite object names the object point whose chief ray
    makes that angle with the axis through the centre of the paraxial entrance
    pupil (Zemax's and CODE V's definition, and the paraxial chief ray of
    :func:`lensrt.paraxial.first_order.field_slope_and_height`): the point at
    height -tan(angle) (object distance + z_EP), below the axis for a positive angle.
    """
    h = math.hypot(hx, hy)
    ca, sa = (hx / h, hy / h) if h > 0.0 else (0.0, 1.0)  # exact zeros on the axes
    radial = _radial_to_object(lens, h * lens.fields.max_radial)
    if lens.fields.kind == "angle" and not math.isinf(lens.object_distance_mm):
        if abs(radial) >= 0.5 * math.pi:
            raise LensrtError(f"field angle {math.degrees(radial):g} deg cannot come from an object plane at "
                              f"{lens.object_distance_mm:g} mm", hint="field angles of a finite object are below 90 deg")
        from ..paraxial import first_order
        ep_z = first_order(lens).entrance_pupil_z_mm
        radial = -math.tan(radial) * (lens.object_distance_mm + ep_z)
    return _field_point_object(lens, radial, ca, sa)


@lru_cache(maxsize=64)
def pupil_geometry(lens: Lens) -> PupilGeometry:
    """Entrance pupil and real stop radius of ``lens`` (see the module docstring)."""
    from ..paraxial import first_order
    fo = first_order(lens)
    wl = lens.wavelengths.primary_nm
    stop = lens.stop_index
    r_ep = 0.5 * fo.entrance_pupil_diameter_mm
    sd = lens.surfaces[stop].semi_diameter_mm
    if lens.aperture.kind == "float_by_stop" and sd is not None:
        radius = sd
    else:
        fp = field_point(lens, 0.0, 0.0)
        o, d = ray_through_point(fp, np.array([[0.0, r_ep, fo.entrance_pupil_z_mm]]))
        r = trace_reference(lens, o[0], d[0], wl, clip=False, end=stop)
        radius = abs(r.y_mm) if r.status == OK else fo.stop_semi_diameter_mm
    return PupilGeometry(fo.entrance_pupil_z_mm, r_ep, stop, float(radius), wl)


def beam_basis(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal e1, e2 perpendicular to unit ``w`` (..., 3): x and y rotated minimally onto w.

    Smooth for every direction but -z, where e1 = x, e2 = -y (a beam from straight behind);
    on axis e1 = x, e2 = y.
    """
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    back = 1.0 + wz <= 1e-12
    f = 1.0 / np.where(back, 1.0, 1.0 + wz)
    e1 = np.stack([1.0 - wx * wx * f, -wx * wy * f, -wx], axis=-1)
    e2 = np.stack([-wx * wy * f, 1.0 - wy * wy * f, -wy], axis=-1)
    if np.any(back):
        e1 = np.where(back[..., None], np.array([1.0, 0.0, 0.0]), e1)
        e2 = np.where(back[..., None], np.array([0.0, -1.0, 0.0]), e2)
    return e1, e2


def ray_through_point(fp: FieldPoint, points_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays from field point ``fp`` through ``points_mm`` (n, 3): (origins, directions).

    Origins lie on the object-space wavefront through the first vertex (module docstring).
    """
    a = np.atleast_2d(np.asarray(points_mm, dtype=np.float64))
    if fp.infinite:
        d = np.broadcast_to(np.asarray(fp.direction, dtype=np.float64), a.shape).copy()
        origin = a - np.sum(a * d, axis=1, keepdims=True) * d  # foot on the plane through 0, normal d
        return origin, d
    o = np.asarray(fp.point_mm, dtype=np.float64)
    v = a - o
    dist = np.linalg.norm(v, axis=1, keepdims=True)
    d = v / dist
    r0 = float(np.linalg.norm(o))
    # step back from the aim point to the sphere |p - o| = |o|, without cancellation
    back = (np.sum(a * a, axis=1, keepdims=True) - 2.0 * (a @ o)[:, None]) / (dist + r0)
    return a - back * d, d


def rays_through_points(fps, points_mm: np.ndarray, rows: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Rays from field point ``fps[rows[k]]`` (``fps[k]`` without ``rows``) through ``points_mm[k]`` (n, 3):
    (origins, directions), as :func:`ray_through_point` gives them one field point at a time."""
    a = np.atleast_2d(np.asarray(points_mm, dtype=np.float64))
    idx = np.arange(len(fps)) if rows is None else np.asarray(rows)
    inf_f = np.array([fp.infinite for fp in fps], dtype=bool)
    dirs = np.array([fp.direction if fp.infinite else (0.0, 0.0, 1.0) for fp in fps], dtype=np.float64)
    objs = np.array([(0.0, 0.0, 0.0) if fp.infinite else fp.point_mm for fp in fps], dtype=np.float64)
    inf = inf_f[idx]
    d = np.empty_like(a)
    o = np.empty_like(a)
    if inf.any():
        di = dirs[idx[inf]]
        ai = a[inf]
        o[inf] = ai - np.sum(ai * di, axis=1, keepdims=True) * di
        d[inf] = di
    if (~inf).any():
        ob = objs[idx[~inf]]
        af = a[~inf]
        v = af - ob
        dist = np.linalg.norm(v, axis=1, keepdims=True)
        df = v / dist
        r0 = np.linalg.norm(ob, axis=1, keepdims=True)
        back = (np.sum(af * af, axis=1, keepdims=True) - 2.0 * np.sum(af * ob, axis=1, keepdims=True)) / (dist + r0)
        o[~inf] = af - back * df
        d[~inf] = df
    return o, d


def aim_frames(fps, geom: PupilGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per field point: the centre C of the aim plane (the paraxial entrance pupil's centre, shared),
    the beam axis w (n, 3) and the plane's basis e1, e2 (n, 3) -- :func:`_aim_frame` for many."""
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    w = np.empty((len(fps), 3))
    for k, fp in enumerate(fps):
        if fp.infinite:
            w[k] = fp.direction
        else:
            v = c - np.asarray(fp.point_mm, dtype=np.float64)
            w[k] = v / np.linalg.norm(v)
    e1, e2 = beam_basis(w)
    return c, w, e1, e2


def chief_rays(lens: Lens, fps, wavelength_nm: float | np.ndarray, to_stop: ToStop | None = None,
               geometry: PupilGeometry | None = None, fallback: bool = True
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Real chief rays (through the centre of the real stop) of many field points at once:
    (origins, directions, aimed), one row per field point.

    The Newton iteration of :func:`aim_rays` (``aim="real"``, pupil (0, 0)) runs on every field point
    together, so the rays to the stop are traced in a few batched calls; a field point it cannot aim
    directly falls back to :func:`aim_rays` alone (continuation in field) unless ``fallback`` is False.
    """
    fps = list(fps)
    n = len(fps)
    geom = pupil_geometry(lens) if geometry is None else geometry
    wl = np.broadcast_to(np.asarray(wavelength_nm, dtype=np.float64), (n,)).copy()
    to_stop = reference_to_stop(lens) if to_stop is None else to_stop
    c, _, e1, e2 = aim_frames(fps, geom)

    def residual(ab: np.ndarray, rows: np.ndarray):
        pts = c + ab[:, :1] * e1[rows] + ab[:, 1:2] * e2[rows]
        o, d = rays_through_points(fps, pts, rows)
        x, y, ok = to_stop(o, d, wl[rows])
        r = np.stack([x, y], axis=1)
        r[~ok] = 0.0
        return r, ok

    scale = max(geom.ep_radius_mm, geom.stop_radius_mm)
    ab, ok = _newton(residual, np.zeros((n, 2)), scale)
    o, d = rays_through_points(fps, c + ab[:, :1] * e1 + ab[:, 1:2] * e2)
    for k in np.nonzero(~ok)[0] if fallback else ():  # continuation in field, one field point at a time
        ok_k = aim_rays(lens, fps[k], np.zeros(1), np.zeros(1), wl[k], "real", to_stop, geom)
        o[k], d[k], ok[k] = ok_k[0][0], ok_k[1][0], ok_k[2][0]
    return o, d, ok


def reference_to_stop(lens: Lens) -> ToStop:
    """A :data:`ToStop` built on the float64 reference tracer (one ray at a time)."""
    stop = lens.stop_index

    def to_stop(origins: np.ndarray, directions: np.ndarray, wavelength_nm: np.ndarray):
        n = len(origins)
        x, y, ok = np.zeros(n), np.zeros(n), np.zeros(n, dtype=bool)
        for i in range(n):
            r = trace_reference(lens, origins[i], directions[i], float(wavelength_nm[i]), clip=False, end=stop)
            x[i], y[i], ok[i] = r.x_mm, r.y_mm, r.status == OK
        return x, y, ok

    return to_stop


def _aim_frame(fp: FieldPoint, geom: PupilGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre C (on axis at the paraxial EP) and basis e1, e2 of the plane that parametrises aim points."""
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    if fp.infinite:
        w = np.asarray(fp.direction, dtype=np.float64)
    else:
        v = c - np.asarray(fp.point_mm, dtype=np.float64)
        w = v / np.linalg.norm(v)
    e1, e2 = beam_basis(w)
    return c, e1, e2


def _newton(residual: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]], ab: np.ndarray,
            scale: float, tol_mm: float = 1e-10, max_iter: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Solve residual(ab, rows) = 0 for each row of ab (n, 2): Newton, finite-difference Jacobian.

    ``residual(ab_rows, rows)`` returns (r (m, 2), ok (m,)) for the given rows (a row may repeat).
    Each step is halved until the residual drops (backtracking). Returns (ab, converged).

    Every point is evaluated together with its two finite-difference neighbours (ab + (h, 0), ab + (0, h))
    in ONE residual call, so the Jacobian of an accepted step is ready for the next one: one call (one
    trace to the stop) per Newton step instead of three, the same iterates bit for bit.
    """
    ab = ab.copy()
    n = len(ab)
    h = 1e-7 * max(scale, 1e-3)
    r, ok, ra, oka, rb, okb = _with_neighbours(residual, ab, np.arange(n), h)
    done = ok & (np.hypot(r[:, 0], r[:, 1]) <= tol_mm)
    for _ in range(max_iter):
        idx = np.nonzero(~done & ok)[0]
        if len(idx) == 0:
            break
        a0, r0 = ab[idx], r[idx]
        j00, j10 = (ra[idx, 0] - r0[:, 0]) / h, (ra[idx, 1] - r0[:, 1]) / h
        j01, j11 = (rb[idx, 0] - r0[:, 0]) / h, (rb[idx, 1] - r0[:, 1]) / h
        det = j00 * j11 - j01 * j10
        good = oka[idx] & okb[idx] & (det != 0.0) & np.isfinite(det)
        safe = np.where(good, det, 1.0)
        step = np.stack([(j11 * r0[:, 0] - j01 * r0[:, 1]) / safe,
                         (-j10 * r0[:, 0] + j00 * r0[:, 1]) / safe], axis=1)
        norm0 = np.hypot(r0[:, 0], r0[:, 1])
        lam = np.ones(len(idx))
        accepted = np.zeros(len(idx), dtype=bool)
        pending = good.copy()
        for _ in range(12):  # backtracking: take the first step length that lowers the residual
            p = np.nonzero(pending)[0]
            if len(p) == 0:
                break
            trial = a0[p] - lam[p, None] * step[p]
            rt, okt, rta, okta, rtb, oktb = _with_neighbours(residual, trial, idx[p], h)
            better = okt & (np.hypot(rt[:, 0], rt[:, 1]) < norm0[p])
            acc, rows = p[better], idx[p[better]]
            ab[rows], r[rows] = trial[better], rt[better]
            ra[rows], oka[rows], rb[rows], okb[rows] = rta[better], okta[better], rtb[better], oktb[better]
            accepted[acc] = True
            pending[acc] = False
            lam[p[~better]] *= 0.5
        ok[idx[~accepted]] = False  # no step lowers the residual: give up on this ray
        done[idx[accepted]] = np.hypot(r[idx[accepted], 0], r[idx[accepted], 1]) <= tol_mm
    return ab, done


def _with_neighbours(residual: Callable, pts: np.ndarray, rows: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    """residual at ``pts`` and at its Jacobian neighbours pts + (h, 0), pts + (0, h), in one call:
    (r, ok, r_a, ok_a, r_b, ok_b)."""
    m = len(rows)
    r3, ok3 = residual(np.concatenate([pts, pts + np.array([h, 0.0]), pts + np.array([0.0, h])]),
                       np.concatenate([rows, rows, rows]))
    return r3[:m], ok3[:m], r3[m:2 * m], ok3[m:2 * m], r3[2 * m:], ok3[2 * m:]


def aim_rays(lens: Lens, fp: FieldPoint, px: np.ndarray, py: np.ndarray, wavelength_nm: float | np.ndarray,
             aim: str = "paraxial", to_stop: ToStop | None = None,
             geometry: PupilGeometry | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays of field point ``fp`` at pupil coordinates (px, py): (origins, directions, aimed).

    ``aimed`` is False where iterated aiming did not converge (those rays keep the
    paraxial aim). ``to_stop`` traces to the stop (default: the reference tracer).
    """
    if aim not in AIM_MODES:
        raise LensrtError(f"unknown ray aiming {aim!r}", hint=f"use one of {', '.join(AIM_MODES)}")
    geom = pupil_geometry(lens) if geometry is None else geometry
    px = np.atleast_1d(np.asarray(px, dtype=np.float64))
    py = np.atleast_1d(np.asarray(py, dtype=np.float64))
    n = max(len(px), len(py))
    px, py = np.broadcast_to(px, (n,)), np.broadcast_to(py, (n,))
    wl = np.broadcast_to(np.asarray(wavelength_nm, dtype=np.float64), (n,)).copy()
    par = np.stack([px * geom.ep_radius_mm, py * geom.ep_radius_mm, np.full(n, geom.ep_z_mm)], axis=1)
    if aim == "paraxial":
        o, d = ray_through_point(fp, par)
        return o, d, np.ones(n, dtype=bool)
    to_stop = reference_to_stop(lens) if to_stop is None else to_stop
    c, e1, e2 = _aim_frame(fp, geom)

    def points(ab: np.ndarray) -> np.ndarray:
        return c + ab[:, :1] * e1 + ab[:, 1:2] * e2

    if aim == "chief":
        # one real chief ray (per wavelength), then paraxial offsets in the EP plane
        uw, inv = np.unique(wl, return_inverse=True)
        ch_ab, ch_ok = _solve(lens, fp, np.zeros((len(uw), 2)), uw, points, to_stop, geom)
        chief = points(ch_ab)
        # move each chief ray's aim point along its ray into the plane z = z_EP
        _, dch = ray_through_point(fp, chief)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(dch[:, 2] != 0.0, (geom.ep_z_mm - chief[:, 2]) / dch[:, 2], 0.0)
        chief = chief + s[:, None] * dch
        pts = chief[inv] + par - np.array([0.0, 0.0, geom.ep_z_mm])
        o, d = ray_through_point(fp, pts)
        return o, d, ch_ok[inv]
    target = np.stack([px, py], axis=1) * geom.stop_radius_mm
    ab0 = np.stack([np.sum((par - c) * e1, axis=1), np.sum((par - c) * e2, axis=1)], axis=1)
    ab, ok = _solve(lens, fp, ab0, wl, points, to_stop, geom, target)
    o, d = ray_through_point(fp, points(ab))
    if not ok.all():  # keep the paraxial aim where aiming failed
        op, dp = ray_through_point(fp, par)
        o[~ok], d[~ok] = op[~ok], dp[~ok]
    return o, d, ok


def _field_residuals(points: Callable, to_stop: ToStop) -> Callable:
    """residual_for(target (n, 2), wavelengths (n,), field point) -> the Newton residual of those rays."""
    def residual_for(tgt: np.ndarray, w: np.ndarray, f: FieldPoint):
        def residual(ab: np.ndarray, rows: np.ndarray):
            o, d = ray_through_point(f, points(ab))
            x, y, ok = to_stop(o, d, w[rows])
            r = np.stack([x, y], axis=1) - tgt[rows]
            r[~ok] = 0.0
            return r, ok
        return residual
    return residual_for


def _solve(lens: Lens, fp: FieldPoint, ab0: np.ndarray, wl: np.ndarray, points: Callable, to_stop: ToStop,
           geom: PupilGeometry, target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Newton-solve aim coordinates so rays meet the stop at ``target`` (default: the centre)."""
    target = np.zeros_like(ab0) if target is None else target
    residual_for = _field_residuals(points, to_stop)
    scale = max(geom.ep_radius_mm, geom.stop_radius_mm)
    ab, ok = _newton(residual_for(target, wl, fp), ab0, scale)
    return _continue_in_field(fp, ab, ok, wl, residual_for, target, scale)


def _continue_in_field(fp: FieldPoint, ab: np.ndarray, ok: np.ndarray, wl: np.ndarray, residual_for: Callable,
                       target: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Aim the rays of ``fp`` that Newton's method from the start could not (``~ok``) by continuation in field."""
    if ok.all():
        return ab, ok
    # continuation: walk the field (and pupil) up from the axis for the rays that failed. Each
    # step starts from the linear extrapolation of the ray's last two solutions; a step that a ray
    # cannot follow (a fisheye near 90 deg, where few starts reach the stop) is halved for that
    # ray, at most _CONTINUATION_HALVINGS times, before the ray is given up
    bad = np.nonzero(~ok)[0]
    m = len(bad)
    f_at, ab_at = np.zeros(m), np.zeros((m, 2))
    f_prev, ab_prev = np.full(m, np.nan), np.zeros((m, 2))
    step = np.full(m, 1.0 / _CONTINUATION_STEPS)
    alive = np.ones(m, dtype=bool)
    while True:
        act = np.nonzero(alive & (f_at < 1.0))[0]
        if len(act) == 0:
            break
        f_next = np.minimum(f_at[act] + step[act], 1.0)
        for fv in np.unique(f_next):
            g = act[f_next == fv]
            start = ab_at[g].copy()
            known = np.isfinite(f_prev[g])
            if known.any():
                k = g[known]
                slope = (ab_at[k] - ab_prev[k]) / (f_at[k] - f_prev[k])[:, None]
                start[known] += slope * (fv - f_at[k])[:, None]
            res = residual_for(target[bad[g]] * fv, wl[bad[g]], _scaled_field(fp, float(fv)))
            new, ok_g = _newton(res, start, scale, max_iter=20)
            good, fail = g[ok_g], g[~ok_g]
            f_prev[good], ab_prev[good] = f_at[good], ab_at[good]
            f_at[good], ab_at[good] = fv, new[ok_g]
            step[fail] *= 0.5
            alive[fail] = step[fail] >= 0.99 / (_CONTINUATION_STEPS * 2**_CONTINUATION_HALVINGS)
    done = alive & (f_at >= 1.0)
    ab[bad[done]] = ab_at[done]
    ok[bad[done]] = True
    return ab, ok


def _scaled_field(fp: FieldPoint, f: float) -> FieldPoint:
    """The field point at fraction ``f`` of its field (angle or height) along the same azimuth."""
    if fp.infinite:
        dx, dy, dz = fp.direction
        theta = math.atan2(math.hypot(dx, dy), dz) * f
        az = math.atan2(dy, dx) if (dx or dy) else 0.0
        return FieldPoint(True, (math.sin(theta) * math.cos(az), math.sin(theta) * math.sin(az),
                                 math.cos(theta)), None)
    x, y, z = fp.point_mm
    return FieldPoint(False, None, (x * f, y * f, z))


def aim_many(lens: Lens, fps, rows, px, py, wavelength_nm, aim: str = "paraxial", to_stop: ToStop | None = None,
             geometry: PupilGeometry | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays of many field points at once: ray k from ``fps[rows[k]]`` at pupil (px[k], py[k]), wavelength
    ``wavelength_nm[k]`` (nm): (origins (n, 3), directions (n, 3), aimed (n,)).

    The same rays, bit for bit, as :func:`aim_rays` called one field point at a time, but the Newton
    iterations of every field point, pupil point and wavelength share one trace to the stop per step
    (``to_stop`` is called a few dozen times for the whole job instead of that many times per field point).
    """
    if aim not in AIM_MODES:
        raise LensrtError(f"unknown ray aiming {aim!r}", hint=f"use one of {', '.join(AIM_MODES)}")
    fps = list(fps)
    geom = pupil_geometry(lens) if geometry is None else geometry
    rows = np.atleast_1d(np.asarray(rows, dtype=np.intp))
    n = len(rows)
    px, py = (np.broadcast_to(np.atleast_1d(np.asarray(v, dtype=np.float64)), (n,)) for v in (px, py))
    wl = np.broadcast_to(np.asarray(wavelength_nm, dtype=np.float64), (n,)).copy()
    groups = [np.nonzero(rows == f)[0] for f in range(len(fps))]
    o, d, ok = np.empty((n, 3)), np.empty((n, 3)), np.ones(n, dtype=bool)
    if aim == "paraxial":
        for f, sel in enumerate(groups):
            if len(sel):
                o[sel], d[sel], ok[sel] = aim_rays(lens, fps[f], px[sel], py[sel], wl[sel], aim, geometry=geom)
        return o, d, ok
    to_stop = reference_to_stop(lens) if to_stop is None else to_stop
    frames = [_aim_frame(fp, geom) for fp in fps]
    par = np.stack([px * geom.ep_radius_mm, py * geom.ep_radius_mm, np.full(n, geom.ep_z_mm)], axis=1)
    if aim == "chief":
        return _chief_many(fps, frames, groups, wl, par, to_stop, geom)
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    e1 = np.array([fr[1] for fr in frames]).reshape(-1, 3)[rows]
    e2 = np.array([fr[2] for fr in frames]).reshape(-1, 3)[rows]
    target = np.stack([px, py], axis=1) * geom.stop_radius_mm
    ab0 = np.stack([np.sum((par - c) * e1, axis=1), np.sum((par - c) * e2, axis=1)], axis=1)
    ab, ok = _solve_many(fps, frames, rows, groups, ab0, wl, target, to_stop, geom)
    for f, sel in enumerate(groups):
        if len(sel) == 0:
            continue
        cf, e1f, e2f = frames[f]
        o[sel], d[sel] = ray_through_point(fps[f], cf + ab[sel, :1] * e1f + ab[sel, 1:2] * e2f)
        bad = sel[~ok[sel]]
        if len(bad):  # keep the paraxial aim where aiming failed
            o[bad], d[bad] = ray_through_point(fps[f], par[bad])
    return o, d, ok


def _solve_many(fps: list, frames: list, rows: np.ndarray, groups: list, ab0: np.ndarray, wl: np.ndarray,
                target: np.ndarray, to_stop: ToStop, geom: PupilGeometry) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_solve` for the rays of many field points (ray k of field ``fps[rows[k]]``), one Newton run for all."""
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    e1 = np.array([fr[1] for fr in frames]).reshape(-1, 3)[rows]
    e2 = np.array([fr[2] for fr in frames]).reshape(-1, 3)[rows]

    inf_f = np.array([fp.infinite for fp in fps], dtype=bool)
    beam = np.array([fp.direction if fp.infinite else (0.0, 0.0, 1.0) for fp in fps], dtype=np.float64).reshape(-1, 3)

    def residual(ab: np.ndarray, idx: np.ndarray):
        pts = c + ab[:, :1] * e1[idx] + ab[:, 1:2] * e2[idx]
        o, d = np.empty_like(pts), np.empty_like(pts)
        fr = rows[idx]
        inf = inf_f[fr]
        if inf.any():  # collimated beams, all fields at once: ray_through_point's arithmetic, row by row
            a, di = pts[inf], beam[fr[inf]]
            o[inf], d[inf] = a - np.sum(a * di, axis=1, keepdims=True) * di, di
        for f in np.unique(fr[~inf]):  # object points: the rays of each as ray_through_point makes them
            m = fr == f
            o[m], d[m] = ray_through_point(fps[f], pts[m])
        x, y, ok = to_stop(o, d, wl[idx])
        r = np.stack([x, y], axis=1) - target[idx]
        r[~ok] = 0.0
        return r, ok

    scale = max(geom.ep_radius_mm, geom.stop_radius_mm)
    ab, ok = _newton(residual, ab0, scale)
    for f, sel in enumerate(groups):
        if len(sel) == 0 or ok[sel].all():
            continue
        cf, e1f, e2f = frames[f]
        residual_for = _field_residuals(lambda a, cf=cf, e1f=e1f, e2f=e2f: cf + a[:, :1] * e1f + a[:, 1:2] * e2f,
                                        to_stop)
        ab[sel], ok[sel] = _continue_in_field(fps[f], ab[sel], ok[sel], wl[sel], residual_for, target[sel], scale)
    return ab, ok


def _chief_many(fps: list, frames: list, groups: list, wl: np.ndarray, par: np.ndarray, to_stop: ToStop,
                geom: PupilGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``aim="chief"`` of :func:`aim_many`: the real chief ray of every (field point, wavelength) in one solve."""
    n = len(wl)
    uniq = [np.unique(wl[sel], return_inverse=True) if len(sel) else (np.zeros(0), np.zeros(0, int))
            for sel in groups]
    crow = np.concatenate([np.full(len(uw), f, dtype=np.intp) for f, (uw, _) in enumerate(uniq)])
    cwl = np.concatenate([uw for uw, _ in uniq])
    cgroups = [np.nonzero(crow == f)[0] for f in range(len(fps))]
    zeros = np.zeros((len(crow), 2))
    ch_ab, ch_ok = _solve_many(fps, frames, crow, cgroups, zeros, cwl, zeros, to_stop, geom)
    o, d, ok = np.empty((n, 3)), np.empty((n, 3)), np.ones(n, dtype=bool)
    for f, sel in enumerate(groups):
        if len(sel) == 0:
            continue
        cf, e1f, e2f = frames[f]
        ab_f, inv = ch_ab[cgroups[f]], np.asarray(uniq[f][1]).ravel()
        chief = cf + ab_f[:, :1] * e1f + ab_f[:, 1:2] * e2f
        _, dch = ray_through_point(fps[f], chief)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(dch[:, 2] != 0.0, (geom.ep_z_mm - chief[:, 2]) / dch[:, 2], 0.0)
        chief = chief + s[:, None] * dch
        pts = chief[inv] + par[sel] - np.array([0.0, 0.0, geom.ep_z_mm])
        o[sel], d[sel] = ray_through_point(fps[f], pts)
        ok[sel] = ch_ok[cgroups[f]][inv]
    return o, d, ok
