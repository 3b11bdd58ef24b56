"""Entrance and exit pupils: paraxial against real, and the real pupil's outline seen from a field point.

Paraxial pupils are the Gaussian images of the stop (Field Guide p. 9-10,
:func:`lensrt.paraxial.first_order`). The real ones, per field point:

* position: where the real chief ray (through the centre of the real stop)
  crosses the axis in object space (entrance pupil, CODE V's ``EP DIST``) and in
  image space (exit pupil). On axis the chief ray is the axis itself; the limit
  of those crossings there is the paraxial pupil, which is reported.
* size: the real marginal rays aimed at the rim of the real stop (Px, Py =
  (0, +-1), (+-1, 0)) traced without the other apertures: in object space their
  spacing across the beam (tangential, sagittal), in image space their spacing
  on the plane z of the real exit pupil.
* outline (:func:`pupil_outline`): the boundary of the rays of a field point that
  pass *every* aperture (the vignetted pupil, cat's eyes included), found by
  bisection along 360 azimuths from the chief ray in the plane through the
  paraxial entrance-pupil centre perpendicular to the beam (the stream kernel's
  sampling plane). Its area is the beam's transmitted cross-section (mm^2); for a
  finite object the projected solid angle integral_cos(theta_obj) d(omega) the
  stream kernel estimates with Lambertian weights. The boundary rays meet the
  plane of the real exit pupil (z where the real chief ray crosses the axis in
  image space); seen from the chief ray's image point those points enclose the
  projected solid angle of the real exit pupil (sr: the area their direction
  cosines enclose), which sets the image irradiance of a Lambertian object.

The outline assumes the passing region is star-shaped about the chief ray
(true for intersections of the near-elliptical images of circular apertures);
a central obstruction is not resolved.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.frames import travel_signs
from ...prescription.model import Iris, Lens
from ...trace import RayBatch, trace
from ...trace.aiming import FieldPoint, beam_basis, pupil_geometry, ray_through_point
from ..raysets import (aim_batches, exit_pupil_point_z_mm, field_spec, object_field_point, trace64,
                      trace64_many)

__all__ = ["PupilOutline", "pupil_outline", "pupil_outlines", "RealPupils", "real_pupils", "real_pupil_jobs",
           "stop_only_lens", "physical_rim_mm",
           "pupil_frame"]


#: surfaces may touch (a stop on a vertex, cemented faces) within this much without ending each other
CONTACT_TOL_MM = 1e-6


def _first_crossing_mm(gap, r_max: float, samples: int = 2049) -> float | None:
    """Smallest r in (0, r_max] where ``gap(r)`` (the axial room between two surfaces) reaches zero."""
    r = np.linspace(0.0, r_max, samples)
    g = gap(r)
    bad = np.nonzero(~(g > -CONTACT_TOL_MM))[0]
    bad = bad[bad > 0]
    if bad.size == 0:
        return None
    lo, hi = float(r[bad[0] - 1]), float(r[bad[0]])
    for _ in range(60):  # bisection to float64 resolution of the rim
        mid = 0.5 * (lo + hi)
        if gap(np.array([mid]))[0] > -CONTACT_TOL_MM:
            lo = mid
        else:
            hi = mid
    return lo


def physical_rim_mm(lens: Lens, index: int) -> float | None:
    """The largest height at which surface ``index`` can physically be crossed by a ray, or None (no limit).

    A surface ends where it meets a neighbour: where its sag meets the sag of the surface before or after
    it across their (glass or air) gap -- the knife edge of an element, or two elements touching -- and
    where a conic stops existing (r = 1 / (|c| sqrt(1 + k))). The image surface is no neighbour. Rays beyond
    the rim would cross material that is not there, so a stop-only pupil must still respect it.
    """
    surfaces = lens.surfaces
    s = surfaces[index]
    rim = s.max_semi_diameter_mm

    def virtual(j: int) -> bool:  # a plane with the same medium on both sides (a stop or dummy surface)
        before = surfaces[j - 1].material if j > 0 else None
        return surfaces[j].is_plane and (before is None or before.is_air) and surfaces[j].material.is_air
    if virtual(index):
        return None if math.isinf(rim) else rim
    # search out to generous multiples of the aperture the lens already knows (or 1 m)
    known = [x.semi_diameter_mm for x in surfaces if x.semi_diameter_mm is not None]
    reach = min(rim, 20.0 * max(known) if known else 1000.0)
    signs = travel_signs(lens)  # after an odd number of mirrors the gap runs toward local -z
    for j in (index - 1, index + 1):
        if j < 0 or j >= len(surfaces) or virtual(j):
            continue
        a, b = (surfaces[j], s) if j < index else (s, surfaces[j])
        sign = signs[max(j, index)]
        r_max = min(reach, a.max_semi_diameter_mm, b.max_semi_diameter_mm) * (1.0 - 1e-12)
        hit = _first_crossing_mm(lambda r, a=a, b=b, sign=sign: sign * (a.thickness_mm + np.asarray(b.sag(r))
                                                                        - np.asarray(a.sag(r))), r_max)
        if hit is not None:
            rim = min(rim, hit)
    return None if math.isinf(rim) else rim


def stop_only_lens(lens: Lens) -> Lens:
    """A copy of ``lens`` whose only aperture is the stop: the unvignetted pupil.

    Every other surface keeps its physical rim (:func:`physical_rim_mm`) instead of its clear aperture: a ray
    that misses every clear aperture but the stop passes, one that would cross an element beyond the edge
    where its two faces meet does not (without the rim, such rays reach the image and inflate the pupil).
    """
    from dataclasses import replace
    surfaces = tuple(s if i == lens.stop_index else replace(s, semi_diameter_mm=physical_rim_mm(lens, i),
                                                             semi_diameter_auto=True)
                     for i, s in enumerate(lens.surfaces))
    return lens.replace(surfaces=surfaces)


def pupil_frame(lens: Lens, fp: FieldPoint) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(C, w, e1, e2): the paraxial EP centre, the beam axis and the basis of the plane perpendicular to it."""
    geom = pupil_geometry(lens)
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    if fp.infinite:
        w = np.asarray(fp.direction, dtype=np.float64)
    else:
        v = c - np.asarray(fp.point_mm, dtype=np.float64)
        w = v / np.linalg.norm(v)
    e1, e2 = beam_basis(w)
    return c, w, e1, e2


@dataclass
class PupilOutline:
    """The real (vignetted) pupil of one field point (module docstring). Lengths mm, angles rad."""

    object_value: float
    wavelength_nm: float
    clip: bool
    tracer: str
    azimuth_rad: np.ndarray
    radius_mm: np.ndarray  # boundary distance from the centre along each azimuth
    centre_ab_mm: tuple[float, float]  # interior point (the chief ray) in (e1, e2) coordinates about C
    a_mm: np.ndarray  # boundary, e1 coordinate about C
    b_mm: np.ndarray  # boundary, e2 coordinate about C
    area_mm2: float  # cross-section of the passing beam in the plane
    projected_solid_angle_sr: float | None  # finite object: integral of cos(theta_obj) d(omega); None at infinity
    exit_direction: np.ndarray  # (n, 3) image-space directions of the boundary rays
    exit_projected_solid_angle_sr: float  # the real exit pupil's, seen from the chief ray's image point
    rays: int = 0
    frame: tuple = field(default=(), repr=False)
    infinite: bool = True

    def to_dict(self, points: int = 72) -> dict:
        step = max(1, len(self.a_mm) // points)
        key, val = ("field_deg", math.degrees(self.object_value)) if self.infinite else \
            ("object_height_mm", self.object_value)
        return {key: val, "wavelength_nm": self.wavelength_nm, "clip": self.clip,
                "area_mm2": self.area_mm2, "projected_solid_angle_sr": self.projected_solid_angle_sr,
                "exit_projected_solid_angle_sr": self.exit_projected_solid_angle_sr,
                "centre_ab_mm": self.centre_ab_mm, "outline_a_mm": self.a_mm[::step],
                "outline_b_mm": self.b_mm[::step], "rays": self.rays, "tracer": self.tracer}


def _passes_kernel(lens: Lens, clip: bool, iris: Iris | None, device: str | None):
    def passes(o: np.ndarray, d: np.ndarray, wl: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = trace(lens, RayBatch(o, d, wl), "float64", device, clip=clip, iris=iris)
        return r.ok, r.direction, r.position_mm
    return passes


def _passes_reference(lens: Lens, clip: bool, iris: Iris | None):
    from ...trace.reference import trace_reference
    from ...trace.status import OK

    def passes(o: np.ndarray, d: np.ndarray, wl: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ok = np.zeros(len(o), dtype=bool)
        out, pos = np.zeros((len(o), 3)), np.zeros((len(o), 3))
        for i in range(len(o)):
            r = trace_reference(lens, o[i], d[i], wl, clip=clip, iris=iris)
            ok[i] = r.status == OK
            out[i] = (r.L, r.M, r.N)
            pos[i] = (r.x_mm, r.y_mm, r.z_mm)
        return ok, out, pos
    return passes


def _interior_point(lens: Lens, fp: FieldPoint, wl: float, c: np.ndarray, e1: np.ndarray, e2: np.ndarray, shoot,
                    device: str | None) -> tuple[float, float]:
    """A point inside the passing region when the chief ray is vignetted: the centre of the passing grid rays."""
    from ...trace.stream import pupil_box
    box = pupil_box(lens, fp, [wl], device=device, coarse=64, fine=32)
    if box.area_mm2 > 0:
        n = 24
        a = box.a0 + (np.arange(n) + 0.5) * (box.a1 - box.a0) / n
        b = box.b0 + (np.arange(n) + 0.5) * (box.b1 - box.b0) / n
        A, B = (g.ravel() for g in np.meshgrid(a, b, indexing="ij"))
        # the box's frame is the same plane through C (the stream kernel's), so (a, b) carry over
        ok = shoot(A, B)[0]
        if ok.any():
            a0, b0 = float(A[ok].mean()), float(B[ok].mean())
            if shoot(np.array([a0]), np.array([b0]))[0][0]:
                return a0, b0
            k = int(np.argmin((A[ok] - a0) ** 2 + (B[ok] - b0) ** 2))
            return float(A[ok][k]), float(B[ok][k])
    raise LensrtError("no ray of this field point passes the lens: no pupil outline")


def _azimuth_integral(per_azimuth: np.ndarray) -> float:
    """Integral over the azimuth of equally spaced samples (trapezoidal rule, periodic).

    The pupil boundary has corners (where aperture images meet), so the rule errs
    as O(dphi^2); Richardson extrapolation with every other sample removes that term.
    """
    n = len(per_azimuth)
    dphi = 2.0 * np.pi / n
    fine = float(np.sum(per_azimuth)) * dphi
    if n % 2 or n < 16:
        return fine
    coarse = float(np.sum(per_azimuth[::2])) * 2.0 * dphi
    return (4.0 * fine - coarse) / 3.0


def _shoelace(x: np.ndarray, y: np.ndarray) -> float:
    """Area of the polygon (x, y); Richardson with every other vertex for a curve sampled evenly in azimuth."""
    def area(a: np.ndarray, b: np.ndarray) -> float:
        return 0.5 * abs(float(np.dot(a, np.roll(b, -1)) - np.dot(b, np.roll(a, -1))))
    fine = area(x, y)
    if len(x) % 2 or len(x) < 16:
        return fine
    return (4.0 * fine - area(x[::2], y[::2])) / 3.0


def pupil_outline(lens: Lens, object_value: float, wavelength_nm: float | None = None, *, n_azimuth: int = 360,
                  iterations: int = 40, clip: bool = True, tracer: str = "kernel", iris: Iris | None = None,
                  device: str | None = None, radial_nodes: int = 16) -> PupilOutline:
    """The real pupil's outline and area for the field point at ``object_value`` (module docstring).

    ``tracer`` "kernel" (float64 store kernel) or "reference" (the float64 NumPy
    reference tracer, one ray at a time: the independent check).
    """
    out = pupil_outlines(lens, [object_value], wavelength_nm, n_azimuth=n_azimuth, iterations=iterations, clip=clip,
                         tracer=tracer, iris=iris, device=device, radial_nodes=radial_nodes)[0]
    if isinstance(out, LensrtError):
        raise out
    return out


#: bisection steps of a pupil outline per trace (2**_LEVELS - 1 rays per azimuth in each)
_LEVELS = 3


def pupil_outlines(lens: Lens, object_values: Sequence[float], wavelength_nm: float | None = None, *,
                   n_azimuth: int = 360, iterations: int = 40, clip: bool = True, tracer: str = "kernel",
                   iris: Iris | None = None, device: str | None = None,
                   radial_nodes: int = 16) -> list[PupilOutline | LensrtError]:
    """:func:`pupil_outline` of several field points at once, the same outlines: each bisection step traces
    the rays of every field point in one call. A field point without an outline gets, in its place, the
    :class:`LensrtError` that :func:`pupil_outline` raises for it. Outlines already traced with the same
    arguments are taken from a cache (a comparison asks for its fields' outlines twice: real pupils, then
    the exit-pupil illumination of vignetting); each outline is the same whatever else is traced beside it."""
    if tracer not in ("kernel", "reference"):
        raise LensrtError(f"unknown tracer {tracer!r}", hint="use 'kernel' or 'reference'")
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    opts = (wl, n_azimuth, iterations, clip, tracer, iris, device, radial_nodes)
    keys = [(lens, float(v)) + opts for v in object_values]
    missing = list(dict.fromkeys(k[1] for k in keys if k not in _OUTLINES))
    if missing:
        got = _traced_outlines(lens, missing, wl, n_azimuth, iterations, clip, tracer, iris, device, radial_nodes)
        if len(_OUTLINES) + len(got) > _OUTLINES_KEPT:
            _OUTLINES.clear()
        _OUTLINES.update({(lens, v) + opts: o for v, o in zip(missing, got)})
    return [_OUTLINES[k] for k in keys]


#: pupil outlines already traced, per (lens, object value, wavelength, options, device); at most _OUTLINES_KEPT kept
_OUTLINES: dict = {}
_OUTLINES_KEPT = 64


def _traced_outlines(lens: Lens, values: list[float], wl: float, n_azimuth: int, iterations: int, clip: bool,
                     tracer: str, iris: Iris | None, device: str | None, radial_nodes: int) -> list:
    """The outlines of :func:`pupil_outlines`, traced."""
    fps = [object_field_point(lens, v) for v in values]
    frames = [pupil_frame(lens, fp) for fp in fps]
    passes = _passes_kernel(lens, clip, iris, device) if tracer == "kernel" else _passes_reference(lens, clip, iris)
    rays = np.zeros(len(fps), dtype=np.int64)

    def shoot(ks: list[int], a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rays of field points ``ks`` through (a[j], b[j]) (rows of (len(ks), m)): ok, directions, positions."""
        o, d = [], []
        for j, k in enumerate(ks):
            c, _, e1, e2 = frames[k]
            oj, dj = ray_through_point(fps[k], c + a[j][:, None] * e1 + b[j][:, None] * e2)
            o.append(oj)
            d.append(dj)
            rays[k] += a.shape[1]
        ok, dirs, pos = passes(np.concatenate(o), np.concatenate(d), wl)
        m = a.shape[1]
        return ok.reshape(len(ks), m), dirs.reshape(len(ks), m, 3), pos.reshape(len(ks), m, 3)

    results: list = [None] * len(fps)
    chs = aim_batches(lens, [(fp, 0.0, 0.0, wl) for fp in fps], "real", device)
    a0, b0 = _outline_centres(lens, fps, frames, chs, wl, shoot, results, device)
    hi = np.array([[_outline_reach(lens, fp, frames[k][0], frames[k][1], a0[k], b0[k])] * n_azimuth
                   for k, fp in enumerate(fps)]).reshape(len(fps), n_azimuth)
    phi = np.linspace(0.0, 2.0 * np.pi, n_azimuth, endpoint=False)
    cos, sin = np.cos(phi), np.sin(phi)
    act = [k for k in range(len(fps)) if results[k] is None]
    for _ in range(6):  # make sure every azimuth starts outside the pupil
        if not act:
            break
        ok = shoot(act, a0[act, None] + hi[act] * cos, b0[act, None] + hi[act] * sin)[0]
        hi[act] = np.where(ok, 4.0 * hi[act], hi[act])
        act = [k for k, some in zip(act, ok.any(axis=1)) if some]
    for k in act:
        results[k] = LensrtError("rays pass the lens far outside its entrance pupil: no pupil outline",
                                 hint="give the lens clear apertures")
    live = [k for k in range(len(fps)) if results[k] is None]
    if not live:
        return results
    lo = np.zeros((len(fps), n_azimuth))
    # bisection, _LEVELS steps per trace: the 2**_LEVELS - 1 points that split [lo, hi] into equal parts are traced
    # together; the new bracket is the part where the first ray that fails lies (as bisection, step by step, finds it)
    frac = np.arange(1, 2 ** _LEVELS) / 2 ** _LEVELS
    for _ in range(-(-iterations // _LEVELS)):
        w = (hi[live] - lo[live])[:, :, None]
        pts = lo[live][:, :, None] + w * frac  # (L, n_azimuth, 2**_LEVELS - 1)
        ok = shoot(live, (a0[live, None, None] + pts * cos[:, None]).reshape(len(live), -1),
                   (b0[live, None, None] + pts * sin[:, None]).reshape(len(live), -1))[0].reshape(pts.shape)
        first_fail = np.where(ok.all(axis=2), len(frac), np.argmin(ok, axis=2))  # index of the first failing point
        below = np.take_along_axis(np.concatenate([lo[live][:, :, None], pts], axis=2), first_fail[:, :, None], 2)
        above = np.take_along_axis(np.concatenate([pts, hi[live][:, :, None]], axis=2), first_fail[:, :, None], 2)
        lo[live], hi[live] = below[:, :, 0], above[:, :, 0]
    ok, dirs, pos = shoot(live, a0[live, None] + lo[live] * cos, b0[live, None] + lo[live] * sin)
    ch_img = trace64(lens, RayBatch(np.concatenate([chs[k].origin_mm for k in live]),
                                    np.concatenate([chs[k].direction for k in live]), wl), device)
    for j, k in enumerate(live):
        try:
            results[k] = _finish_outline(lens, values[k], fps[k], frames[k], wl, clip, tracer, phi, lo[k],
                                         (float(a0[k]), float(b0[k])), ok[j], dirs[j], pos[j], int(rays[k]),
                                         ch_img, j, radial_nodes)
        except LensrtError as err:
            results[k] = err
    return results


def _outline_centres(lens: Lens, fps: list, frames: list, chs: list, wl: float, shoot, results: list,
                     device: str | None) -> tuple[np.ndarray, np.ndarray]:
    """Interior points (a0, b0) of every field point: the real chief ray's crossing of the plane, or, where
    that ray is vignetted, :func:`_interior_point` (a field point without one gets its error in ``results``)."""
    a0, b0 = np.zeros(len(fps)), np.zeros(len(fps))
    for k, (c, w, e1, e2) in enumerate(frames):
        ch = chs[k]
        t = float((c - ch.origin_mm[0]) @ w / (ch.direction[0] @ w))
        q = ch.origin_mm[0] + t * ch.direction[0] - c
        a0[k], b0[k] = float(q @ e1), float(q @ e2)
    every = list(range(len(fps)))
    passed = shoot(every, a0[:, None], b0[:, None])[0][:, 0] if every else np.zeros(0, dtype=bool)
    for k in np.nonzero(~passed)[0]:
        c, _, e1, e2 = frames[k]

        def one(a: np.ndarray, b: np.ndarray, k=int(k)):
            return tuple(x[0] for x in shoot([k], a[None, :], b[None, :]))
        try:
            a0[k], b0[k] = _interior_point(lens, fps[k], wl, c, e1, e2, one, device)
        except LensrtError as err:
            results[k] = err
    return a0, b0


def _outline_reach(lens: Lens, fp: FieldPoint, c: np.ndarray, w: np.ndarray, a0: float, b0: float) -> float:
    """A first radius about (a0, b0) that should lie outside the pupil (grown later where it does not)."""
    geom = pupil_geometry(lens)
    s1 = lens.surfaces[0]
    sd1 = s1.semi_diameter_mm if s1.semi_diameter_mm is not None else 10.0 * geom.ep_radius_mm
    hi0 = 2.0 * (sd1 + abs(geom.ep_z_mm) + math.hypot(a0, b0)) + 4.0 * geom.ep_radius_mm
    if not fp.infinite:
        dist = float((c - np.asarray(fp.point_mm)) @ w)
        hi0 *= max(1.0, dist / max(dist - abs(geom.ep_z_mm), 1e-9))
    return hi0


def _finish_outline(lens: Lens, object_value: float, fp: FieldPoint, frame: tuple, wl: float, clip: bool,
                    tracer: str, phi: np.ndarray, rho: np.ndarray, centre: tuple[float, float], ok: np.ndarray,
                    dirs: np.ndarray, pos: np.ndarray, rays: int, ch_img, row: int,
                    radial_nodes: int) -> PupilOutline:
    """The outline of one field point from its boundary radii ``rho``: area, solid angles, exit pupil."""
    c, w, e1, e2 = frame
    a0, b0 = centre
    cos, sin = np.cos(phi), np.sin(phi)
    n_azimuth = len(phi)
    area = _azimuth_integral(0.5 * rho * rho)
    solid = None
    if not fp.infinite:
        # integral of the stream kernel's Lambertian weight: cos(beam angle) (D/r)^2 cos(theta_obj) / D^2
        x, wq = np.polynomial.legendre.leggauss(radial_nodes)
        s = 0.5 * (x + 1.0)
        o = np.asarray(fp.point_mm, dtype=np.float64)
        per = np.zeros(n_azimuth)
        for k in range(n_azimuth):
            r = s * rho[k]
            p = c + (a0 + r * cos[k])[:, None] * e1 + (b0 + r * sin[k])[:, None] * e2
            v = p - o
            dist = np.linalg.norm(v, axis=1)
            u = v / dist[:, None]
            g = (u @ w) * u[:, 2] / dist ** 2
            per[k] = float(np.sum(0.5 * rho[k] * wq * g * r))
        solid = _azimuth_integral(per)
    # the real exit pupil seen from the chief ray's image point C: the boundary rays meet the plane of the
    # real exit pupil (where the chief ray crosses the axis) at X; directions C -> X span the pupil
    ex_solid = math.nan
    if ok.all() and ch_img.ok[row]:
        cpt, cdir = ch_img.position_mm[row], ch_img.direction[row]
        z_xp = exit_pupil_point_z_mm(lens, cpt, cdir, wl)
        if math.isfinite(z_xp):
            x = pos + ((z_xp - pos[:, 2]) / dirs[:, 2])[:, None] * dirs
            u = x - cpt
            u /= np.linalg.norm(u, axis=1)[:, None]
        else:  # exit pupil at infinity: the rays' own directions
            u = dirs
        ex_solid = _shoelace(u[:, 0], u[:, 1])
    return PupilOutline(float(object_value), wl, clip, tracer, phi, rho, (a0, b0), a0 + rho * cos, b0 + rho * sin,
                        area, solid, dirs, ex_solid, rays, (c, w, e1, e2), fp.infinite)


@dataclass
class RealPupils:
    """Paraxial and real pupils against field at one wavelength (module docstring). Positions z from the first
    vertex, sizes full widths (mm)."""

    wavelength_nm: float
    paraxial: dict
    object_value: np.ndarray
    labels: list[str]
    entrance_pupil_z_mm: np.ndarray
    exit_pupil_z_mm: np.ndarray
    entrance_tangential_mm: np.ndarray
    entrance_sagittal_mm: np.ndarray
    exit_tangential_mm: np.ndarray
    exit_sagittal_mm: np.ndarray
    real_working_f_number: float  # 1 / (2 n' sin U') of the real axial marginal ray
    outlines: list[PupilOutline] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"wavelength_nm": self.wavelength_nm, "paraxial": self.paraxial, "fields": self.labels,
                "entrance_pupil_z_mm": self.entrance_pupil_z_mm, "exit_pupil_z_mm": self.exit_pupil_z_mm,
                "entrance_pupil_tangential_mm": self.entrance_tangential_mm,
                "entrance_pupil_sagittal_mm": self.entrance_sagittal_mm,
                "exit_pupil_tangential_mm": self.exit_tangential_mm, "exit_pupil_sagittal_mm": self.exit_sagittal_mm,
                "real_working_f_number": self.real_working_f_number,
                "vignetted_outlines": [o.to_dict() for o in self.outlines]}


def real_pupil_jobs(lens: Lens, hy: Sequence[float], wavelength_nm: float) -> list[tuple]:
    """The rays :func:`real_pupils` aims (jobs for :func:`~lensrt.analysis.raysets.aim_batches`): per field the
    chief ray and the four stop-rim rays (+-y, +-x), then the axial marginal ray."""
    pup = np.array([[0.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 0.0], [-1.0, 0.0]])
    wl = float(wavelength_nm)
    fps = [object_field_point(lens, field_spec(lens, h).object_value) for h in hy]
    return [(fp, pup[:, 0], pup[:, 1], wl) for fp in fps] + [(object_field_point(lens, 0.0), 0.0, 1.0, wl)]


def real_pupils(lens: Lens, hy: Sequence[float], wavelength_nm: float | None = None, *, outlines: bool = True,
                n_azimuth: int = 180, device: str | None = None) -> RealPupils:
    """Paraxial against real pupils at normalised fields ``hy`` (module docstring)."""
    from ...paraxial import first_order
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fo = first_order(lens, wl)
    par = {"entrance_pupil_z_mm": fo.entrance_pupil_z_mm, "entrance_pupil_diameter_mm": fo.entrance_pupil_diameter_mm,
           "exit_pupil_z_mm": fo.exit_pupil_z_mm, "exit_pupil_diameter_mm": fo.exit_pupil_diameter_mm,
           "f_number": fo.f_number, "working_f_number": fo.working_f_number}
    specs = [field_spec(lens, h) for h in hy]
    n = len(specs)
    ep_z, xp_z = np.full(n, np.nan), np.full(n, np.nan)
    ent_t, ent_s, ex_t, ex_s = (np.full(n, np.nan) for _ in range(4))
    outs = []
    fps = [object_field_point(lens, spec.object_value) for spec in specs]
    # every field's chief and stop-rim rays and the real axial marginal ray (for the real working f-number)
    # aimed in one solve (aim_many: the rays aim_rays gives one field point at a time, bit for bit) and traced
    # in one trace
    aimed = aim_batches(lens, real_pupil_jobs(lens, hy, wl), "real", device)
    *traced, m = trace64_many(lens, aimed, device)
    for k, spec in enumerate(specs):
        fp, rays, r = fps[k], aimed[k], traced[k]
        good = r.ok & rays.aimed
        o, d = rays.origin_mm, rays.direction
        p, v = r.position_mm, r.direction
        if good[0]:  # the chief ray: pupil positions
            if abs(spec.object_value) < 1e-12:
                ep_z[k], xp_z[k] = fo.entrance_pupil_z_mm, fo.exit_pupil_z_mm
            else:
                ep_z[k] = float(o[0, 2] - o[0, 1] * d[0, 2] / d[0, 1])
                xp_z[k] = float(p[0, 2] - p[0, 1] * v[0, 2] / v[0, 1]) if abs(v[0, 1]) > 1e-12 else math.inf
        # sizes from each pair of stop-rim rays that exists (a fast wide angle's lower rim ray may miss a
        # surface's sphere off axis: that size stays NaN, the others are still reported)
        c, w, e1, e2 = pupil_frame(lens, fp)
        t = ((c - o) @ w) / (d @ w)
        q = o + t[:, None] * d - c
        tan_ok, sag_ok = bool(good[1] and good[2]), bool(good[3] and good[4])
        if tan_ok:
            ent_t[k] = abs(float((q[1] - q[2]) @ e2))
        if sag_ok:
            ent_s[k] = abs(float((q[3] - q[4]) @ e1))
        if math.isfinite(xp_z[k]):
            with np.errstate(divide="ignore", invalid="ignore"):
                x = p + ((xp_z[k] - p[:, 2]) / v[:, 2])[:, None] * v
            if tan_ok:
                ex_t[k] = abs(float(x[1, 1] - x[2, 1]))
            if sag_ok:
                ex_s[k] = abs(float(x[3, 0] - x[4, 0]))
    if outlines:
        outs = [o for o in pupil_outlines(lens, [spec.object_value for spec in specs], wl, n_azimuth=n_azimuth,
                                          device=device) if not isinstance(o, LensrtError)]
    # the real working f-number from the real axial marginal ray
    n_img = float(lens.indices(wl)[-1])
    nw = 1.0 / (2.0 * n_img * abs(float(m.direction[0, 1]))) if m.ok[0] and m.direction[0, 1] != 0 else math.nan
    return RealPupils(wl, par, np.array([s.object_value for s in specs]), [s.label for s in specs], ep_z, xp_z,
                      ent_t, ent_s, ex_t, ex_s, nw, outs)
