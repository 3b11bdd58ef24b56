"""First-order (Gaussian) data of a lens at one wavelength and object distance.

Field Guide p. 4-10, 30-31. Axial positions ``*_z_mm`` are measured from the
first vertex, +z toward the image; ``bfl_mm`` runs from the last vertex to the
rear focal point and ``ffl_mm`` is the z of the front focal point (negative
when it lies in front of the lens, as CODE V prints FFL).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from .ynu import ParaxialRay, ParaxialSystem, paraxial_system, trace_ynu

__all__ = ["FirstOrder", "first_order", "pupils", "Pupils", "entrance_pupil_diameter_mm",
           "marginal_ray", "chief_ray", "field_slope_and_height"]


@dataclass(frozen=True)
class Pupils:
    """Paraxial pupils: images of the stop (p. 9). Positions are z from the first vertex."""

    entrance_z_mm: float
    entrance_magnification: float  # stop radius / entrance-pupil radius
    exit_z_mm: float
    exit_magnification: float  # exit-pupil radius / stop radius


def pupils(system: ParaxialSystem) -> Pupils:
    """Entrance and exit pupils as paraxial images of the stop surface."""
    s, N = system.stop_index, system.n_surfaces
    front = system.matrix(0, s - 1, include_last_transfer=True) if s > 0 else np.eye(2)
    a, b = front[0]
    if abs(a) < 1e-15:
        raise LensrtError("the entrance pupil is at infinity (the stop is at a focal point of the front group)")
    z_ep = b * system.index[0] / a
    rear = system.matrix(s, N - 1)
    (ra, rb), (rc, rd) = rear
    if abs(rd) < 1e-15:
        raise LensrtError("the exit pupil is at infinity (image-space telecentric lens)")
    d = -rb * system.index[-1] / rd
    z_last = float(system.vertex_z_mm[N - 1])
    return Pupils(float(z_ep), float(a), z_last + float(d), float(1.0 / rd))


def entrance_pupil_diameter_mm(lens: Lens, system: ParaxialSystem, pup: Pupils, efl_mm: float) -> float:
    """Entrance-pupil diameter implied by the lens's aperture specification."""
    ap = lens.aperture
    if ap.kind == "epd":
        return ap.value
    if ap.kind == "image_fno":
        return abs(efl_mm) / ap.value
    if ap.kind == "float_by_stop":
        sd = lens.surfaces[lens.stop_index].semi_diameter_mm
        return 2.0 * sd / abs(pup.entrance_magnification)  # type: ignore[operator]
    # object-space NA: the marginal ray from the axial object point to the pupil edge
    n0 = system.index[0]
    dist = pup.entrance_z_mm + lens.object_distance_mm
    return 2.0 * dist * math.tan(math.asin(min(ap.value / n0, 0.999999)))


def field_slope_and_height(lens: Lens, value: float, object_distance_mm: float, ep_z_mm: float,
                           system: ParaxialSystem | None = None, epd_mm: float | None = None) -> tuple[float, float]:
    """Object-space slope u0 and surface-1 height y1 of the chief ray for a radial field ``value``.

    ``value`` is in the lens's field unit (rad or mm). Image-height fields
    are converted with a unit chief ray through ``system``.
    """
    kind = lens.fields.kind
    if kind == "angle":
        u0 = math.tan(value)
        return u0, -u0 * ep_z_mm
    if kind == "object_height":
        u0 = -value / (ep_z_mm + object_distance_mm)
        return u0, value + u0 * object_distance_mm
    # image heights: scale a unit chief ray to reach the requested paraxial image height
    assert system is not None
    if math.isinf(object_distance_mm):
        u_unit, y_unit = 1e-3, -1e-3 * ep_z_mm
    else:
        u_unit = -1.0 / (ep_z_mm + object_distance_mm)
        y_unit = 1.0 + u_unit * object_distance_mm
    ray = trace_ynu(system, y_unit, u_unit)
    img_z = _image_plane_offset(lens, system, object_distance_mm, ep_z_mm, epd_mm)
    h = ray.y[-2] + img_z * ray.u[-1]
    scale = value / h if h != 0 else 0.0
    return u_unit * scale, y_unit * scale


def _image_plane_offset(lens: Lens, system: ParaxialSystem, object_distance_mm: float, ep_z_mm: float,
                        epd_mm: float | None) -> float:
    """Distance from the last vertex to the paraxial image plane."""
    m = marginal_ray(system, object_distance_mm, ep_z_mm, 1.0 if epd_mm is None else epd_mm)
    if m.u[-1] == 0.0:
        raise LensrtError("the image is at infinity (afocal system at this object distance)")
    return -m.y[-2] / m.u[-1]


def marginal_ray(system: ParaxialSystem, object_distance_mm: float, ep_z_mm: float, epd_mm: float) -> ParaxialRay:
    """Paraxial marginal ray: from the axial object point to the edge of the entrance pupil."""
    r = 0.5 * epd_mm
    if math.isinf(object_distance_mm):
        return trace_ynu(system, r, 0.0)
    u0 = r / (ep_z_mm + object_distance_mm)
    return trace_ynu(system, u0 * object_distance_mm, u0)


def chief_ray(lens: Lens, system: ParaxialSystem, value: float, object_distance_mm: float, ep_z_mm: float,
              epd_mm: float) -> ParaxialRay:
    """Paraxial chief ray for a radial field ``value`` (through the centre of the entrance pupil)."""
    u0, y1 = field_slope_and_height(lens, value, object_distance_mm, ep_z_mm, system, epd_mm)
    return trace_ynu(system, y1, u0)


@dataclass(frozen=True)
class FirstOrder:
    """Gaussian data of a lens; see the module docstring for positions and signs."""

    wavelength_nm: float
    object_distance_mm: float | None  # None = infinity
    efl_mm: float
    front_focal_length_mm: float
    rear_focal_length_mm: float
    bfl_mm: float
    ffl_mm: float
    front_focal_z_mm: float
    rear_focal_z_mm: float
    front_principal_z_mm: float
    rear_principal_z_mm: float
    front_nodal_z_mm: float
    rear_nodal_z_mm: float
    entrance_pupil_z_mm: float
    entrance_pupil_diameter_mm: float
    exit_pupil_z_mm: float
    exit_pupil_diameter_mm: float
    stop_semi_diameter_mm: float
    pupil_magnification: float
    f_number: float
    working_f_number: float
    image_z_mm: float
    magnification: float
    lagrange_invariant: float
    petzval_sum_per_mm: float
    total_track_mm: float
    half_field_deg: float
    paraxial_image_height_mm: float

    def to_dict(self) -> dict:
        return asdict(self)


def first_order(lens: Lens, wavelength_nm: float | None = None,
                object_distance_mm: float | None = None) -> FirstOrder:
    """First-order data of ``lens`` at ``wavelength_nm`` (default: primary) and object distance.

    ``object_distance_mm`` (from the first vertex; ``inf`` allowed) defaults
    to the lens's own. The entrance-pupil diameter follows the lens's
    aperture specification at this wavelength.
    """
    sysm = paraxial_system(lens, wavelength_nm)
    d_obj = lens.object_distance_mm if object_distance_mm is None else float(object_distance_mm)
    N = sysm.n_surfaces
    n0, nk = float(sysm.index[0]), float(sysm.index[-1])
    full = sysm.matrix(0, N - 1)
    (A, B), (C, D) = full
    phi = -C
    if abs(phi) < 1e-15:
        raise LensrtError("the lens has no power (afocal): first-order data are undefined")
    efl = 1.0 / phi
    f_front, f_rear = n0 / phi, nk / phi
    z = sysm.vertex_z_mm
    z_last = float(z[N - 1])
    bfl = A * nk / phi
    front_focal_z = -D * n0 / phi
    rear_focal_z = z_last + bfl
    front_principal_z = front_focal_z + f_front
    rear_principal_z = rear_focal_z - f_rear
    pup = pupils(sysm)
    epd = entrance_pupil_diameter_mm(lens, sysm, pup, efl)
    stop_sd = 0.5 * epd * abs(pup.entrance_magnification)
    xpd = 2.0 * stop_sd * abs(pup.exit_magnification)
    mp = xpd / epd
    m_ray = marginal_ray(sysm, d_obj, pup.entrance_z_mm, epd)
    if m_ray.u[-1] == 0.0:
        raise LensrtError("the image is at infinity at this object distance")
    image_offset = -m_ray.y[N - 1] / m_ray.u[-1]
    image_z = z_last + image_offset
    if math.isinf(d_obj):
        mag = 0.0
    else:
        mag = float(m_ray.nu[0] / m_ray.nu[-1])
    f_number = efl / epd
    bellows = 1.0 + abs(mag) / mp
    fmax = lens.fields.max_radial
    c_ray = chief_ray(lens, sysm, fmax, d_obj, pup.entrance_z_mm, epd)
    h_img = float(c_ray.y[N - 1] + image_offset * c_ray.u[-1])
    lagrange = float(n0 * (c_ray.u[0] * m_ray.y[0] - m_ray.u[0] * c_ray.y[0]))
    petzval = float(np.sum(sysm.power_per_mm / (sysm.index[:-1] * sysm.index[1:])))
    half_field = math.degrees(math.atan(abs(c_ray.u[0]))) if lens.fields.kind != "angle" else math.degrees(fmax)
    return FirstOrder(
        wavelength_nm=sysm.wavelength_nm,
        object_distance_mm=None if math.isinf(d_obj) else d_obj,
        efl_mm=efl, front_focal_length_mm=f_front, rear_focal_length_mm=f_rear,
        bfl_mm=bfl, ffl_mm=front_focal_z, front_focal_z_mm=front_focal_z, rear_focal_z_mm=rear_focal_z,
        front_principal_z_mm=front_principal_z, rear_principal_z_mm=rear_principal_z,
        front_nodal_z_mm=front_focal_z + f_rear, rear_nodal_z_mm=rear_focal_z - f_front,
        entrance_pupil_z_mm=pup.entrance_z_mm, entrance_pupil_diameter_mm=epd,
        exit_pupil_z_mm=pup.exit_z_mm, exit_pupil_diameter_mm=xpd, stop_semi_diameter_mm=stop_sd,
        pupil_magnification=mp, f_number=f_number, working_f_number=bellows * f_number,
        image_z_mm=image_z, magnification=mag, lagrange_invariant=lagrange, petzval_sum_per_mm=petzval,
        total_track_mm=lens.image_z_mm, half_field_deg=half_field, paraxial_image_height_mm=h_img,
    )
