"""First-order (Gaussian) data of a lens at one wavelength and object distance.

Field Guide p. 2-10, 17, 30-31. Axial positions ``*_z_mm`` are measured from the
first vertex, +z toward the image. ``bfl_mm`` runs from the last vertex to the
rear focal point F'; ``ffl_mm`` is the z of the front focal point F (negative
when F lies in front of the lens, as CODE V prints FFL).

Focal lengths (p. 6): the effective focal length is f_E = 1/Phi, the front and
rear effective focal lengths are f = n/Phi and f' = n'/Phi, with n the
object-space and n' the image-space index (f = f' = f_E for a lens in air).
The f-number is N = f/D (p. 30) with D the entrance-pupil diameter; with the
front focal length in it the camera equation E = (pi/4) L T / N^2 holds in any
media. The pupil distances of p. 10 use the Field Guide's signs: s_EP runs from
the front principal plane P to the entrance pupil, positive toward the object;
s'_XP from the rear principal plane P' to the exit pupil, positive toward the
image. They equal (1 - 1/mp) f and (1 - mp) f', because the pupils are
conjugate through the whole lens with magnification mp.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..core.keep import kept
from ..errors import LensrtError
from ..prescription.model import Lens
from .ynu import ParaxialRay, ParaxialSystem, paraxial_system, trace_ynu

__all__ = ["FirstOrder", "first_order", "is_afocal", "refuse_afocal", "pupils", "Pupils", "entrance_pupil_diameter_mm",
           "marginal_ray", "chief_ray", "field_slope_and_height", "paraxial_rays"]

#: a matrix element below this (relative) counts as zero: a pupil or image at infinity
_TINY = 1e-15
#: an image farther than this many focal lengths from the last vertex is at infinity
_IMAGE_AT_INFINITY = 1e9


@dataclass(frozen=True)
class Pupils:
    """Paraxial pupils: images of the stop (p. 9). Positions are z from the first vertex.

    ``exit_z_mm`` and ``exit_magnification`` are ``inf`` for an image-space
    telecentric lens (exit pupil at infinity).
    """

    entrance_z_mm: float
    entrance_magnification: float  # stop radius / entrance-pupil radius (signed)
    exit_z_mm: float
    exit_magnification: float  # exit-pupil radius / stop radius (signed)

    @property
    def pupil_magnification_signed(self) -> float:
        """Lateral magnification from the entrance to the exit pupil (signed)."""
        return self.exit_magnification / self.entrance_magnification


def pupils(system: ParaxialSystem) -> Pupils:
    """Entrance and exit pupils as paraxial images of the stop surface."""
    s, N = system.stop_index, system.n_surfaces
    front = system.matrix(0, s - 1, include_last_transfer=True) if s > 0 else np.eye(2)
    a, b = front[0]
    if abs(a) < _TINY * max(1.0, abs(b)):
        raise LensrtError("the entrance pupil is at infinity (the stop is at the rear focal point of the "
                          "group in front of it: an object-space telecentric lens)",
                          hint="lensrt's first-order data need a finite entrance pupil")
    z_ep = b * system.index[0] / a
    rear = system.matrix(s, N - 1)
    (ra, rb), (rc, rd) = rear
    z_last = float(system.vertex_z_mm[N - 1])
    if abs(rd) < _TINY * max(1.0, abs(rb)):
        return Pupils(float(z_ep), float(a), math.inf, math.inf)
    d = -rb * system.index[-1] / rd
    return Pupils(float(z_ep), float(a), z_last + float(d), float(1.0 / rd))


def entrance_pupil_diameter_mm(lens: Lens, system: ParaxialSystem, pup: Pupils, efl_mm: float,
                               object_distance_mm: float | None = None) -> float:
    """Entrance-pupil diameter (mm) implied by the lens's aperture specification.

    ``image_fno`` gives D = f/N with f = n/Phi the front focal length (so that
    N = f/D holds, p. 30); ``object_na`` the pupil that the axial object point at
    ``object_distance_mm`` (default: the lens's own) sees under that NA.
    """
    ap = lens.aperture
    if ap.kind == "epd":
        return ap.value
    if ap.kind == "image_fno":
        return abs(system.index[0] * efl_mm) / ap.value
    if ap.kind == "float_by_stop":
        sd = lens.surfaces[lens.stop_index].semi_diameter_mm
        return 2.0 * sd / abs(pup.entrance_magnification)  # type: ignore[operator]
    d = lens.object_distance_mm if object_distance_mm is None else object_distance_mm
    if math.isinf(d):
        raise LensrtError("the aperture is an object-space NA but the object is at infinity",
                          hint="give a finite object distance, or an entrance-pupil diameter")
    n0 = system.index[0]
    dist = pup.entrance_z_mm + d
    return 2.0 * dist * math.tan(math.asin(min(ap.value / n0, 0.999999)))


def field_slope_and_height(lens: Lens, value: float, object_distance_mm: float, ep_z_mm: float,
                           system: ParaxialSystem | None = None, epd_mm: float | None = None) -> tuple[float, float]:
    """Object-space slope u0 and surface-1 height y1 of the chief ray for a radial field ``value``.

    ``value`` is in the lens's field unit (rad for angles, mm for heights).
    Angles give u0 = tan(angle) (CODE V's and OpticStudio's paraxial chief ray);
    object heights a ray from the object point to the entrance-pupil centre;
    image heights are reached by scaling a unit chief ray traced through
    ``system`` to the paraxial image plane.
    """
    kind = lens.fields.kind
    if kind == "angle":
        u0 = math.tan(value)
        return u0, -u0 * ep_z_mm
    if kind == "object_height":
        if math.isinf(object_distance_mm):
            raise LensrtError("fields are object heights but the object is at infinity",
                              hint="use field angles, or give a finite object distance")
        u0 = -value / (ep_z_mm + object_distance_mm)
        return u0, value + u0 * object_distance_mm
    # image heights: scale a unit chief ray to reach the requested paraxial image height
    if system is None:
        system = paraxial_system(lens)
    if math.isinf(object_distance_mm):
        u_unit, y_unit = 1e-3, -1e-3 * ep_z_mm
    else:
        u_unit = -1.0 / (ep_z_mm + object_distance_mm)
        y_unit = 1.0 + u_unit * object_distance_mm
    ray = trace_ynu(system, y_unit, u_unit)
    m = marginal_ray(system, object_distance_mm, ep_z_mm, 1.0 if epd_mm is None else epd_mm)
    img = m.axis_crossing_mm()
    if math.isinf(img):
        raise LensrtError("the image is at infinity (afocal at this object distance): image-height fields "
                          "are undefined")
    h = ray.height_at(img)
    if h == 0.0:
        raise LensrtError("the chief ray does not reach the image plane off axis: image-height fields "
                          "are undefined for this lens")
    scale = value / h
    return u_unit * scale, y_unit * scale


def marginal_ray(system: ParaxialSystem, object_distance_mm: float, ep_z_mm: float, epd_mm: float) -> ParaxialRay:
    """Paraxial marginal ray: from the axial object point to the top of the entrance pupil.

    For an object at infinity: parallel to the axis at height D/2.
    """
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


def paraxial_rays(lens: Lens, wavelength_nm: float | None = None, object_distance_mm: float | None = None,
                  field: float | None = None) -> tuple[ParaxialRay, ParaxialRay, ParaxialSystem]:
    """Marginal and chief rays (full aperture, full field by default) and the system they went through.

    ``field`` is a radial field value in the lens's field unit (default: the
    largest field). These are the rays of CODE V's ``fio`` table.
    """
    sysm = paraxial_system(lens, wavelength_nm)
    d_obj = lens.object_distance_mm if object_distance_mm is None else float(object_distance_mm)
    pup = pupils(sysm)
    phi = _power(sysm)
    epd = entrance_pupil_diameter_mm(lens, sysm, pup, 1.0 / phi, d_obj)
    m = marginal_ray(sysm, d_obj, pup.entrance_z_mm, epd)
    fval = lens.fields.max_radial if field is None else float(field)
    c = chief_ray(lens, sysm, fval, d_obj, pup.entrance_z_mm, epd)
    return m, c, sysm


def _power(system: ParaxialSystem) -> float:
    phi = -float(system.matrix(0, system.n_surfaces - 1)[1, 0])
    if is_afocal(system):
        raise LensrtError("the lens has no power (afocal): focal lengths and image positions are undefined",
                          hint="first_order() reports its angular magnification and pupils")
    return phi


def _petzval_sum(lens: Lens, sysm: ParaxialSystem) -> float:
    """sum Phi / (n n') over the surfaces; an ideal paraxial lens (flat-field, perfect) adds nothing."""
    real = np.array([not s.is_ideal for s in lens.surfaces])
    return float(np.sum((sysm.power_per_mm / (sysm.index[:-1] * sysm.index[1:]))[real]))


def refuse_afocal(lens: Lens, what: str, wavelength_nm: float | None = None) -> None:
    """Raise one clear :class:`LensrtError` when ``lens`` is afocal: ``what`` (an analysis) needs an image.

    An afocal lens (a telescope, a beam expander) sends every object point at infinity to infinity: its
    image lies in angle space, and analyses on an image plane (focus, distortion, spots, PSFs, bokeh) are
    not defined there.
    """
    sysm = paraxial_system(lens, wavelength_nm)
    if not is_afocal(sysm):
        return
    m = float(sysm.matrix(0, sysm.n_surfaces - 1)[1, 1]) * float(sysm.index[0] / sysm.index[-1])
    raise LensrtError(f"{what} needs an image, but the lens is afocal (angular magnification {m:.6g}): its image "
                      "lies at infinity, in angle space",
                      hint="lensrt info gives its angular magnification and pupils; to image it, add an ideal lens "
                           "behind it (ideal_focal_mm, or TYPE PARAXIAL in a Zemax file)")


def is_afocal(system: ParaxialSystem) -> bool:
    """True when the system's power vanishes (a telescope, or a plate): no focal points."""
    return abs(float(system.matrix(0, system.n_surfaces - 1)[1, 0])) < 1e-15


@dataclass(frozen=True)
class FirstOrder:
    """Gaussian data of a lens; see the module docstring for positions and signs.

    Lengths in mm, ``*_z_mm`` from the first vertex; infinite quantities are
    ``inf`` (``None`` for the object distance at infinity) and become ``null``
    in JSON.
    """

    wavelength_nm: float
    object_distance_mm: float | None  # from the object to the first vertex; None = infinity
    object_z_mm: float | None  # z of the object plane (= -object_distance_mm)
    efl_mm: float  # f_E = 1/Phi
    front_focal_length_mm: float  # f = n/Phi
    rear_focal_length_mm: float  # f' = n'/Phi
    bfl_mm: float  # last vertex -> F'
    ffl_mm: float  # first vertex -> F (= front_focal_z_mm)
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
    stop_semi_diameter_mm: float  # the stop radius the aperture specification implies
    pupil_magnification: float  # mp = D_XP / D
    entrance_pupil_distance_mm: float  # s_EP: P -> EP, + toward the object (p. 10)
    exit_pupil_distance_mm: float  # s'_XP: P' -> XP, + toward the image (p. 10)
    f_number: float  # N = f / D (p. 30)
    bellows_factor: float  # b = 1 + |m| / mp (p. 31)
    working_f_number: float  # Nw = b N
    image_z_mm: float  # paraxial image of the object plane
    image_distance_mm: float  # last vertex -> paraxial image (< 0: a virtual image)
    image_surface_distance_mm: float  # last vertex -> the lens's image surface (CODE V IMG DIS)
    unit_focus_extension_mm: float  # paraxial image z - F' z: the extension e of a unit-focusing lens (p. 12)
    magnification: float  # m = n u / (n' u') of the marginal ray; 0 at infinity
    lagrange_invariant: float  # H = n (u_c y_m - u_m y_c), mm (full aperture and field)
    petzval_sum_per_mm: float  # sum Phi_i / (n_i n'_i)
    overall_length_mm: float  # first -> last vertex (CODE V OAL)
    total_track_mm: float  # first vertex -> image surface
    half_field_deg: float  # largest object-space half field angle (chief-ray slope for heights)
    paraxial_image_height_mm: float  # at the largest field, in the paraxial image plane
    field_image_heights_mm: tuple[float, ...]  # at each field point (radial), paraxial image plane
    #: the image-space rays diverge: the paraxial image lies in front of the last vertex (behind it, along
    #: the direction light travels, after an odd number of mirrors) (an object
    #: inside the front focal point of a positive lens -- a magnifier); the lens's image surface then
    #: receives a blur, not an image
    image_virtual: bool = False
    #: the lens has no power (a telescope or a plate): focal lengths, focal and principal points, the image
    #: and the f-number are inf; ``angular_magnification`` (u'/u of a ray, n u' = D n u with the system
    #: matrix's D) and the pupils are what it has
    afocal: bool = False
    angular_magnification: float | None = None
    #: the lens has tilts/decenters: these are the paraxial data of its unfolded axis (exact for fold
    #: mirrors that are tilted flats, not for genuinely decentred systems)
    unfolded_axis: bool = False

    def to_dict(self) -> dict:
        return asdict(self)


def first_order(lens: Lens, wavelength_nm: float | None = None,
                object_distance_mm: float | None = None) -> FirstOrder:
    """First-order data of ``lens`` at ``wavelength_nm`` (default: primary) and object distance.

    Parameters
    ----------
    lens : Lens
    wavelength_nm : float, optional
        Wavelength (nm) for the indices; default the lens's primary wavelength.
    object_distance_mm : float, optional
        Distance from the object plane to the first vertex (mm; ``inf``
        allowed); default the lens's own.

    Notes
    -----
    The entrance-pupil diameter follows the lens's aperture specification at
    this wavelength and object distance; the image is the paraxial image of the
    object plane (the lens's image surface is not moved: ``image_surface_distance_mm``
    keeps the file's last thickness). Results are kept per (lens, wavelength, object distance) in this
    process (a report asks for the same ones in many analyses; :class:`FirstOrder` is immutable).
    """
    try:
        key = (lens, None if wavelength_nm is None else float(wavelength_nm),
               None if object_distance_mm is None else float(object_distance_mm))
    except (TypeError, ValueError):  # an unusual argument: computed (and refused) as it is
        return _first_order(lens, wavelength_nm, object_distance_mm)
    return kept(_KNOWN, key, lambda: _first_order(lens, wavelength_nm, object_distance_mm), _KNOWN_KEPT)


#: first-order data already found, per (lens, wavelength or None, object distance or None); at most _KNOWN_KEPT
_KNOWN: dict = {}
_KNOWN_KEPT = 512


def _first_order(lens: Lens, wavelength_nm: float | None, object_distance_mm: float | None) -> FirstOrder:
    """:func:`first_order`, computed."""
    sysm = paraxial_system(lens, wavelength_nm)
    d_obj = lens.object_distance_mm if object_distance_mm is None else float(object_distance_mm)
    if math.isnan(d_obj) or d_obj <= 0.0:
        raise LensrtError(f"object distance {d_obj!r} mm must be positive (inf for an object at infinity)")
    if is_afocal(sysm):
        return _afocal_first_order(lens, sysm, d_obj)
    N = sysm.n_surfaces
    n0, nk = float(sysm.index[0]), float(sysm.index[-1])
    (A, B), (C, D) = sysm.matrix(0, N - 1)
    phi = _power(sysm)
    efl = 1.0 / phi
    f_front, f_rear = n0 / phi, nk / phi
    z_last = float(sysm.vertex_z_mm[N - 1])
    # Cardinal points (p. 4-6): F' from a ray parallel in object space, F from one parallel in image space.
    bfl = A * nk / phi
    front_focal_z = -D * n0 / phi
    rear_focal_z = z_last + bfl
    front_principal_z = front_focal_z + f_front
    rear_principal_z = rear_focal_z - f_rear
    # Pupils (p. 9-10): images of the stop; mp = D_XP / D.
    pup = pupils(sysm)
    epd = entrance_pupil_diameter_mm(lens, sysm, pup, efl, d_obj)
    stop_sd = 0.5 * epd * abs(pup.entrance_magnification)
    xpd = 2.0 * stop_sd * abs(pup.exit_magnification)
    mp = xpd / epd
    # Object at distance d_obj: marginal ray from the axial object point to the EP's edge.
    m_ray = marginal_ray(sysm, d_obj, pup.entrance_z_mm, epd)
    image_offset = m_ray.axis_crossing_mm()
    # an object at (or within rounding of) the front focal point images to infinity: rounding leaves
    # a finite but meaningless image distance (1e17 mm), so anything beyond 1e9 focal lengths is infinity
    if (math.isinf(image_offset) or abs(image_offset) > _IMAGE_AT_INFINITY * abs(efl)) and math.isinf(d_obj):
        raise LensrtError(f"an object at infinity has no finite image: the image lies {image_offset:.4g} mm behind "
                          f"the last vertex, more than 1e9 focal lengths (EFL {efl:.4g} mm)",
                          hint="check the radii and thicknesses")
    if math.isinf(image_offset) or abs(image_offset) > _IMAGE_AT_INFINITY * abs(efl):
        raise LensrtError(f"the image is at infinity at this object distance ({d_obj:g} mm: the object is at the "
                          f"front focal point, z = {front_focal_z:g} mm)",
                          hint="move the object away from the front focal point")
    image_z = z_last + image_offset
    mag = 0.0 if math.isinf(d_obj) else float(m_ray.nu[0] / m_ray.nu[-1])
    f_number = abs(f_front) / epd
    bellows = 1.0 + abs(mag) / mp
    # Chief rays of every field point; the largest gives the Lagrange invariant.
    radial = [math.hypot(x, y) for x, y in zip(lens.fields.x, lens.fields.y)]
    heights = []
    for v in radial:
        c = chief_ray(lens, sysm, v, d_obj, pup.entrance_z_mm, epd)
        heights.append(c.height_at(image_offset))
    fmax = lens.fields.max_radial
    c_ray = chief_ray(lens, sysm, fmax, d_obj, pup.entrance_z_mm, epd)
    h_img = c_ray.height_at(image_offset)
    lagrange = float(n0 * (c_ray.u[0] * m_ray.y[0] - m_ray.u[0] * c_ray.y[0]))
    petzval = _petzval_sum(lens, sysm)
    half_field = math.degrees(fmax) if lens.fields.kind == "angle" else math.degrees(math.atan(abs(c_ray.u[0])))
    return FirstOrder(
        wavelength_nm=sysm.wavelength_nm,
        object_distance_mm=None if math.isinf(d_obj) else d_obj,
        object_z_mm=None if math.isinf(d_obj) else -d_obj,
        efl_mm=efl, front_focal_length_mm=f_front, rear_focal_length_mm=f_rear,
        bfl_mm=bfl, ffl_mm=front_focal_z, front_focal_z_mm=front_focal_z, rear_focal_z_mm=rear_focal_z,
        front_principal_z_mm=front_principal_z, rear_principal_z_mm=rear_principal_z,
        front_nodal_z_mm=front_focal_z + f_rear, rear_nodal_z_mm=rear_focal_z - f_front,
        entrance_pupil_z_mm=pup.entrance_z_mm, entrance_pupil_diameter_mm=epd,
        exit_pupil_z_mm=pup.exit_z_mm, exit_pupil_diameter_mm=xpd, stop_semi_diameter_mm=stop_sd,
        pupil_magnification=mp,
        entrance_pupil_distance_mm=front_principal_z - pup.entrance_z_mm,
        exit_pupil_distance_mm=pup.exit_z_mm - rear_principal_z,
        f_number=f_number, bellows_factor=bellows, working_f_number=bellows * f_number,
        image_z_mm=image_z, image_distance_mm=image_offset,
        image_surface_distance_mm=float(lens.surfaces[-1].thickness_mm),
        unit_focus_extension_mm=image_z - rear_focal_z,
        magnification=mag, lagrange_invariant=lagrange, petzval_sum_per_mm=petzval,
        overall_length_mm=lens.length_mm, total_track_mm=lens.image_z_mm,
        half_field_deg=half_field, paraxial_image_height_mm=h_img,
        field_image_heights_mm=tuple(float(h) for h in heights),
        image_virtual=bool(image_offset * math.copysign(1.0, nk) < 0.0), unfolded_axis=_has_transforms(lens),
    )


def _afocal_first_order(lens: Lens, sysm: ParaxialSystem, d_obj: float) -> FirstOrder:
    """First-order data of an afocal lens: pupils and angular magnification; focal quantities inf; the image of
    a finite object (finite: lateral magnification 1/M), inf for an object at infinity."""
    if lens.aperture.kind == "image_fno":
        raise LensrtError("the lens is afocal: an f-number aperture is undefined",
                          hint="give the entrance-pupil diameter (EPD / ENPD) instead")
    if lens.fields.kind in ("paraxial_image_height", "real_image_height"):
        raise LensrtError("the lens is afocal: image-height fields are undefined", hint="use field angles")
    N = sysm.n_surfaces
    n0, nk = float(sysm.index[0]), float(sysm.index[-1])
    D = float(sysm.matrix(0, N - 1)[1, 1])
    inf = math.inf
    pup = pupils(sysm)
    epd = entrance_pupil_diameter_mm(lens, sysm, pup, inf, d_obj)
    stop_sd = 0.5 * epd * abs(pup.entrance_magnification)
    xpd = 2.0 * stop_sd * abs(pup.exit_magnification)
    m_ray = marginal_ray(sysm, d_obj, pup.entrance_z_mm, epd)
    fmax = lens.fields.max_radial
    c_ray = chief_ray(lens, sysm, fmax, d_obj, pup.entrance_z_mm, epd)
    lagrange = float(n0 * (c_ray.u[0] * m_ray.y[0] - m_ray.u[0] * c_ray.y[0]))
    petzval = _petzval_sum(lens, sysm)
    half_field = math.degrees(fmax) if lens.fields.kind == "angle" else math.degrees(math.atan(abs(c_ray.u[0])))
    # a finite object has a finite image (lateral magnification n u / (n' u') = 1 / M for every object distance)
    image_offset, mag, heights, virtual = inf, 0.0, tuple(inf for _ in lens.fields.y), False
    if math.isfinite(d_obj):
        image_offset = m_ray.axis_crossing_mm()
        mag = float(m_ray.nu[0] / m_ray.nu[-1])
        heights = tuple(float(chief_ray(lens, sysm, math.hypot(x, y), d_obj, pup.entrance_z_mm, epd)
                              .height_at(image_offset)) for x, y in zip(lens.fields.x, lens.fields.y))
        virtual = bool(image_offset * math.copysign(1.0, nk) < 0.0)
    z_last = float(sysm.vertex_z_mm[N - 1])
    return FirstOrder(
        wavelength_nm=sysm.wavelength_nm, object_distance_mm=None if math.isinf(d_obj) else d_obj,
        object_z_mm=None if math.isinf(d_obj) else -d_obj, efl_mm=inf, front_focal_length_mm=inf,
        rear_focal_length_mm=inf, bfl_mm=inf, ffl_mm=-inf, front_focal_z_mm=-inf, rear_focal_z_mm=inf,
        front_principal_z_mm=inf, rear_principal_z_mm=inf, front_nodal_z_mm=inf, rear_nodal_z_mm=inf,
        entrance_pupil_z_mm=pup.entrance_z_mm, entrance_pupil_diameter_mm=epd, exit_pupil_z_mm=pup.exit_z_mm,
        exit_pupil_diameter_mm=xpd, stop_semi_diameter_mm=stop_sd, pupil_magnification=xpd / epd,
        entrance_pupil_distance_mm=inf, exit_pupil_distance_mm=inf, f_number=inf, bellows_factor=1.0,
        working_f_number=inf, image_z_mm=z_last + image_offset, image_distance_mm=image_offset,
        image_surface_distance_mm=float(lens.surfaces[-1].thickness_mm), unit_focus_extension_mm=0.0,
        magnification=mag, lagrange_invariant=lagrange, petzval_sum_per_mm=petzval,
        overall_length_mm=lens.length_mm, total_track_mm=lens.image_z_mm, half_field_deg=half_field,
        paraxial_image_height_mm=float(c_ray.height_at(image_offset)) if math.isfinite(image_offset) else inf,
        field_image_heights_mm=heights, image_virtual=virtual,
        afocal=True, angular_magnification=D * n0 / nk, unfolded_axis=_has_transforms(lens))


def _has_transforms(lens: Lens) -> bool:
    """True when a surface or the image surface changes frame (tilts/decenters); centred obscurations keep
    the lens rotationally symmetric and its paraxial data exact."""
    return lens.image_transform is not None or any(s.transform_before is not None or s.transform_after is not None
                                                   for s in lens.surfaces)
