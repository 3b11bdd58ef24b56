"""Vignetting and relative illumination against field, from real rays (Field Guide p. 32).

Mechanical vignetting
    The fraction of the entrance pupil's rays that pass: the real pupil's
    transmitted cross-section with every clear aperture, A(theta), over the one
    with the stop alone, A_stop(theta) (the stream kernel over the box of each
    pupil; both Monte Carlo, :class:`lensrt.stats.Estimate`).
Relative illumination, flux method (the default)
    The image of a uniform Lambertian object of radiance L. The flux collected
    from a small solid angle d(Omega) about the field angle theta is
    L A(theta) d(Omega); it lands on the image area dA that the real chief rays
    map d(Omega) to: dA / d(Omega) = y' (dy'/d theta) / sin(theta) for a
    rotationally symmetric lens (y' the real chief ray's height on the image
    surface). So E(theta) = L A(theta) sin(theta) / (y' dy'/d theta) and

        RI(theta) = [A(theta) / A(0)] [sin(theta) / (y' y'_theta)] (y'_theta(0))^2.

    This includes vignetting, pupil aberration (A(theta) is the real pupil) and
    distortion (the mapping). For a finite object, A is the projected solid angle
    integral cos(theta_obj) d(omega) of the pupil seen from the object point
    (Lambertian weights) and theta becomes the object height h.
    With a flat entrance pupil seen obliquely, A = A(0) cos(theta), and the
    rectilinear mapping y' = f tan(theta), sin(theta) / (y' y'_theta) = cos^3(theta) / f^2:
    RI = cos^4(theta), the cos^4 law of natural vignetting (p. 32). A thin lens with
    its stop on its flat first face is such a lens (tests).
Relative illumination, exit-pupil method (Rimmer 1986; OpticStudio's)
    The projected solid angle of the real exit pupil as seen from the image: the
    area enclosed by the direction cosines (L', M') of the rays along the
    vignetted pupil's boundary (:func:`lensrt.analysis.compare.pupils.pupil_outline`),
    over its value on axis. Deterministic. It equals the flux method when the
    imaging is good (the image-space rays of one field point meet in one point).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...stats import Estimate, batch_means, jackknife
from .pupils import pupil_frame, pupil_outlines, stop_only_lens
from ..raysets import chief_batch, field_spec, object_field_point, trace64

__all__ = ["Vignetting", "vignetting", "mapping_factor", "mapping_points",
           "relative_illumination_at", "RI_DEFINITION",
           "RI_VALIDITY"]

RI_DEFINITION = ("relative illumination E(theta)/E(0) of a uniform Lambertian object: real pupil cross-section "
                 "A(theta)/A(0) (stream kernel, every aperture) times the real chief-ray mapping factor "
                 "sin(theta) y'_theta(0)^2 / (y' dy'/dtheta); the exit-pupil method is the projected solid angle of "
                 "the real exit pupil seen from the image, relative to the axis")
#: where each relative-illumination method holds
RI_VALIDITY = {"flux": "always (energy through the real pupil onto the image area the real chief rays map it to)",
               "exit_pupil": "only where the image-space rays of a field point meet in one point (small aberrations "
                             "of the pupil imaging and of the image); with field aberrations it differs from the "
                             "flux method, which is then the one to read"}
#: the two methods are flagged when they differ by more than this many flux standard errors plus RI_AGREE_ABS
RI_AGREE_SIGMAS = 3.0
RI_AGREE_ABS = 2e-3


def mapping_points(lens: Lens, object_values: np.ndarray, step: float | None = None) -> tuple[np.ndarray, float]:
    """The object-space field values whose real chief rays :func:`mapping_factor` traces (the points, each
    +- the step, and +- the step about the axis) and the step."""
    obj = np.asarray(object_values, dtype=np.float64)
    top = max(float(np.max(np.abs(obj))), field_spec(lens, 1.0).object_value, 1e-6)
    h = 1e-4 * top if step is None else float(step)
    return np.concatenate([obj, obj + h, obj - h, [h, -h]]), h


def mapping_factor(lens: Lens, object_values: np.ndarray, wavelength_nm: float, device: str | None = None,
                   step: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Solid angle (or object area) per image area relative to the axis, and the real image heights (mm).

    Central differences of the real chief ray's height y' on the image surface
    with ``step`` (default 1e-4 of the largest field value).
    """
    obj = np.asarray(object_values, dtype=np.float64)
    pts, h = mapping_points(lens, obj, step)
    fps = [object_field_point(lens, float(v)) for v in pts]
    r = trace64(lens, chief_batch(lens, fps, wavelength_nm, device), device)
    if not r.ok.all():
        raise LensrtError("a real chief ray did not reach the image: no mapping factor there")
    y = r.position_mm[:, 1]
    n = len(obj)
    y0, yp, ym = y[:n], y[n:2 * n], y[2 * n:3 * n]
    dy = (yp - ym) / (2.0 * h)
    dy_axis = (y[-2] - y[-1]) / (2.0 * h)
    infinite = math.isinf(lens.object_distance_mm)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.sin(obj) if infinite else obj
        m = np.where(np.abs(obj) > 1e-12, s / (y0 * dy), 1.0 / dy_axis ** 2) * dy_axis ** 2
    return m, y0


@dataclass
class Vignetting:
    """Vignetting and relative illumination at field points (module docstring)."""

    wavelength_nm: float
    infinite: bool
    object_value: np.ndarray
    labels: list[str]
    pupil_area: list[Estimate]  # mm^2 (infinite) or sr (finite: projected solid angle)
    stop_pupil_area: list[Estimate]
    vignetting_fraction: list[Estimate]
    relative_illumination: list[Estimate]
    mapping_factor: np.ndarray
    image_height_mm: np.ndarray
    relative_illumination_exit_pupil: np.ndarray
    cos4: np.ndarray
    rays_per_field: int
    definition: str = RI_DEFINITION
    extra: dict = field(default_factory=dict)

    @property
    def ri_methods_agree(self) -> list[bool | None]:
        """Per field: do the flux and exit-pupil methods agree within the flux estimate's error
        (``RI_AGREE_SIGMAS`` standard errors plus ``RI_AGREE_ABS``)? None where the exit-pupil value is missing."""
        out: list[bool | None] = []
        for e, x in zip(self.relative_illumination, self.relative_illumination_exit_pupil):
            out.append(None if not math.isfinite(float(x))
                       else bool(abs(e.value - float(x)) <= RI_AGREE_SIGMAS * e.stderr + RI_AGREE_ABS))
        return out

    def ri_disagreement_note(self) -> str | None:
        """A line naming the fields where the two relative-illumination methods disagree, or None."""
        bad = [lab for lab, ok in zip(self.labels, self.ri_methods_agree) if ok is False]
        if not bad:
            return None
        return (f"relative illumination: the exit-pupil method differs from the flux method beyond its error at "
                f"{', '.join(bad)}; the exit-pupil method holds {RI_VALIDITY['exit_pupil']}")

    def values(self, name: str) -> np.ndarray:
        """Values of a list of estimates (``pupil_area``, ``relative_illumination``, ...)."""
        return np.array([e.value for e in getattr(self, name)])

    def stderrs(self, name: str) -> np.ndarray:
        return np.array([e.stderr for e in getattr(self, name)])

    def to_dict(self) -> dict:
        unit = "mm2" if self.infinite else "sr"
        return {"wavelength_nm": self.wavelength_nm, "fields": self.labels,
                ("field_deg" if self.infinite else "field_mm"):
                    np.degrees(self.object_value) if self.infinite else self.object_value,
                f"pupil_area_{unit}": [e.to_dict() for e in self.pupil_area],
                f"stop_pupil_area_{unit}": [e.to_dict() for e in self.stop_pupil_area],
                "vignetting_fraction": [e.to_dict() for e in self.vignetting_fraction],
                "relative_illumination": [e.to_dict() for e in self.relative_illumination],
                "relative_illumination_exit_pupil": self.relative_illumination_exit_pupil,
                "cos4": self.cos4, "mapping_factor": self.mapping_factor, "image_height_mm": self.image_height_mm,
                "rays_per_field": self.rays_per_field, "definition": self.definition,
                "relative_illumination_methods_agree": self.ri_methods_agree,
                "relative_illumination_validity": RI_VALIDITY}


def _per_batch_sums(lens: Lens, object_values: np.ndarray, wavelength_nm: float, rays: int, batches: int, seed: int,
                    sampler: str, device: str | None, precision: str = "float64"
                    ) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """Stream the real pupils: per-batch weight sums (S, B), the box factor to turn a mean weight into an
    area (mm^2) or projected solid angle (sr), rays per source, seconds (all) and the stream kernel's
    seconds."""
    from ...trace.sampling import spectrum_discrete
    from ...trace.stream import Grid, stream, stream_sources
    fps = [object_field_point(lens, float(v)) for v in object_values]
    t0 = time.perf_counter()
    # every field point's pupil box in one batched pass (the same sources as stream_source one by one)
    sources = stream_sources(lens, fps, centres_mm=[(0.0, 0.0)] * len(fps), layers=[0] * len(fps),
                             wavelengths_nm=[wavelength_nm], device=device)
    res = stream(lens, sources, Grid(1, 1, 1.0), rays, spectrum=spectrum_discrete([wavelength_nm], [1.0]),
                 sampler=sampler, seed=seed, batches=batches, precision=precision, device=device)
    n_b = res.rays_per_source // res.batches
    factor = np.array(res.pupil_area_mm2, dtype=np.float64) / n_b
    for k, fp in enumerate(fps):
        if not fp.infinite:
            c, w, _, _ = pupil_frame(lens, fp)
            dist = float((c - np.asarray(fp.point_mm)) @ w)
            factor[k] /= dist * dist
    return res.batch_stats[:, :, 1], factor, res.rays_per_source, time.perf_counter() - t0, float(res.seconds)


def _ri_estimate(s_all: np.ndarray, f_all: np.ndarray, i: int, m: float, samples: int, seconds: float,
                 batches: int) -> Estimate:
    """Relative illumination of source ``i`` against source 0 (the axis): jackknife over the batches."""
    pair = np.stack([s_all[i], s_all[0]], axis=1)
    v, se = jackknife(pair, lambda t: (t[0] * f_all[i]) / (t[1] * f_all[0]) * m)
    return Estimate(float(v), float(se), samples, seconds, f"jackknife over {batches} batches", "")


def relative_illumination_at(lens: Lens, object_value: float, wavelength_nm: float | None = None, *,
                             rays: int = 1 << 16, batches: int = 32, seed: int = 0, sampler: str = "sobol",
                             precision: str = "float64", mapping: float | None = None,
                             device: str | None = None) -> Estimate:
    """Relative illumination (flux method) at one field value (rad, or mm for a near object) alone.

    The Monte Carlo part of :func:`vignetting` for one field: the real pupil at the field and on
    the axis (``rays`` each), times the mapping factor (``mapping``, else computed here). The
    estimate's ``seconds`` are the stream kernel's (what error against run time needs).
    """
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    m = float(mapping_factor(lens, np.array([object_value]), wl, device)[0][0]) if mapping is None else float(mapping)
    s_all, f_all, n, _, kernel_s = _per_batch_sums(lens, np.array([0.0, float(object_value)]), wl, rays, batches,
                                                   seed, sampler, device, precision)
    return _ri_estimate(s_all, f_all, 1, m, 2 * n, kernel_s, batches)


def vignetting(lens: Lens, hy: Sequence[float] | None = None, wavelength_nm: float | None = None, *,
               rays: int = 1 << 16, batches: int = 32, seed: int = 0, sampler: str = "sobol",
               exit_pupil: bool = True, n_azimuth: int = 180, device: str | None = None,
               object_values: Sequence[float] | None = None) -> Vignetting:
    """Vignetting fraction and relative illumination (both methods) at normalised fields ``hy``.

    ``rays`` Monte Carlo rays per field for each of the two pupils (every aperture,
    stop only); the axis is always traced too (it normalises the illumination).
    """
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    if object_values is None:
        hs = np.linspace(0.0, 1.0, 11) if hy is None else np.asarray(hy, dtype=np.float64)
        obj = np.array([field_spec(lens, h).object_value for h in hs])
    else:
        obj = np.asarray(object_values, dtype=np.float64)
    if np.any(obj < 0):
        raise LensrtError("field values for vignetting must not be negative")
    labels = [(f"{math.degrees(v):.2f} deg" if math.isinf(lens.object_distance_mm) else f"{v:.3f} mm") for v in obj]
    pts = np.concatenate([[0.0], obj])
    s_all, f_all, n, sec, _ = _per_batch_sums(lens, pts, wl, rays, batches, seed, sampler, device)
    s_stop, f_stop, _, sec2, _ = _per_batch_sums(stop_only_lens(lens), pts, wl, rays, batches, seed, sampler, device)
    seconds = sec + sec2
    per = seconds / (2 * len(pts))
    jk = f"jackknife over {batches} batches"
    area, area_stop, frac, ri = [], [], [], []
    m, y_img = mapping_factor(lens, obj, wl, device)
    unit = "mm^2" if math.isinf(lens.object_distance_mm) else "sr"
    for k in range(len(obj)):
        i = k + 1
        v, se = batch_means(s_all[i] * f_all[i])
        area.append(Estimate(float(v), float(se), n, per, f"batch means over {batches} batches", unit))
        v, se = batch_means(s_stop[i] * f_stop[i])
        area_stop.append(Estimate(float(v), float(se), n, per, f"batch means over {batches} batches", unit))
        pair = np.stack([s_all[i], s_stop[i]], axis=1)
        v, se = jackknife(pair, lambda t, i=i: (t[0] * f_all[i]) / (t[1] * f_stop[i]) if t[1] > 0 else 0.0)
        frac.append(Estimate(float(v), float(se), 2 * n, 2 * per, jk, ""))
        ri.append(_ri_estimate(s_all, f_all, i, float(m[k]), 2 * n, 2 * per, batches))
    ri_xp = np.full(len(obj), np.nan)
    if exit_pupil:
        sol = [math.nan if isinstance(o, LensrtError) else o.exit_projected_solid_angle_sr
               for o in pupil_outlines(lens, [float(v) for v in pts], wl, n_azimuth=n_azimuth, device=device)]
        ri_xp = np.array(sol[1:]) / sol[0]
    if math.isinf(lens.object_distance_mm):
        cos4 = np.cos(obj) ** 4
    else:
        from ...paraxial import first_order
        z_ep = first_order(lens, wl).entrance_pupil_z_mm
        cos4 = np.cos(np.arctan(obj / (lens.object_distance_mm + z_ep))) ** 4
    return Vignetting(wl, math.isinf(lens.object_distance_mm), obj, labels, area, area_stop, frac, ri, m, y_img,
                      ri_xp, cos4, n)
