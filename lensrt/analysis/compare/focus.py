"""Focal lengths and foci: paraxial against real.

* :func:`real_focal_length` -- the real EFL of a ray parallel to the axis at height h,
  f(h) = -h / (n' sin U') (Abbe's sine condition form; f(h) -> 1/Phi as h -> 0 with
  an O(h^2) difference, the offence against the sine condition), and the
  *equivalent* focal length from the real chief ray's image height at a small
  angle, f_eq = y'(theta) / (n tan theta) (-> n/Phi with an O(theta^2) difference:
  distortion).
* :func:`longitudinal_aberration` -- where real rays of each pupil zone cross the
  axis against the paraxial focus (Field Guide p. 11, 26): LSA(rho) = z(rho) -
  z_par. LSA < 0 at the margin (marginal rays focus before the paraxial focus)
  is *under-corrected* spherical aberration (the simple positive lens), LSA > 0
  *over-corrected*. Per wavelength against the primary's paraxial focus, so the
  curves also show axial colour.
* :func:`best_focus` -- the image plane of minimum RMS spot radius about the
  centroid, for a uniformly filled real pupil (a deterministic square grid of
  rays over the real, vignetted pupil, equal weights). Each ray is a straight
  line in image space, so the mean square radius is a quadratic in the plane's z
  and its minimum is found in closed form.
* :func:`chromatic_focal_shift` -- paraxial focus against wavelength (and the real
  best focus at given wavelengths), both from the primary's paraxial focus.
* :func:`field_curvature` -- sagittal and tangential foci against field from close
  rays about the real chief ray (the Coddington foci, O(delta^2)), measured along z
  as CODE V's X-FOCUS / Y-FOCUS and OpticStudio's field curvature plot; the
  Petzval surface z_P = z_par + c_P y'^2 / 2 (c_P = -n' sum Phi/(n n'), CODE V's
  PTZ sum) and the third-order (Seidel) sagittal and tangential surfaces
  z = z_par - (SAS, TAS) / u' (y'/y'_max)^2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...trace import RayBatch
from ...trace.focus import BEST_FOCUS_DEFINITION, best_focus_plane, focus_moments_many
from ..raysets import (aim_batch, axis_crossing_z, chief_batch, close_ray_batch, field_spec, meridional_intersection_z, object_field_point, paraxial_chief, plane_crossing_z, trace64, trace64_many)

__all__ = ["FocalLength", "real_focal_length", "real_focal_lengths", "LongitudinalAberration",
           "longitudinal_aberration", "BestFocus",
           "best_focus", "ChromaticFocalShift", "chromatic_focal_shift", "FieldCurvature", "field_curvature",
           "BEST_FOCUS_DEFINITION", "correction_name", "small_field_value"]



def correction_name(lsa_marginal_mm: float, tolerance_mm: float = 0.0) -> str:
    """'under-corrected' (LSA < 0), 'over-corrected' (LSA > 0) or 'corrected' (|LSA| <= tolerance)."""
    if abs(lsa_marginal_mm) <= tolerance_mm:
        return "corrected"
    return "under-corrected" if lsa_marginal_mm < 0 else "over-corrected"


@dataclass
class FocalLength:
    """Paraxial and real focal lengths at one wavelength (mm)."""

    wavelength_nm: float
    paraxial_efl_mm: float  # 1 / Phi
    ray_height_mm: np.ndarray  # h of the parallel rays
    real_efl_mm: np.ndarray  # -h / (n' sin U') per height
    near_axis_height_mm: float
    real_efl_near_axis_mm: float
    small_angle_rad: float | None
    equivalent_focal_length_mm: float | None  # y'(theta) / (n tan theta) at a small angle (object at infinity)
    paraxial_front_focal_length_mm: float
    paraxial_magnification: float | None = None  # finite object: paraxial m
    real_magnification: float | None = None  # finite object: y'/h of the real chief ray at a small object height
    small_object_height_mm: float | None = None

    def to_dict(self) -> dict:
        return {"wavelength_nm": self.wavelength_nm, "paraxial_efl_mm": self.paraxial_efl_mm,
                "near_axis_ray_height_mm": self.near_axis_height_mm,
                "real_efl_near_axis_mm": self.real_efl_near_axis_mm,
                "real_efl_mm_by_ray_height": {"ray_height_mm": self.ray_height_mm, "real_efl_mm": self.real_efl_mm},
                "small_field_angle_deg": None if self.small_angle_rad is None else math.degrees(self.small_angle_rad),
                "equivalent_focal_length_mm": self.equivalent_focal_length_mm,
                "paraxial_front_focal_length_mm": self.paraxial_front_focal_length_mm,
                "paraxial_magnification": self.paraxial_magnification, "real_magnification": self.real_magnification,
                "small_object_height_mm": self.small_object_height_mm}


def real_focal_length(lens: Lens, wavelength_nm: float | None = None, heights_mm: Sequence[float] | None = None,
                      near_axis_fraction: float = 1e-3, small_angle_fraction: float = 1e-3,
                      device: str | None = None) -> FocalLength:
    """Real EFL from rays parallel to the axis, and the equivalent focal length from a small-angle image height.

    ``heights_mm`` default: 11 heights from 0.1 to 1 x the entrance-pupil radius;
    the near-axis value uses ``near_axis_fraction`` x r_EP and the equivalent focal
    length ``small_angle_fraction`` x the largest field angle (object at infinity only).
    """
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    return real_focal_lengths(lens, [wl], heights_mm, near_axis_fraction, small_angle_fraction, device)[0]


def small_field_value(lens: Lens, small_angle_fraction: float = 1e-3) -> float | None:
    """The small field (object-space value: rad at infinity, else mm) whose real chief ray
    :func:`real_focal_lengths` traces for the equivalent focal length; None for a lens without a field."""
    if lens.fields.max_radial <= 0:
        return None
    return small_angle_fraction * max(field_spec(lens, 1.0).object_value, 1e-3)


def real_focal_lengths(lens: Lens, wavelengths_nm: Sequence[float], heights_mm: Sequence[float] | None = None,
                       near_axis_fraction: float = 1e-3, small_angle_fraction: float = 1e-3,
                       device: str | None = None) -> list[FocalLength]:
    """:func:`real_focal_length` at several wavelengths, the same results: the parallel rays of every
    wavelength in one trace, the small-field chief ray of every wavelength in one aiming run."""
    from ...paraxial import first_order
    from ..raysets import chief_batches, trace64_many
    wls = [float(w) for w in wavelengths_nm]
    fos = [first_order(lens, wl) for wl in wls]
    heights, batches = [], []
    for wl, fo in zip(wls, fos):
        try:  # an EFL belongs to infinite conjugates: the entrance pupil there sets the heights
            r_ep = 0.5 * first_order(lens, wl, math.inf).entrance_pupil_diameter_mm
        except LensrtError:
            r_ep = 0.5 * fo.entrance_pupil_diameter_mm
        h = np.linspace(0.1, 1.0, 10) * r_ep if heights_mm is None else np.asarray(heights_mm, dtype=np.float64)
        h_all = np.concatenate([[near_axis_fraction * r_ep], h])
        n = len(h_all)
        heights.append((h, h_all))
        batches.append(RayBatch(np.column_stack([np.zeros(n), h_all, np.zeros(n)]), np.tile([0.0, 0.0, 1.0], (n, 1)),
                                wl))
    parallel = trace64_many(lens, batches, device)
    small = small_field_value(lens, small_angle_fraction)
    chiefs = chief_batches(lens, [object_field_point(lens, small)], wls, device) if small is not None else []
    out = []
    for k, (wl, fo, (h, h_all), res) in enumerate(zip(wls, fos, heights, parallel)):
        n_img = float(lens.indices(wl)[-1])
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.where(res.ok, -h_all / (n_img * res.direction[:, 1]), np.nan)
        f_eq = theta = m_par = m_real = h_obj = None
        r = trace64(lens, chiefs[k], device, plane_z_mm=fo.image_z_mm) if chiefs else None
        if r is not None and fo.object_distance_mm is None:
            theta = small
            if r.ok[0]:
                f_eq = float(r.position_mm[0, 1] / (float(lens.indices(wl)[0]) * math.tan(theta)))
        elif r is not None:
            h_obj, m_par = small, fo.magnification
            if r.ok[0]:
                m_real = float(r.position_mm[0, 1] / h_obj)
        out.append(FocalLength(wl, fo.efl_mm, h, f[1:], float(h_all[0]), float(f[0]), theta, f_eq,
                               fo.front_focal_length_mm, m_par, m_real, h_obj))
    return out


@dataclass
class LongitudinalAberration:
    """Axis crossings of real rays against pupil zone, per wavelength (mm; module docstring)."""

    zones: np.ndarray  # pupil zone rho in (0, 1] (fraction of the paraxial EP radius, or of the real stop's)
    wavelengths_nm: np.ndarray
    reference_z_mm: float  # the primary wavelength's paraxial image z
    paraxial_focus_z_mm: np.ndarray  # per wavelength
    focus_z_mm: np.ndarray  # (wavelengths, zones): real axis crossings
    lsa_mm: np.ndarray  # focus_z - reference_z
    third_order_lsa_mm: np.ndarray  # primary wavelength, from the Seidel sum: -SA rho^2 / u'
    primary_nm: float

    def marginal_lsa_mm(self, wavelength_nm: float | None = None) -> float:
        """LSA of the marginal zone relative to that wavelength's own paraxial focus."""
        k = self._row(wavelength_nm)
        return float(self.focus_z_mm[k, -1] - self.paraxial_focus_z_mm[k])

    def _row(self, wavelength_nm: float | None) -> int:
        w = self.primary_nm if wavelength_nm is None else wavelength_nm
        return int(np.argmin(np.abs(self.wavelengths_nm - w)))

    def correction(self, wavelength_nm: float | None = None) -> str:
        return correction_name(self.marginal_lsa_mm(wavelength_nm))

    def to_dict(self) -> dict:
        return {"zones": self.zones, "wavelengths_nm": self.wavelengths_nm, "reference_z_mm": self.reference_z_mm,
                "paraxial_focus_z_mm": self.paraxial_focus_z_mm, "focus_z_mm": self.focus_z_mm,
                "lsa_mm": self.lsa_mm, "third_order_lsa_mm": self.third_order_lsa_mm,
                "marginal_lsa_mm": [self.marginal_lsa_mm(float(w)) for w in self.wavelengths_nm],
                "correction": [self.correction(float(w)) for w in self.wavelengths_nm]}


def longitudinal_aberration(lens: Lens, wavelengths_nm: Sequence[float] | None = None,
                            zones: Sequence[float] | None = None, device: str | None = None,
                            aim: str = "paraxial") -> LongitudinalAberration:
    """Real marginal-ray foci against pupil zone (axial field), per wavelength (module docstring).

    Zones are fractions of the paraxial entrance-pupil radius (``aim="paraxial"``,
    as the Seidel sum counts them, so the third-order curve is the small-zone limit)
    or of the real stop radius (``aim="real"``).
    """
    from ...paraxial import first_order, seidel_sums
    wls = np.asarray(lens.wavelengths.nm if wavelengths_nm is None else wavelengths_nm, dtype=np.float64)
    rho = np.linspace(0.05, 1.0, 20) if zones is None else np.asarray(zones, dtype=np.float64)
    if np.any(rho <= 0) or np.any(rho > 1.5):
        raise LensrtError("pupil zones must lie in (0, 1.5]")
    primary = lens.wavelengths.primary_nm
    ref_z = first_order(lens, primary).image_z_mm
    fp = object_field_point(lens, 0.0)
    par_z = np.array([first_order(lens, float(w)).image_z_mm for w in wls])
    focus = np.full((len(wls), len(rho)), np.nan)
    # every wavelength's zones aimed, then traced in one trace
    aimed = [aim_batch(lens, fp, np.zeros_like(rho), rho, float(w), aim, device) for w in wls]
    for k, (rays, r) in enumerate(zip(aimed, trace64_many(lens, aimed, device))):
        ok = r.ok & rays.aimed
        focus[k] = np.where(ok, axis_crossing_z(r.position_mm, r.direction), np.nan)
    s = seidel_sums(lens, primary)
    sa = s.transverse_totals()["SA"]
    u = s.image_marginal_slope
    third = -sa / u * rho ** 2 if u != 0 else np.full_like(rho, np.nan)
    return LongitudinalAberration(rho, wls, ref_z, par_z, focus, focus - ref_z, third, primary)


@dataclass
class BestFocus:
    """The minimum-RMS image plane (``definition``) for one field point and a set of wavelengths."""

    wavelengths_nm: tuple[float, ...]
    weights: tuple[float, ...]
    object_value: float
    z_mm: float
    paraxial_image_z_mm: float  # of the primary wavelength
    offset_from_paraxial_mm: float
    rms_radius_mm: float  # at the best focus
    rms_radius_paraxial_mm: float  # on the paraxial image plane
    rays: int
    definition: str = BEST_FOCUS_DEFINITION

    def to_dict(self) -> dict:
        return {"wavelengths_nm": self.wavelengths_nm, "weights": self.weights, "z_mm": self.z_mm,
                "paraxial_image_z_mm": self.paraxial_image_z_mm, "offset_from_paraxial_mm": self.offset_from_paraxial_mm,
                "rms_radius_mm": self.rms_radius_mm, "rms_radius_at_paraxial_mm": self.rms_radius_paraxial_mm,
                "rays": self.rays, "definition": self.definition}


def _moments(lens: Lens, wavelengths_nm: Sequence[float], object_value: float, z0_mm: float, device: str | None):
    """The focus moments of each wavelength on the plane ``z0_mm``, traced together (those found before in this
    process -- a comparison asks for each several times -- are kept by :func:`focus_moments_fields`)."""
    return focus_moments_many(lens, [float(w) for w in wavelengths_nm], fp=object_field_point(lens, object_value),
                              z0_mm=z0_mm, device=device)


def best_focus(lens: Lens, wavelengths_nm: Sequence[float] | None = None, weights: Sequence[float] | None = None,
               object_value: float = 0.0, device: str | None = None) -> BestFocus:
    """The plane of minimum RMS spot radius (:data:`BEST_FOCUS_DEFINITION`, :mod:`lensrt.trace.focus`).

    ``wavelengths_nm`` default: the primary only; several wavelengths are pooled
    with ``weights`` (default the lens's weights where they match, else equal).
    """
    from ...paraxial import first_order
    wls = [lens.wavelengths.primary_nm] if wavelengths_nm is None else [float(w) for w in wavelengths_nm]
    if weights is None:
        table = dict(zip(lens.wavelengths.nm, lens.wavelengths.weights))
        weights = [table.get(w, 1.0) for w in wls]
    z_par = first_order(lens, lens.wavelengths.primary_nm).image_z_mm
    moments = _moments(lens, wls, float(object_value), z_par, device)
    plane = best_focus_plane(moments, weights)
    return BestFocus(tuple(wls), tuple(float(x) for x in weights), float(object_value), plane.z_mm, z_par,
                     plane.z_mm - z_par, plane.rms_radius_mm, plane.rms_radius_z0_mm, plane.rays)


@dataclass
class ChromaticFocalShift:
    """Paraxial focus against wavelength, and real best foci, from the primary's paraxial focus (mm)."""

    wavelength_nm: np.ndarray
    paraxial_shift_mm: np.ndarray
    best_focus_wavelength_nm: np.ndarray
    best_focus_shift_mm: np.ndarray  # real best focus (minimum RMS) minus the primary's paraxial focus
    reference_z_mm: float
    primary_nm: float

    def to_dict(self) -> dict:
        return {"wavelength_nm": self.wavelength_nm, "paraxial_focus_shift_mm": self.paraxial_shift_mm,
                "best_focus_wavelength_nm": self.best_focus_wavelength_nm,
                "best_focus_shift_mm": self.best_focus_shift_mm, "reference_z_mm": self.reference_z_mm,
                "primary_nm": self.primary_nm}


def chromatic_focal_shift(lens: Lens, wavelength_nm: Sequence[float] | None = None,
                          best_focus_wavelengths_nm: Sequence[float] | None = None,
                          device: str | None = None) -> ChromaticFocalShift:
    """Chromatic focal shift (module docstring); default 41 wavelengths over the lens's range (at least 400-700 nm)."""
    from ...paraxial import first_order
    nm = lens.wavelengths.nm
    if wavelength_nm is None:
        lo, hi = min(min(nm), 400.0), max(max(nm), 700.0)
        wavelength_nm = np.linspace(lo, hi, 41)
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    ref = first_order(lens, lens.wavelengths.primary_nm).image_z_mm
    par = np.array([first_order(lens, float(w)).image_z_mm for w in wl]) - ref
    bw = np.asarray(nm if best_focus_wavelengths_nm is None else best_focus_wavelengths_nm, dtype=np.float64)
    bf = np.array([best_focus(lens, [float(w)], [1.0], device=device).z_mm for w in bw]) - ref
    return ChromaticFocalShift(wl, par, bw, bf, ref, lens.wavelengths.primary_nm)


@dataclass
class FieldCurvature:
    """Sagittal and tangential foci (z, mm) against field at one wavelength (module docstring)."""

    wavelength_nm: float
    infinite: bool
    object_value: np.ndarray  # rad or mm
    paraxial_height_mm: np.ndarray
    paraxial_image_z_mm: float
    image_z_mm: float
    sagittal_z_mm: np.ndarray
    tangential_z_mm: np.ndarray
    petzval_z_mm: np.ndarray
    third_order_sagittal_z_mm: np.ndarray
    third_order_tangential_z_mm: np.ndarray
    petzval_curvature_per_mm: float
    valid: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    @property
    def astigmatism_mm(self) -> np.ndarray:
        """Tangential minus sagittal focus (mm)."""
        return self.tangential_z_mm - self.sagittal_z_mm

    def to_dict(self) -> dict:
        zp = self.paraxial_image_z_mm
        key = "field_deg" if self.infinite else "field_mm"
        return {"wavelength_nm": self.wavelength_nm,
                key: np.degrees(self.object_value) if self.infinite else self.object_value,
                "paraxial_height_mm": self.paraxial_height_mm, "paraxial_image_z_mm": zp,
                "image_z_mm": self.image_z_mm,
                "sagittal_focus_z_mm": self.sagittal_z_mm, "tangential_focus_z_mm": self.tangential_z_mm,
                "sagittal_from_paraxial_mm": self.sagittal_z_mm - zp,
                "tangential_from_paraxial_mm": self.tangential_z_mm - zp,
                "astigmatism_mm": self.astigmatism_mm, "petzval_from_paraxial_mm": self.petzval_z_mm - zp,
                "third_order_sagittal_from_paraxial_mm": self.third_order_sagittal_z_mm - zp,
                "third_order_tangential_from_paraxial_mm": self.third_order_tangential_z_mm - zp,
                "petzval_curvature_per_mm": self.petzval_curvature_per_mm}


def field_curvature(lens: Lens, hy: Sequence[float] | np.ndarray | None = None, wavelength_nm: float | None = None,
                    device: str | None = None, object_values: Sequence[float] | None = None,
                    chief: RayBatch | None = None, traced=None) -> FieldCurvature:
    """Sagittal and tangential foci from close rays about the real chief rays (module docstring); ``chief``:
    those chief rays at this wavelength when the caller aimed them already; ``traced``: their
    :func:`~lensrt.analysis.raysets.close_ray_batch` already traced (:func:`~lensrt.analysis.raysets.trace64`,
    no apertures), e.g. with other wavelengths' rays in one launch."""
    from ...paraxial import first_order, seidel_sums
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fo = first_order(lens, wl)
    if object_values is None:
        hs = np.linspace(0.0, 1.0, 21) if hy is None else np.asarray(hy, dtype=np.float64)
        obj = np.array([field_spec(lens, h).object_value for h in hs])
    else:
        obj = np.asarray(object_values, dtype=np.float64)
    fps = [object_field_point(lens, float(v)) for v in obj]
    chief = chief_batch(lens, fps, wl, device) if chief is None else chief
    r = trace64(lens, close_ray_batch(lens, chief, fps), device) if traced is None else traced
    ok = r.ok.reshape(-1, 3).all(axis=1) & chief.aimed
    p, v = r.position_mm, r.direction
    z_t = meridional_intersection_z(p[0::3], v[0::3], p[1::3], v[1::3])
    z_s = plane_crossing_z(p[2::3], v[2::3], 0)
    z_t, z_s = np.where(ok, z_t, np.nan), np.where(ok, z_s, np.nan)
    y_par = np.array([paraxial_chief(lens, fo, float(o))[0] for o in obj])
    s = seidel_sums(lens, wl)
    c_p = float(np.sum(s.petzval_curvature_per_mm))
    zp = fo.image_z_mm
    petz = zp + 0.5 * c_p * y_par ** 2
    tr = s.transverse_totals()
    y_max = paraxial_chief(lens, fo, field_spec(lens, 1.0).object_value)[0]
    u = s.image_marginal_slope
    k = (y_par / y_max) ** 2 if y_max and math.isfinite(y_max) and u != 0 else np.full_like(y_par, np.nan)
    third_s = zp - tr["SAS"] / u * k if u != 0 else np.full_like(y_par, np.nan)
    third_t = zp - tr["TAS"] / u * k if u != 0 else np.full_like(y_par, np.nan)
    return FieldCurvature(wl, fo.object_distance_mm is None, obj, y_par, zp, lens.image_z_mm, z_s, z_t, petz,
                          third_s, third_t, c_p, ok)
