"""Paraxial against real: every comparison of ``lensrt compare`` in one call.

Gaussian optics is exact for a perfect lens (Field Guide p. 2); each difference
between the ynu trace and the real trace below is an aberration:

* focal length: 1/Phi against the real EFL of near-axis and marginal rays, and the
  equivalent focal length from a small-angle image height (:mod:`.focus`);
* image height: the paraxial chief ray against the real one, distortion in both
  definitions and the fisheye mappings (:mod:`.distortion`);
* focus: the paraxial image plane against the real best focus and the marginal
  focus by pupil zone (spherical aberration, under/over-corrected);
* field curvature: real sagittal and tangential foci, the Petzval surface and the
  third-order surfaces;
* colour: axial (focus against wavelength) and lateral (image height against wavelength);
* pupils: paraxial against real, and the vignetted pupil seen from each field point (:mod:`.pupils`);
* vignetting and relative illumination against cos^4 (:mod:`.vignetting`);
* ray fans, OPD fans and spot diagrams (:mod:`.aberrations`).

:func:`compare_lens` returns a :class:`Comparison`; ``to_dict()`` is the JSON of
``lensrt compare --json`` (every number's unit in its key);
:func:`lensrt.views.compare.comparison_text` is the terminal text and
:func:`lensrt.views.plots.analysis.write_compare_plots` the figures.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...trace import RayBatch
from .aberrations import RayFan, SpotDiagram, fan_jobs, ray_fan, spot_diagrams, trace_fans
from .distortion import (DEFINITION_TEXT, DistortionCurve, GridDistortion, distortion_curve, grid_distortion,
                         grid_object_values)
from .focus import (BEST_FOCUS_DEFINITION, BestFocus, ChromaticFocalShift, FieldCurvature, FocalLength,
                    LongitudinalAberration, best_focus, chromatic_focal_shift, field_curvature, longitudinal_aberration,
                    real_focal_lengths, small_field_value)
from .pupils import RealPupils, pupil_outlines, real_pupil_jobs, real_pupils
from ..raysets import (FieldSpec, aim_batches, chief_batches, field_display, field_key, field_spec, lens_fields,
                       close_ray_batch, object_field_point, paraxial_chief, trace64, trace64_many)
from .vignetting import RI_DEFINITION, Vignetting, mapping_points, vignetting

__all__ = ["Comparison", "compare_lens", "lateral_colour", "LateralColour"]


@dataclass
class LateralColour:
    """Chief-ray heights per wavelength on the primary wavelength's paraxial image plane (mm)."""

    wavelengths_nm: np.ndarray
    labels: list[str]
    paraxial_height_mm: np.ndarray  # (fields, wavelengths)
    real_height_mm: np.ndarray  # (fields, wavelengths)
    primary_nm: float
    plane_z_mm: float

    def to_dict(self) -> dict:
        k = int(np.argmin(np.abs(self.wavelengths_nm - self.primary_nm)))
        return {"wavelengths_nm": self.wavelengths_nm, "fields": self.labels, "plane_z_mm": self.plane_z_mm,
                "paraxial_height_mm": self.paraxial_height_mm, "real_height_mm": self.real_height_mm,
                "paraxial_from_primary_mm": self.paraxial_height_mm - self.paraxial_height_mm[:, k:k + 1],
                "real_from_primary_mm": self.real_height_mm - self.real_height_mm[:, k:k + 1]}


def _lateral_jobs(lens: Lens, fields: Sequence[FieldSpec], wls) -> list[tuple]:
    """The chief rays :func:`lateral_colour` aims: every field at every wavelength (wavelength-major)."""
    fps = [object_field_point(lens, f.object_value) for f in fields]
    return [(fp, 0.0, 0.0, float(w)) for w in wls for fp in fps]


def lateral_colour(lens: Lens, fields: Sequence[FieldSpec], wavelengths_nm: Sequence[float],
                   device: str | None = None) -> LateralColour:
    """Paraxial and real chief-ray heights at each wavelength, all on the primary's paraxial image plane."""
    from ...paraxial import first_order
    primary = lens.wavelengths.primary_nm
    z = first_order(lens, primary).image_z_mm
    wls = np.asarray(wavelengths_nm, dtype=np.float64)
    par = np.full((len(fields), len(wls)), np.nan)
    real = np.full((len(fields), len(wls)), np.nan)
    fps = [object_field_point(lens, f.object_value) for f in fields]
    # the chief rays of every field and wavelength aimed in one solve
    chiefs = aim_batches(lens, _lateral_jobs(lens, fields, wls), "real", device)
    # and traced in one trace, a result per wavelength
    parts = [chiefs[j * len(fps):(j + 1) * len(fps)] for j in range(len(wls))]
    batches = [RayBatch(np.concatenate([c.origin_mm for c in part]), np.concatenate([c.direction for c in part]),
                        float(w), np.concatenate([c.aimed for c in part])) for w, part in zip(wls, parts)]
    traced = trace64_many(lens, batches, device, plane_z_mm=z)
    for j, (w, r) in enumerate(zip(wls, traced)):
        fo = first_order(lens, float(w))
        real[:, j] = np.where(r.ok, r.position_mm[:, 1], np.nan)
        for i, f in enumerate(fields):
            h, u = paraxial_chief(lens, fo, f.object_value)
            par[i, j] = h + (z - fo.image_z_mm) * u
    return LateralColour(wls, [f.label for f in fields], par, real, primary, z)


@dataclass
class Comparison:
    """Everything :func:`compare_lens` computed (see the module docstring)."""

    lens: Lens
    wavelengths_nm: tuple[float, ...]
    primary_nm: float
    fields: list[FieldSpec]
    curve_hy: np.ndarray
    field_index: list[int]  # index of each field in the curves
    focal: list[FocalLength]
    distortion: dict[float, DistortionCurve]
    grid: GridDistortion | None
    lsa: LongitudinalAberration
    best_focus: dict[str, BestFocus]
    chromatic: ChromaticFocalShift
    field_curvature: dict[float, FieldCurvature]
    lateral: LateralColour
    pupils: RealPupils
    vignetting: Vignetting
    spots: list[SpotDiagram]
    fans: list[tuple[RayFan, RayFan]]
    seconds: float
    device: str
    notes: list[str] = field(default_factory=list)

    @property
    def infinite(self) -> bool:
        return math.isinf(self.lens.object_distance_mm)

    @property
    def field_key(self) -> str:
        """Name and unit of the lens's field values (``field_deg``, ``paraxial_image_height_mm``, ...)."""
        return field_key(self.lens)

    @property
    def object_key(self) -> str:
        """Name and unit of object-space field values: ``field_deg`` at infinity, else ``object_height_mm``."""
        return "field_deg" if self.infinite else "object_height_mm"

    def field_number(self, spec: FieldSpec) -> float:
        """The field in the lens's own unit (deg for angles, mm for heights)."""
        return field_display(self.lens, spec)

    def object_number(self, spec: FieldSpec) -> float:
        return math.degrees(spec.object_value) if self.infinite else spec.object_value

    def to_dict(self) -> dict:
        """The JSON object of ``lensrt compare --json``."""
        from ...paraxial import first_order
        fo = first_order(self.lens, self.primary_nm)
        prim = self.distortion[self.primary_nm]
        rows = []
        for spec, i in zip(self.fields, self.field_index):
            for w in self.wavelengths_nm:
                d, fc = self.distortion[w], self.field_curvature[w]
                row = {self.field_key: self.field_number(spec), "wavelength_nm": w,
                       "paraxial_height_mm": d.paraxial_height_mm[i], "real_height_mm": d.real_height_mm[i],
                       "real_height_image_surface_mm": d.real_height_image_mm[i],
                       "distortion_percent": d.distortion_percent[i],
                       "distortion_codev_percent": d.distortion_codev_percent[i],
                       "sagittal_focus_from_paraxial_mm": fc.sagittal_z_mm[i] - fc.paraxial_image_z_mm,
                       "tangential_focus_from_paraxial_mm": fc.tangential_z_mm[i] - fc.paraxial_image_z_mm,
                       "petzval_from_paraxial_mm": fc.petzval_z_mm[i] - fc.paraxial_image_z_mm}
                if self.infinite:
                    row.update({f"{k}_height_mm": v[i] for k, v in d.mapping_height_mm.items() if k != "rectilinear"})
                rows.append(row)
        vg = self.vignetting
        last = prim.distortion_percent[self.field_index[-1]] if self.field_index else math.nan
        out = {
            "lens": self.lens.name, "path": self.lens.path, "device": self.device, "seconds": self.seconds,
            "wavelengths_nm": list(self.wavelengths_nm), "primary_wavelength_nm": self.primary_nm,
            "object_distance_mm": None if self.infinite else self.lens.object_distance_mm,
            "fields": [{self.field_key: self.field_number(s), self.object_key: self.object_number(s), "hy": s.hy,
                        "label": s.label} for s in self.fields],
            "definitions": {"distortion": DEFINITION_TEXT, "best_focus": BEST_FOCUS_DEFINITION,
                            "relative_illumination": RI_DEFINITION,
                            "spherical_aberration": "LSA = z(real ray of pupil zone crosses the axis) - z(paraxial "
                                                    "image); LSA < 0 at the margin: under-corrected",
                            "field_curvature": "sagittal and tangential foci (z) from close rays about the real chief "
                                               "ray; Petzval z = z_par + c_P y'^2 / 2"},
            "focal_length": [f.to_dict() for f in self.focal],
            "per_field": rows,
            "distortion_type_at_largest_field": ("barrel" if last < 0 else "pincushion" if last > 0 else "none"),
            "distortion_curve": prim.to_dict(),
            "grid_distortion": None if self.grid is None else self.grid.to_dict(),
            "focus": {"paraxial_image_z_mm": fo.image_z_mm, "image_surface_z_mm": self.lens.image_z_mm,
                      "image_surface_from_paraxial_mm": self.lens.image_z_mm - fo.image_z_mm,
                      "best_focus": {k: v.to_dict() for k, v in self.best_focus.items()}},
            "spherical_aberration": self.lsa.to_dict(),
            "field_curvature": self.field_curvature[self.primary_nm].to_dict(),
            "colour": {"axial": self.chromatic.to_dict(), "lateral": self.lateral.to_dict()},
            "pupils": self.pupils.to_dict(),
            "vignetting": vg.to_dict(),
            "spots": [s.to_dict() for s in self.spots],
            "notes": self.notes,
        }
        return out


#: the sagittal fans of compare_lens: one half of the pupil (the other is its mirror image)
_SAGITTAL_PUPIL = np.linspace(0.0, 1.0, 21)


def _aim_fans(lens: Lens, fields: list[FieldSpec], wls, device: str | None) -> list:
    """The rays of every field's tangential and sagittal fan aimed in one solve: [tangential, sagittal] per
    field, each the list :func:`ray_fan` takes as ``aimed`` (None where that fan could not be set up)."""
    jobs, spans = _fan_jobs_of(lens, fields, wls)
    aimed = aim_batches(lens, jobs, "real", device)
    return [None if sp is None else aimed[sp[0]:sp[1]] for sp in spans]


def _fan_jobs_of(lens: Lens, fields: list[FieldSpec], wls) -> tuple[list, list]:
    """The aiming jobs of every field's tangential and sagittal fan, and each fan's (start, stop) in them
    (None where that fan could not be set up)."""
    jobs, spans = [], []
    for f in fields:
        for fan, pupil in (("tangential", None), ("sagittal", _SAGITTAL_PUPIL)):
            try:
                part = fan_jobs(lens, f.hy, fan, wls, pupil)
            except LensrtError:
                spans.append(None)
                continue
            spans.append((len(jobs), len(jobs) + len(part)))
            jobs += part
    return jobs, spans


def _aim_ahead(lens: Lens, fields: list[FieldSpec], wls, curve_fps: list, vhy: np.ndarray, fans: bool,
               device: str | None) -> None:
    """Every real ray that the analyses of :func:`compare_lens` aim with ``aim_batches``/``chief_batch`` -- the
    curves' and lateral colour's chief rays at every wavelength, the real pupils' chief and rim rays,
    vignetting's mapping-factor chief rays, the real focal lengths' small-field chief rays, the distortion grid's
    chief rays, the fans -- in one Newton run. ``aim_batches`` keeps them, so each
    analysis then finds its rays aimed: the same bits (each ray's Newton run is its own), one run instead of
    one each."""
    primary = lens.wavelengths.primary_nm
    jobs = [(fp, 0.0, 0.0, float(w)) for w in wls for fp in curve_fps] + _lateral_jobs(lens, fields, wls)
    jobs += real_pupil_jobs(lens, [f.hy for f in fields], primary)
    pts = mapping_points(lens, np.array([field_spec(lens, h).object_value for h in vhy]))[0]
    jobs += [(object_field_point(lens, float(v)), 0.0, 0.0, float(primary)) for v in pts]
    small = small_field_value(lens)  # real_focal_lengths' small-field chief rays
    if small is not None:
        jobs += [(object_field_point(lens, small), 0.0, 0.0, float(w)) for w in wls]
    try:  # grid_distortion's chief rays (its own error, if any, is raised and noted where it runs)
        jobs += [(object_field_point(lens, float(v)), 0.0, 0.0, float(primary))
                 for v in grid_object_values(lens, 11, primary)]
    except LensrtError:
        pass
    if fans:
        jobs += _fan_jobs_of(lens, fields, wls)[0]
    aim_batches(lens, jobs, "real", device)


def compare_lens(lens: Lens, *, wavelengths_nm: Sequence[float] | None = None,
                 extra_fields: Sequence[float] | None = None, device: str | None = None, rays: int = 1 << 16,
                 seed: int = 0, curve_points: int = 21, fans: bool = True, spots: bool = True,
                 spot_rays: int = 1 << 14) -> Comparison:
    """Run every paraxial-against-real comparison (module docstring).

    Parameters
    ----------
    lens : Lens
    wavelengths_nm : sequence, optional
        Extra wavelengths (nm) beside the lens's own.
    extra_fields : sequence, optional
        Extra field points in the lens's field unit (rad for angles, mm for heights).
    device : str, optional
        Warp device ('cpu', 'cuda', ...); default: CUDA when present.
    rays : int
        Monte Carlo rays per field point for the vignetting (each of two pupils).
    seed : int
        Seed of every Monte Carlo estimate.
    curve_points : int
        Field samples of the distortion, field-curvature and illumination curves.
    fans, spots : bool
        Compute ray fans and spot diagrams.
    spot_rays : int
        Monte Carlo rays per field and wavelength for the spot statistics.
    """
    from ...device import resolve_device
    from ...paraxial.first_order import refuse_afocal
    refuse_afocal(lens, "compare (focal lengths, focus, distortion, spots on the image plane)")
    t0 = time.perf_counter()
    dev = resolve_device(device)
    wls = list(lens.wavelengths.nm)
    for w in wavelengths_nm or ():
        if not (math.isfinite(w) and 200.0 <= w <= 20000.0):
            raise LensrtError(f"wavelength {w!r} nm is outside 200..20000 nm")
        if all(abs(w - v) > 1e-9 for v in wls):
            wls.append(float(w))
    wls = tuple(sorted(wls))
    primary = lens.wavelengths.primary_nm
    fields = lens_fields(lens, extra_fields)
    top = max([1.0] + [f.hy for f in fields])
    hy = np.unique(np.round(np.concatenate([np.linspace(0.0, top, curve_points), [f.hy for f in fields]]), 12))
    index = [int(np.argmin(np.abs(hy - f.hy))) for f in fields]
    notes = []
    # the chief rays of the curves' field points at every wavelength, aimed in one solve with the rays of the
    # other analyses (_aim_ahead)
    curve_fps = [object_field_point(lens, float(v)) for v in (field_spec(lens, h).object_value for h in hy)]
    vhy = np.unique(np.round(np.concatenate([np.linspace(0.0, top, 11), [f.hy for f in fields]]), 12))
    _aim_ahead(lens, fields, wls, curve_fps, vhy, fans, dev)
    focal = real_focal_lengths(lens, wls, device=dev)  # every wavelength's rays traced together
    chiefs = dict(zip(wls, chief_batches(lens, curve_fps, wls, dev)))
    # every wavelength's chief rays (distortion) and close rays about them (field curvature) in one trace
    curve_rays = [chiefs[w] for w in wls] + [close_ray_batch(lens, chiefs[w], curve_fps) for w in wls]
    curves = trace64_many(lens, curve_rays, dev)
    dist = {w: distortion_curve(lens, hy, w, device=dev, chief=chiefs[w], traced=t) for w, t in zip(wls, curves)}
    try:
        grid = grid_distortion(lens, 11, primary, device=dev)
    except LensrtError as e:
        grid = None
        notes.append(f"no grid distortion: {e}")
    lsa = longitudinal_aberration(lens, wls, device=dev)
    # the polychromatic best focus first: the focus moments of all the lens's wavelengths in one batched search,
    # which the single-wavelength ones then find in best_focus's cache (the same moments, fewer launches)
    poly = best_focus(lens, list(lens.wavelengths.nm), device=dev)
    bf = {f"{w:g}": best_focus(lens, [w], [1.0], device=dev) for w in wls}
    bf["polychromatic"] = poly
    chrom = chromatic_focal_shift(lens, best_focus_wavelengths_nm=wls, device=dev)
    fcurv = {w: field_curvature(lens, hy, w, device=dev, chief=chiefs[w], traced=t)
             for w, t in zip(wls, curves[len(wls):])}
    lat = lateral_colour(lens, fields, wls, device=dev)
    # the pupil outlines of the real pupils' fields and of vignetting's exit-pupil illumination in one batched
    # search (each analysis then finds its outlines in pupil_outlines' cache: the same outlines, fewer launches)
    pupil_outlines(lens, [0.0] + [field_spec(lens, h).object_value for h in [f.hy for f in fields] + list(vhy)],
                   primary, n_azimuth=180, device=dev)
    pup = real_pupils(lens, [f.hy for f in fields], primary, device=dev)
    vig = vignetting(lens, vhy, primary, rays=rays, seed=seed, device=dev)
    if vig.ri_disagreement_note():
        notes.append(vig.ri_disagreement_note())
    spot = []
    if spots:
        try:
            spot = spot_diagrams(lens, [f.hy for f in fields], wls, rays=spot_rays, seed=seed, device=dev)
        except LensrtError as e:
            notes.append(f"no spot diagrams: {e}")
        have = {s.label for s in spot}
        notes += [f"no spot diagram at {f.label}: every ray is vignetted" for f in fields if f.label not in have]
    fan = []
    if fans:
        aimed = _aim_fans(lens, fields, wls, dev)
        traced = trace_fans(lens, aimed, dev)  # every field's fans in two launches
        for k, f in enumerate(fields):
            try:
                pair = (ray_fan(lens, f.hy, "tangential", wls, device=dev, aimed=aimed[2 * k], traced=traced[2 * k]),
                        ray_fan(lens, f.hy, "sagittal", wls, pupil=_SAGITTAL_PUPIL, device=dev,
                                aimed=aimed[2 * k + 1], traced=traced[2 * k + 1]))
            except LensrtError as e:
                notes.append(f"no ray fan at {f.label}: {e}")
                continue
            if not (pair[0].passed.any() or pair[1].passed.any()):
                notes.append(f"no ray fan at {f.label}: every ray is vignetted")
                continue
            fan.append(pair)
    return Comparison(lens, wls, primary, fields, hy, index, focal, dist, grid, lsa, bf, chrom, fcurv, lat, pup, vig,
                      spot, fan, time.perf_counter() - t0, dev, notes)
