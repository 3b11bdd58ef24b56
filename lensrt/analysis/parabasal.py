"""First-order data from real rays about the chief ray: the parabasal picture of a decentred or tilted lens.

A lens whose surfaces are tilted or decentred has no optical axis, so the
y-nu trace of :mod:`lensrt.paraxial.first_order` (which unfolds the axis)
is exact only for fold mirrors that are tilted flats. CODE V and OpticStudio
give such systems first-order data from *real* rays instead: a base ray --
the chief ray of the central field, aimed at the centre of the stop -- and
rays infinitesimally close to it (parabasal rays). Their differences obey a
linear law, the 4x4 parabasal system matrix

    (x', y', u', v') = M (x, y, u, v)

where (x, y) are the offsets of a neighbouring ray from the base ray in the
plane normal to it (object space: through the object point, or for an object
at infinity through the base ray's hit on surface 1; image space: through its
hit on the last surface) and (u, v) the slopes of the neighbour relative to
the base ray (direction tangents in that frame). lensrt builds ``M`` by
central differences of float64 real rays
(:func:`lensrt.trace.reference.trace_reference`; steps 1e-4 mm and 1e-6 rad, the
angle step cut to 1e-4 mm over the object distance for a finite object;
truncation ~(step/f)^2, rounding ~1e-10 relative) and reads the Gaussian
quantities off it, in the y-z section (y-ray into y', v') and the x-z
section (x into x', u') separately, with the same signs as the y-nu trace
(Field Guide p. 3-4: ``n'u' = n u - y Phi``):

* object at infinity: ``efl = -1 / (n' dv'/dy)``, back focal distance
  ``-dy'/dy / (dv'/dy)`` along the base ray from its hit on the last surface;
* finite object: magnification ``n / (n' dv'/dv)`` (a ray leaving the object
  point), image distance ``-dy'/dv / (dv'/dv)``;
* pupils: the neighbour through the stop centre (offset chosen so its stop
  intercept does not move) crosses the base ray at the entrance pupil (object
  space) and the exit pupil (image space); pupil magnification ``n/(n' v')``.

Signs after mirrors follow the y-nu trace: the image-space frame's z is the
base ray's direction, reversed after an odd number of mirrors (light travels
toward -z there and ``n'`` is negative), its x the object-space x axis carried
along the base ray (at each surface the component normal to the plane of
incidence is kept, the in-plane one turns with the ray), so that a flat fold
mirror tilted about any axis does not rotate the sections. For a rotationally symmetric lens the base ray is the axis and every
number equals the y-nu trace's (``tests/analysis/test_parabasal.py``: 1e-8
relative).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import LensrtError
from ..paraxial.first_order import first_order
from ..prescription.frames import surface_frames, travel_signs
from ..prescription.model import Lens
from ..trace.reference import trace_reference
from ..trace.status import OK

__all__ = ["ParabasalFirstOrder", "parabasal_first_order", "FIRST_ORDER_METHOD"]

#: the label lensrt puts on first-order data computed here
FIRST_ORDER_METHOD = "real-ray parabasal about chief ray"
_STEP_MM = 1e-4
_STEP_RAD = 1e-6


@dataclass(frozen=True)
class ParabasalFirstOrder:
    """Gaussian data from rays about the central field's chief ray (module docstring); lengths in mm.

    ``*_y`` is the y-z section, ``*_x`` the x-z section. Distances run along
    the base ray: ``bfl`` / ``image_distance`` / ``exit_pupil_distance`` from
    its hit on the last surface, ``entrance_pupil_distance`` from its hit on
    surface 1. What does not apply is ``inf`` (the back focal distance and
    f-number of a finite object, the focal data of an afocal section; ``None``
    in JSON via ``to_dict``) or 0 (the magnification of an object at infinity).
    The entrance-pupil diameter is the lens's aperture specification as
    :func:`lensrt.paraxial.first_order` reads it (for an f-number aperture:
    from the y-nu focal length of the unfolded axis).
    """

    method: str
    wavelength_nm: float
    efl_y_mm: float
    efl_x_mm: float
    bfl_y_mm: float
    bfl_x_mm: float
    f_number_y: float
    f_number_x: float
    magnification_y: float
    magnification_x: float
    image_distance_y_mm: float
    image_distance_x_mm: float
    entrance_pupil_distance_mm: float
    exit_pupil_distance_mm: float
    pupil_magnification: float
    entrance_pupil_diameter_mm: float
    exit_pupil_diameter_mm: float
    #: the x-y coupling of the matrix (largest off-section term relative to the in-section one): 0 for a lens
    #: with a plane of symmetry containing y (tilts about x, decenters in y)
    coupling: float
    chief_ray_origin_mm: tuple[float, float, float]  # a global point of the base ray in object space
    chief_ray_direction: tuple[float, float, float]  # its global direction cosines in object space
    chief_ray_image_point_mm: tuple[float, float, float]  # global hit of the base ray on the image surface
    chief_ray_image_direction: tuple[float, float, float]  # global direction cosines in image space
    system_matrix: tuple[tuple[float, ...], ...]  # M, rows (x', y', u', v'), columns (x, y, u, v)

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def _ratio(num: float, den: float) -> float:
    """num / den, or a signed inf where den vanishes (an afocal section: focal lengths beyond 1e12 mm)."""
    if abs(den) < 1e-12 * max(abs(num), 1e-300):
        return math.copysign(math.inf, num) * (1.0 if den >= 0.0 else -1.0)
    return float(num / den)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


class _Rays:
    """The base ray, its transverse frames and the traced neighbours (one lens, one wavelength)."""

    def __init__(self, lens: Lens, wavelength_nm: float) -> None:
        self.lens, self.wl = lens, wavelength_nm
        self.frames = surface_frames(lens)
        self.sign_img = travel_signs(lens)[-1]
        n = lens.indices(wavelength_nm)
        self.n_obj, self.n_img = float(n[0]), float(n[-1]) * self.sign_img
        self.infinite = math.isinf(lens.object_distance_mm)
        self.k0 = np.array([0.0, 0.0, 1.0])
        self.p0 = np.zeros(3) if self.infinite else np.array([0.0, 0.0, -lens.object_distance_mm])
        self.ex0, self.ey0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
        # slope steps move the ray at the lens by no more than the offset step (truncation ~ step^2)
        self.step_rad = _STEP_RAD if self.infinite else min(_STEP_RAD, _STEP_MM / lens.object_distance_mm)

    def ray(self, q: np.ndarray) -> tuple[tuple, tuple]:
        """Origin and direction of the neighbour q = (x, y, u, v) of the base ray."""
        o = self.p0 + q[0] * self.ex0 + q[1] * self.ey0
        d = self.k0 + q[2] * self.ex0 + q[3] * self.ey0
        return tuple(o), tuple(d / np.linalg.norm(d))

    def trace(self, q: np.ndarray, end: int | None = None):
        o, d = self.ray(q)
        r = trace_reference(self.lens, o, d, self.wl, clip=False, end=end)
        if r.status != OK:
            raise LensrtError(f"the parabasal trace about the chief ray failed at surface {r.surface + 1} "
                              f"(status {r.status})", hint="the central field's chief ray must pass the lens")
        return r

    def hit_global(self, r, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Global point and direction of ray ``r`` at its hit on surface ``i`` (local frame -> global)."""
        h = r.hits[i]
        o, a = self.frames[i]
        return o + a @ np.array([h.x_mm, h.y_mm, h.z_mm]), a @ np.array([h.L, h.M, h.N])

    def aim(self) -> None:
        """Aim the base ray at the stop centre (Newton on the free pair: offsets at infinity, else slopes)."""
        stop = self.lens.stop_index
        free = (0, 1) if self.infinite else (2, 3)
        q = np.zeros(4)
        for _ in range(30):
            h = self.trace(q, end=stop).hits[-1]
            s = np.array([h.x_mm, h.y_mm])
            if np.abs(s).max() < 1e-12:
                break
            jac = np.empty((2, 2))
            for c, k in enumerate(free):
                step = _STEP_MM if k < 2 else self.step_rad
                dq = np.zeros(4)
                dq[k] = step
                hp, hm = self.trace(q + dq, end=stop).hits[-1], self.trace(q - dq, end=stop).hits[-1]
                jac[:, c] = [(hp.x_mm - hm.x_mm) / (2 * step), (hp.y_mm - hm.y_mm) / (2 * step)]
            q[list(free)] -= np.linalg.solve(jac, s)
        else:
            raise LensrtError("the chief ray of the central field could not be aimed at the stop centre",
                              hint="check that the stop is reachable from the object")
        o, d = self.ray(q)
        self.k0 = np.array(d)
        self.ex0 = _unit(np.array([1.0, 0.0, 0.0]) - self.k0[0] * self.k0)
        self.ey0 = np.cross(self.k0, self.ex0)
        self.p0 = np.array(o)
        base = self.trace(np.zeros(4))
        if self.infinite:  # the object-space reference plane goes through the base ray's hit on surface 1
            self.p0 = self.hit_global(base, 0)[0]
            base = self.trace(np.zeros(4))
        self.p_img, k_img = self.hit_global(base, self.lens.n_surfaces - 1)
        self.k_img = k_img
        self.ez1 = self.sign_img * k_img
        ax = self.transported_x(base)
        self.ex1 = _unit(ax - (ax @ self.ez1) * self.ez1)
        self.ey1 = np.cross(self.ez1, self.ex1)
        self.base = base

    def transported_x(self, base) -> np.ndarray:
        """The object-space x axis carried along the base ray to image space: at each surface the component
        normal to the plane of incidence (s) is kept and the in-plane one (q = d x s) turns with the ray
        (a refraction: a rotation about s) or is mirrored with it (a reflection: e - 2 (e.n) n, q -> -q')."""
        e, d_in = self.ex0.copy(), self.k0
        for i, surf in enumerate(self.lens.surfaces):
            d_out = self.hit_global(base, i)[1]
            s = np.cross(d_in, d_out)
            if np.linalg.norm(s) > 1e-14:  # the ray turned: move e with it (else e stays normal to it)
                s = _unit(s)
                q_sign = -1.0 if surf.mirror else 1.0
                e = (e @ s) * s + q_sign * (e @ np.cross(d_in, s)) * np.cross(d_out, s)
            d_in = d_out  # (normal incidence on a mirror, d_out = -d_in: e is its own mirror image)
        return e

    def image_state(self, r) -> np.ndarray:
        """(x', y', u', v') of ray ``r`` about the base ray, image-space reference plane."""
        p, d = self.hit_global(r, self.lens.n_surfaces - 1)
        t = ((self.p_img - p) @ self.ez1) / (d @ self.ez1)
        q = p + t * d - self.p_img
        dz = d @ self.ez1
        return np.array([q @ self.ex1, q @ self.ey1, (d @ self.ex1) / dz, (d @ self.ey1) / dz])

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """M (4x4: image state per unit object state) and S (2x4: stop intercept per unit object state)."""
        m, s = np.empty((4, 4)), np.empty((2, 4))
        stop = self.lens.stop_index
        for k in range(4):
            step = _STEP_MM if k < 2 else self.step_rad
            dq = np.zeros(4)
            dq[k] = step
            rp, rm = self.trace(dq), self.trace(-dq)
            m[:, k] = (self.image_state(rp) - self.image_state(rm)) / (2 * step)
            hp, hm = rp.hits[stop], rm.hits[stop]
            s[:, k] = [(hp.x_mm - hm.x_mm) / (2 * step), (hp.y_mm - hm.y_mm) / (2 * step)]
        return m, s


def parabasal_first_order(lens: Lens, wavelength_nm: float | None = None,
                          object_distance_mm: float | None = None) -> ParabasalFirstOrder:
    """First-order data of ``lens`` from parabasal rays about the central field's chief ray.

    Parameters
    ----------
    lens : Lens
        Any lens the float64 reference tracer traces (tilts, decenters, mirrors).
    wavelength_nm : float, optional
        Wavelength (nm); default the lens's primary wavelength.
    object_distance_mm : float, optional
        Object plane to the first vertex (mm, ``inf`` allowed); default the lens's own.

    Returns
    -------
    ParabasalFirstOrder
        See the module docstring for the definitions and signs.
    """
    wl = float(lens.wavelengths.nm[lens.wavelengths.primary] if wavelength_nm is None else wavelength_nm)
    if object_distance_mm is not None:
        lens = dataclasses.replace(lens, object_distance_mm=float(object_distance_mm))
    rays = _Rays(lens, wl)
    rays.aim()
    m, s = rays.matrices()
    n0, n1 = rays.n_obj, rays.n_img
    inf = math.inf
    X, Y, U, V = 0, 1, 2, 3
    efl_y, efl_x = _ratio(-1.0, n1 * m[V, Y]), _ratio(-1.0, n1 * m[U, X])
    if rays.infinite:
        bfl_y, bfl_x = _ratio(-m[Y, Y], m[V, Y]), _ratio(-m[X, X], m[U, X])
        mag_y = mag_x = 0.0
        img_y, img_x = bfl_y, bfl_x
    else:
        bfl_y = bfl_x = inf
        mag_y, mag_x = _ratio(n0, n1 * m[V, V]), _ratio(n0, n1 * m[U, U])
        img_y, img_x = _ratio(-m[Y, V], m[V, V]), _ratio(-m[X, U], m[U, U])
    # the neighbour through the stop centre with unit slope v: offsets that keep the stop intercept still
    dxy = np.linalg.solve(s[:, :2], -s[:, V])
    w = np.array([dxy[0], dxy[1], 0.0, 1.0])
    out = m @ w
    ep = -dxy[1] - (0.0 if rays.infinite else float(np.linalg.norm(rays.hit_global(rays.base, 0)[0] - rays.p0)))
    xp = _ratio(-out[Y], out[V])
    mp = _ratio(n0, n1 * out[V])
    epd = first_order(lens, wl).entrance_pupil_diameter_mm
    # x-y coupling: the largest term linking the x-z and y-z sections over the largest within them, offsets
    # measured in entrance-pupil diameters so that lengths and slopes weigh alike
    scale = np.array([epd, epd, 1.0, 1.0])
    md = np.abs(m * scale[None, :] / scale[:, None])
    xs, ys = [X, U], [Y, V]
    within = max(md[np.ix_(xs, xs)].max(), md[np.ix_(ys, ys)].max())
    coupling = max(md[np.ix_(xs, ys)].max(), md[np.ix_(ys, xs)].max()) / within
    img_pt, img_dir = rays.hit_global(rays.base, lens.n_surfaces)
    return ParabasalFirstOrder(
        method=FIRST_ORDER_METHOD, wavelength_nm=wl, efl_y_mm=float(efl_y), efl_x_mm=float(efl_x),
        bfl_y_mm=float(bfl_y), bfl_x_mm=float(bfl_x),
        f_number_y=abs(n0 * efl_y) / epd if rays.infinite else inf,
        f_number_x=abs(n0 * efl_x) / epd if rays.infinite else inf,
        magnification_y=float(mag_y), magnification_x=float(mag_x),
        image_distance_y_mm=float(img_y), image_distance_x_mm=float(img_x),
        entrance_pupil_distance_mm=float(ep), exit_pupil_distance_mm=float(xp), pupil_magnification=float(mp),
        entrance_pupil_diameter_mm=float(epd), exit_pupil_diameter_mm=float(epd * abs(mp)),
        coupling=float(coupling), chief_ray_origin_mm=tuple(float(v) for v in rays.p0),
        chief_ray_direction=tuple(float(v) for v in rays.k0), chief_ray_image_point_mm=tuple(float(v) for v in img_pt),
        chief_ray_image_direction=tuple(float(v) for v in img_dir),
        system_matrix=tuple(tuple(float(v) for v in row) for row in m))
