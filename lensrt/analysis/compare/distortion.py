"""Image height and distortion: the real chief ray against the paraxial image (Field Guide p. 11).

Distortion is a change of magnification with field: the real chief ray lands
closer to the axis than the paraxial image (barrel, negative) or farther out
(pincushion, positive). Two definitions are computed side by side:

``"paraxial"`` (the textbook one, lensrt's default)
    D = (y_real - y_par) / y_par, with y_real the real chief ray's height on
    the *paraxial image plane* and y_par the paraxial chief ray's height there
    (f tan(theta) for an object at infinity, m h for an object at distance).

``"codev"`` (what CODE V prints as DISTORTION in its ``ssp`` ray listing)
    D = (y_real(IMG) - y_ref) / y_ref with y_real(IMG) the real chief ray on
    the image surface IMG and the reference height carried from the paraxial
    image plane to IMG along the real chief ray:
    y_ref = y_par + (z_IMG - z_par) tan(U'), U' the real chief ray's exit angle.
    The numerator equals the textbook one (the displacement measured in the
    paraxial image plane); only the denominator moves with the image surface.
    The two agree when the image surface is the paraxial image plane. This
    definition is *inferred*, not documented: it reproduces the CODE V double
    Gauss listing (-0.4976 % and -1.0557 % at 10 and 14 deg, image surface
    0.400269 mm inside the paraxial focus) to all printed digits with no free
    parameter, where the textbook definition gives -0.4959 % and -1.0522 %.
    No CODE V manual text defining it was found.

For fisheyes a paraxial (f tan theta) height does not exist at and beyond
90 degrees; the real height is then compared with the usual fisheye mappings
(:data:`MAPPINGS`, f the paraxial front focal length): equidistant f theta
(the "f-theta" lens), equisolid 2 f sin(theta/2), stereographic 2 f tan(theta/2)
and orthographic f sin(theta).

The chief ray is the real one (aimed at the centre of the real stop); heights
are signed along the field azimuth (+y for a positive angle at infinity).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...trace import RayBatch
from ..raysets import chief_batch, field_spec, object_field_point, paraxial_chief, trace64

__all__ = ["DISTORTION_DEFINITIONS", "MAPPINGS", "DistortionCurve", "GridDistortion", "distortion_curve",
           "grid_distortion", "grid_object_values", "mapping_height_mm", "DEFINITION_TEXT"]

DISTORTION_DEFINITIONS = ("paraxial", "codev")
#: fisheye (and rectilinear) mappings: name -> height / f as a function of theta (rad)
MAPPINGS = {
    "rectilinear": lambda t: np.where(np.abs(t) < 0.5 * np.pi, np.tan(t), np.nan),
    "equidistant": lambda t: t,
    "equisolid": lambda t: 2.0 * np.sin(0.5 * t),
    "stereographic": lambda t: 2.0 * np.tan(0.5 * t),
    "orthographic": lambda t: np.where(np.abs(t) <= 0.5 * np.pi, np.sin(t), np.nan),
}
DEFINITION_TEXT = {
    "paraxial": "100 (y_real - y_par) / y_par: real chief ray height on the paraxial image plane against the "
                "paraxial chief ray height there (f tan theta at infinity)",
    "codev": "CODE V ssp DISTORTION (inferred): 100 (y_real(IMG) - y_ref) / y_ref with y_ref = y_par + "
             "(z_IMG - z_par) tan U', U' the real chief ray's exit angle; equals 'paraxial' when the image "
             "surface is the paraxial image plane",
}


def mapping_height_mm(name: str, theta_rad: np.ndarray, focal_length_mm: float) -> np.ndarray:
    """Image height (mm) of mapping ``name`` (:data:`MAPPINGS`) at field angles ``theta_rad``."""
    if name not in MAPPINGS:
        raise LensrtError(f"unknown mapping {name!r}", hint=f"use one of {', '.join(MAPPINGS)}")
    with np.errstate(invalid="ignore"):
        return focal_length_mm * MAPPINGS[name](np.asarray(theta_rad, dtype=np.float64))


def _percent(num: np.ndarray, den: np.ndarray, at_axis: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 100.0 * num / den
    return np.where(at_axis, 0.0, d)


@dataclass
class DistortionCurve:
    """Chief-ray image heights and distortion against field at one wavelength.

    Arrays have one entry per field point; NaN where a quantity does not exist
    (no paraxial height at 90 deg and beyond, a chief ray that could not be traced:
    see ``valid``). The distortion at the axis is 0 (the limit).
    """

    wavelength_nm: float
    infinite: bool
    hy: np.ndarray  # normalised field
    field_value: np.ndarray  # lens field unit (rad or mm)
    object_value: np.ndarray  # rad (infinite object) or mm
    focal_length_mm: float  # paraxial front focal length f = n/Phi (mappings)
    paraxial_image_z_mm: float
    image_z_mm: float
    paraxial_height_mm: np.ndarray  # paraxial chief ray on the paraxial image plane
    real_height_mm: np.ndarray  # real chief ray on the paraxial image plane
    real_height_image_mm: np.ndarray  # real chief ray on the image surface
    exit_tangent: np.ndarray  # tan U' of the real chief ray (dy/dz in image space)
    valid: np.ndarray
    distortion_percent: np.ndarray  # "paraxial" definition
    distortion_codev_percent: np.ndarray  # "codev" definition
    mapping_height_mm: dict[str, np.ndarray] = field(default_factory=dict)
    mapping_distortion_percent: dict[str, np.ndarray] = field(default_factory=dict)

    def distortion(self, definition: str = "paraxial") -> np.ndarray:
        """Distortion (%) by ``definition`` in :data:`DISTORTION_DEFINITIONS`."""
        if definition not in DISTORTION_DEFINITIONS:
            raise LensrtError(f"unknown distortion definition {definition!r}",
                              hint=f"use one of {', '.join(DISTORTION_DEFINITIONS)}")
        return self.distortion_percent if definition == "paraxial" else self.distortion_codev_percent

    def closest_mapping(self) -> str | None:
        """The mapping of :data:`MAPPINGS` the real image heights follow best (RMS relative difference over the
        traced field points); only mappings defined at all of them compete. None if the object is not at infinity."""
        use = self.valid & (np.abs(self.object_value) > 0)
        best, err = None, math.inf
        for name, h in self.mapping_height_mm.items():
            if use.sum() < 1 or not np.all(np.isfinite(h[use])):
                continue
            e = float(np.sqrt(np.mean((self.real_height_image_mm[use] / h[use] - 1.0) ** 2)))
            if e < err:
                best, err = name, e
        return best

    def to_dict(self) -> dict:
        d = {"wavelength_nm": self.wavelength_nm, "focal_length_mm": self.focal_length_mm,
             "paraxial_image_z_mm": self.paraxial_image_z_mm, "image_z_mm": self.image_z_mm,
             "hy": self.hy, ("field_deg" if self.infinite else "field_mm"):
                 np.degrees(self.object_value) if self.infinite else self.object_value,
             "paraxial_height_mm": self.paraxial_height_mm, "real_height_mm": self.real_height_mm,
             "real_height_image_surface_mm": self.real_height_image_mm,
             "chief_exit_angle_deg": np.degrees(np.arctan(self.exit_tangent)),
             "distortion_percent": self.distortion_percent, "distortion_codev_percent": self.distortion_codev_percent,
             "definitions": DEFINITION_TEXT}
        if self.infinite:
            d.update({f"{k}_height_mm": v for k, v in self.mapping_height_mm.items()})
            d.update({f"{k}_distortion_percent": v for k, v in self.mapping_distortion_percent.items()})
            d["closest_mapping"] = self.closest_mapping()
        return d


def distortion_curve(lens: Lens, hy: Sequence[float] | np.ndarray | None = None, wavelength_nm: float | None = None,
                     device: str | None = None, object_values: Sequence[float] | None = None,
                     chief: RayBatch | None = None, traced=None) -> DistortionCurve:
    """Chief-ray heights and distortion (both definitions, module docstring) at field points.

    Parameters
    ----------
    lens : Lens
    hy : array, optional
        Normalised fields (default 21 points from 0 to 1).
    wavelength_nm : float, optional
        Default: the primary; the paraxial image plane is this wavelength's.
    device : str, optional
        Warp device for the float64 store kernel.
    chief : RayBatch, optional
        The real chief rays of these field points at this wavelength, when the caller aimed them already
        (:func:`lensrt.analysis.raysets.chief_batches`).
    object_values : array, optional
        Object-space field values (rad at infinity, else mm) instead of ``hy``.
    traced : RayResult, optional
        ``chief`` already traced to the image surface (:func:`~lensrt.analysis.raysets.trace64`, no apertures),
        e.g. with other wavelengths' rays in one launch.
    """
    from ...paraxial import first_order
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fo = first_order(lens, wl)
    infinite = fo.object_distance_mm is None
    if object_values is None:
        hs = np.linspace(0.0, 1.0, 21) if hy is None else np.asarray(hy, dtype=np.float64)
        obj = np.array([field_spec(lens, h).object_value for h in hs])
    else:
        obj = np.asarray(object_values, dtype=np.float64)
        hs = np.full(len(obj), np.nan)
    fps = [object_field_point(lens, float(v)) for v in obj]
    chief = chief_batch(lens, fps, wl, device) if chief is None else chief
    res = trace64(lens, chief, device) if traced is None else traced
    valid = res.ok & chief.aimed
    z_img, z_par = lens.image_z_mm, fo.image_z_mm
    v = res.direction
    with np.errstate(divide="ignore", invalid="ignore"):
        tan_u = v[:, 1] / v[:, 2]
    y_img = np.where(valid, res.position_mm[:, 1], np.nan)
    tan_u = np.where(valid, tan_u, np.nan)
    y_real = y_img + (z_par - z_img) * tan_u
    y_par = np.array([paraxial_chief(lens, fo, float(o))[0] for o in obj])
    axis = np.abs(obj) < 1e-15
    dist = _percent(y_real - y_par, y_par, axis)
    y_ref = y_par + (z_img - z_par) * tan_u
    dist_cv = _percent(y_img - y_ref, y_ref, axis)
    maps, map_d = {}, {}
    f = abs(fo.front_focal_length_mm)
    if infinite:
        for name in MAPPINGS:
            h = mapping_height_mm(name, obj, f)
            maps[name] = h
            map_d[name] = _percent(y_img - h, h, axis)
    fvals = hs * lens.fields.max_radial
    return DistortionCurve(wl, infinite, hs, fvals, obj, f, z_par, z_img, y_par, y_real, y_img, tan_u, valid,
                           dist, dist_cv, maps, map_d)


@dataclass
class GridDistortion:
    """Real chief-ray image points of a square grid of ideal image points (mm).

    ``ideal_*`` are the points the ``mapping`` puts on a square grid; ``real_*`` where the
    real chief rays of those object points land on the plane ``plane_z_mm``;
    ``distortion_percent`` the radial departure 100 (|r_real| - |r_ideal|) / |r_ideal|.
    """

    wavelength_nm: float
    mapping: str
    plane_z_mm: float
    ideal_x_mm: np.ndarray
    ideal_y_mm: np.ndarray
    real_x_mm: np.ndarray
    real_y_mm: np.ndarray
    valid: np.ndarray
    distortion_percent: np.ndarray

    @property
    def max_abs_distortion_percent(self) -> float:
        d = self.distortion_percent[self.valid]
        return float(np.max(np.abs(d))) if d.size else math.nan

    def to_dict(self) -> dict:
        return {"wavelength_nm": self.wavelength_nm, "mapping": self.mapping, "plane_z_mm": self.plane_z_mm,
                "ideal_x_mm": self.ideal_x_mm, "ideal_y_mm": self.ideal_y_mm, "real_x_mm": self.real_x_mm,
                "real_y_mm": self.real_y_mm, "distortion_percent": self.distortion_percent,
                "max_abs_distortion_percent": self.max_abs_distortion_percent}


def grid_object_values(lens: Lens, n: int = 11, wavelength_nm: float | None = None,
                       mapping: str | None = None) -> np.ndarray:
    """The object-space field values (rad at infinity, else mm) whose real chief rays :func:`grid_distortion`
    traces: one per distinct ideal radius of its n x n grid."""
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    return _grid(lens, n, wl, mapping)[-1]


def _grid(lens: Lens, n: int, wl: float, mapping: str | None) -> tuple:
    """(first order, mapping, gx, gy, r, index of each point's radius, object value of each radius) of
    :func:`grid_distortion`'s grid."""
    from ...paraxial import first_order
    if n < 2:
        raise LensrtError("a distortion grid needs at least 2 x 2 points")
    fo = first_order(lens, wl)
    infinite = fo.object_distance_mm is None
    obj_max = field_spec(lens, 1.0).object_value
    if mapping is None:
        mapping = "equidistant" if infinite and obj_max > math.radians(60.0) else "rectilinear"
    f = abs(fo.front_focal_length_mm)
    # ideal radius at the largest field, then a square grid whose corners reach it
    if infinite:
        r_max = float(mapping_height_mm(mapping, np.array([obj_max]), f)[0])
    else:
        if mapping != "rectilinear":
            raise LensrtError("fisheye mappings need an object at infinity")
        r_max = abs(paraxial_chief(lens, fo, obj_max)[0])
    if not math.isfinite(r_max) or r_max <= 0:
        raise LensrtError(f"the {mapping} mapping has no image height at the largest field",
                          hint="use mapping='equidistant' for fields at or beyond 90 deg")
    g = np.linspace(-1.0, 1.0, n) * r_max / math.sqrt(2.0)
    gx, gy = np.meshgrid(g, g, indexing="xy")
    r = np.hypot(gx, gy)
    radii, inv = np.unique(np.round(r, 12), return_inverse=True)
    inv = inv.reshape(r.shape)
    # object values of each distinct ideal radius (inverse of the mapping)
    if infinite:
        t = np.linspace(0.0, obj_max * 1.02, 4097)
        h = mapping_height_mm(mapping, t, f)
        obj = np.interp(radii, h, t)
    else:
        m = paraxial_chief(lens, fo, 1.0)[0]  # image height per mm of object height
        obj = radii / abs(m)
    return fo, mapping, gx, gy, r, inv, obj


def grid_distortion(lens: Lens, n: int = 11, wavelength_nm: float | None = None, device: str | None = None,
                    mapping: str | None = None, plane: str = "paraxial") -> GridDistortion:
    """Grid distortion: an n x n square of ideal image points whose corners reach the largest field.

    ``mapping`` is the undistorted reference ("rectilinear" = the paraxial image,
    or a fisheye mapping of :data:`MAPPINGS`; default rectilinear, equidistant
    when the largest field angle exceeds 60 deg). Real points are on the paraxial
    image plane (``plane="paraxial"``) or the image surface (``"image"``). The
    lens is rotationally symmetric, so the chief rays are traced once per distinct
    radius along +y and rotated to each point's azimuth.
    """
    if plane not in ("paraxial", "image"):
        raise LensrtError(f"unknown plane {plane!r}", hint="use 'paraxial' or 'image'")
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fo, mapping, gx, gy, r, inv, obj = _grid(lens, n, wl, mapping)
    curve = distortion_curve(lens, wavelength_nm=wl, device=device, object_values=obj)
    h_real = curve.real_height_mm if plane == "paraxial" else curve.real_height_image_mm
    h_real = np.abs(h_real)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux, uy = np.where(r > 0, gx / r, 0.0), np.where(r > 0, gy / r, 0.0)
    rr = h_real[inv]
    real_x, real_y = rr * ux, rr * uy
    valid = curve.valid[inv]
    d = _percent(rr - r, r, r < 1e-12)
    z = fo.image_z_mm if plane == "paraxial" else lens.image_z_mm
    return GridDistortion(wl, mapping, z, gx, gy, real_x, real_y, valid, d)
