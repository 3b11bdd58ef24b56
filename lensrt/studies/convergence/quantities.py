"""The Monte Carlo quantities of ``lensrt converge`` (the render's is :mod:`lensrt.studies.convergence.render`).

Each is a :class:`lensrt.studies.convergence.study.Quantity`: ``run(samples, sampler, precision, seed)``
gives a scalar :class:`lensrt.stats.Estimate` whose seconds are the stream kernel's, and
``closed_form()`` the exact value where one exists for the lens at hand:

``psf-rms`` (:class:`PsfRms`) -- RMS spot radius about the centroid at one field point (moment sums
    of the stream kernel, jackknife over the batches). Closed form: **pure defocus of a stigmatic
    lens** (:func:`stigmatic_defocus_rms_mm`): on axis, object at infinity, every surface flat but the
    last, which is the conic that images a collimated beam perfectly, k = -(n/n')^2 (a hyperboloid
    from glass into air; Descartes). Every ray then passes the focus F exactly, so a ray entering at
    height h lands at r(h) = h (z_F - z) / (z_F - z_s(h)) on the plane z (z_s the surface's sag
    position), and the RMS radius of the uniformly filled pupil of radius R is
    sqrt(2 / R^2 int_0^R r(h)^2 h dh) (64-point Gauss-Legendre, exact to rounding).
``mtf`` (:class:`PsfMtf`) -- MTF at one frequency along the tangential or sagittal direction
    (per-batch histograms, jackknife). No closed form.
``rel-illum`` (:class:`RelIllum`) -- relative illumination by the flux method
    (:func:`lensrt.analysis.compare.vignetting.relative_illumination_at`). Closed form: **the cos^4 case**: object
    at infinity, a flat circular stop as the first surface and nothing else clipping the beam (checked
    by tracing its rim): the real pupil is the stop disc foreshortened, A(theta) / A(0) = cos(theta),
    exactly, so RI = cos(theta) x the (deterministic) mapping factor -- cos^4(theta) for a rectilinear
    lens (Field Guide p. 32).
``bokeh`` (:class:`BokehRegion`) -- mean illuminance Y (lux) over a square region of a bokeh spot's
    window (default: the central fifth of the spot's footprint), batch means over the batches. No closed
    form.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...stats import Estimate, batch_means
from .study import Reference, converge, default_ray_counts
from ...analysis.fields import FieldSpec
from ...analysis.grid import ImageGrid

__all__ = ["PsfRms", "PsfMtf", "RelIllum", "BokehRegion", "stigmatic_defocus_rms_mm", "cos_pupil_ratio_applies",
           "SAMPLERS_ALL", "converge_psf"]

SAMPLERS_ALL = ("random", "stratified", "sobol", "r2")
_PRECISIONS = ("float32", "float64")


def stigmatic_defocus_rms_mm(lens: Lens, wavelengths_nm: Sequence[float], plane_z_mm: float,
                             field: FieldSpec | None = None) -> tuple[float | None, str]:
    """RMS spot radius (mm) of pure defocus (module docstring), or (None, why the lens is not such a case)."""
    if not math.isinf(lens.object_distance_mm):
        return None, "the object is not at infinity"
    if field is not None and (field.hx != 0.0 or field.hy != 0.0):
        return None, "the field point is off the axis"
    *front, last = lens.surfaces
    if any(s.curvature_per_mm != 0.0 or s.asphere for s in front):
        return None, "a surface before the last one is curved"
    if last.curvature_per_mm == 0.0 or last.asphere:
        return None, "the last surface is not a pure conic"
    if lens.iris.blades or lens.iris.obstruction_ratio:
        return None, "the iris is not a clear circle"
    for wl in sorted(set(float(w) for w in wavelengths_nm)):
        idx = lens.indices(wl)
        k_star = -(idx[-2] / idx[-1]) ** 2
        if abs(last.conic - k_star) > 1e-9 * abs(k_star):
            return None, f"the last surface's conic {last.conic:g} is not -(n/n')^2 = {k_star:.9g} at {wl:g} nm"
    n, n2 = (float(v) for v in lens.indices(float(wavelengths_nm[0]))[-2:])
    radius = min(float(s.semi_diameter_mm) for s in lens.surfaces)
    c, k = last.curvature_per_mm, last.conic
    z_last = float(lens.length_mm)
    z_f = z_last + n2 / (c * (n2 - n))
    x, w = np.polynomial.legendre.leggauss(64)
    h = 0.5 * radius * (x + 1.0)
    sag = c * h * h / (1.0 + np.sqrt(1.0 - (1.0 + k) * c * c * h * h))
    r = h * (z_f - float(plane_z_mm)) / (z_f - (z_last + sag))
    ms = float(np.sum(0.5 * radius * w * r * r * 2.0 * h) / radius ** 2)
    return math.sqrt(ms), (f"pure defocus of a stigmatic conic (k = {k:.6g} = -(n/n')^2), pupil radius {radius:g} mm, "
                           f"plane {float(plane_z_mm) - z_f:+.6g} mm from the focus")


class PsfRms:
    """``psf-rms``: RMS spot radius about the centroid at one field point (module docstring)."""

    name = "psf-rms"
    unit, display_unit, display_scale = "mm", "um", 1000.0
    sample_unit = "rays"
    samplers, precisions = SAMPLERS_ALL, _PRECISIONS
    reference_sampler, reference_precision = "sobol", "float64"

    def __init__(self, setup, field: FieldSpec, device: str | None = None) -> None:
        from ...analysis.psf.geometric import prepare_field, psf_window
        self.setup = setup.with_(target_error=None, time_budget_s=None)
        self.field, self.device = field, device
        self.geom = prepare_field(self.setup, field, device)
        pitch_um, pixels, _ = psf_window(self.setup, self.geom, device)
        self.grid = ImageGrid.centred((pixels, pixels), pitch_um, self.geom.reference_mm)
        self.min_samples = int(setup.batches) * 64
        self.label = f"RMS spot radius at {field.label or (field.hx, field.hy)}"

    def totals(self, samples: int, sampler: str, precision: str, seed: int):
        from ...analysis.psf.geometric import run_stream
        s = self.setup.with_(sampler=sampler, precision=precision, rays=int(samples))
        return run_stream(s, self.geom, self.grid, seed, self.device)[0]

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        from ...analysis.psf.geometric import rms_rel_error
        tot = self.totals(samples, sampler, precision, seed)
        v, rel = rms_rel_error(tot.moments)
        return Estimate(v, rel * v, int(tot.rays), float(tot.trace_seconds),
                        f"jackknife over {self.setup.batches} batches", "mm")

    def closed_form(self) -> tuple[Reference | None, str]:
        spec = self.setup.spectrum
        wls = list(spec.lines_nm) + [spec.min_nm, spec.max_nm]
        v, why = stigmatic_defocus_rms_mm(self.setup.lens, wls, self.setup.plane_z_mm, self.field)
        return (None, why) if v is None else (Reference(v, 0.0, 0, 0.0, "closed form", why), why)


class PsfMtf(PsfRms):
    """``mtf``: MTF at ``freq_cpmm`` along the tangential (or sagittal) direction at one field point."""

    name = "mtf"
    unit, display_unit, display_scale = "", "", 1.0

    def __init__(self, setup, field: FieldSpec, freq_cpmm: float, azimuth: str = "tangential",
                 device: str | None = None) -> None:
        from ...analysis.psf.otf import tangential_angle_rad
        super().__init__(setup, field, device)
        if azimuth not in ("tangential", "sagittal"):
            raise LensrtError(f"unknown MTF azimuth {azimuth!r}", hint="tangential or sagittal")
        nyq = 0.5 / self.grid.pitch_mm
        if not 0.0 < freq_cpmm < nyq:
            raise LensrtError(f"{freq_cpmm:g} cycles/mm is not within (0, {nyq:.4g}) (the PSF grid's Nyquist "
                              "frequency)", hint="a smaller --pitch-um or a lower frequency")
        self.freq_cpmm = float(freq_cpmm)
        t = tangential_angle_rad(self.geom.reference_mm)
        self.angle_rad = t if azimuth == "tangential" else t + 0.5 * math.pi
        self.label = f"{azimuth} MTF at {freq_cpmm:g} cycles/mm, {field.label or (field.hx, field.hy)}"

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        from ...analysis.psf.otf import mtf_estimate
        tot = self.totals(samples, sampler, precision, seed)
        e = mtf_estimate(tot.hist, self.grid, [self.freq_cpmm], self.angle_rad, samples=int(tot.rays),
                         seconds=float(tot.trace_seconds))
        return Estimate(float(np.ravel(e.value)[0]), float(np.ravel(e.stderr)[0]), e.samples, e.seconds, e.method, "")

    def closed_form(self) -> tuple[Reference | None, str]:
        return None, "the geometric MTF of a real lens has no closed form here"


def cos_pupil_ratio_applies(lens: Lens, object_value: float, wavelength_nm: float,
                            device: str | None = None) -> tuple[bool, str]:
    """Whether the real pupil at ``object_value`` (rad) is the flat circular stop foreshortened (module
    docstring, rel-illum): the stop first and flat, and its rim's rays pass every other aperture."""
    from ...trace import RayBatch, trace
    if not math.isinf(lens.object_distance_mm):
        return False, "the object is not at infinity"
    s0 = lens.surfaces[0]
    if lens.stop_index != 0 or s0.curvature_per_mm != 0.0 or s0.asphere:
        return False, "the stop is not a flat first surface"
    if lens.iris.blades or lens.iris.obstruction_ratio:
        return False, "the iris is not a clear circle"
    rad = 0.9999 * float(s0.semi_diameter_mm)
    phi = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
    for th in (0.0, float(object_value)):
        d = np.tile([0.0, math.sin(th), math.cos(th)], (len(phi), 1))
        o = np.stack([rad * np.cos(phi), rad * np.sin(phi), np.zeros_like(phi)], axis=1) - d
        res = trace(lens, RayBatch(o, d, np.full(len(phi), float(wavelength_nm))), "float64", device)
        if not np.all(res.ok):
            return False, f"another aperture clips the beam at {math.degrees(th):g} deg"
    return True, "a flat circular stop first, nothing else clips: A(theta)/A(0) = cos(theta)"


class RelIllum:
    """``rel-illum``: relative illumination at normalised field ``hy`` (module docstring)."""

    name = "rel-illum"
    unit, display_unit, display_scale = "", "", 1.0
    sample_unit = "rays"
    samplers, precisions = SAMPLERS_ALL, _PRECISIONS
    reference_sampler, reference_precision = "sobol", "float64"

    def __init__(self, lens: Lens, hy: float, wavelength_nm: float | None = None, batches: int = 32,
                 device: str | None = None) -> None:
        from ...analysis.raysets import field_spec
        from ...analysis.compare.vignetting import mapping_factor
        self.lens, self.batches, self.device = lens, int(batches), device
        self.wavelength_nm = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
        spec = field_spec(lens, hy)
        self.object_value = float(spec.object_value)
        self.mapping = float(mapping_factor(lens, np.array([self.object_value]), self.wavelength_nm, device)[0][0])
        self.min_samples = 64 * self.batches
        self.label = f"relative illumination at {spec.label} ({self.wavelength_nm:g} nm)"

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        from ...analysis.compare.vignetting import relative_illumination_at
        return relative_illumination_at(self.lens, self.object_value, self.wavelength_nm, rays=int(samples),
                                        batches=self.batches, seed=seed, sampler=sampler, precision=precision,
                                        mapping=self.mapping, device=self.device)

    def closed_form(self) -> tuple[Reference | None, str]:
        ok, why = cos_pupil_ratio_applies(self.lens, self.object_value, self.wavelength_nm, self.device)
        if not ok:
            return None, why
        v = math.cos(self.object_value) * self.mapping
        return Reference(v, 0.0, 0, 0.0, "closed form",
                         f"cos(theta) x mapping factor {self.mapping:.9g} ({why}); cos^4 = "
                         f"{math.cos(self.object_value) ** 4:.9g}"), why


class BokehRegion:
    """``bokeh``: mean Y (lux) over a square region of one point source's bokeh spot (module docstring).

    ``region_fraction``: the region's side as a fraction of the footprint's larger side;
    ``region_offset``: its centre's offset from the footprint's centre in the same units (x, y).
    """

    name = "bokeh"
    unit, display_unit, display_scale = "lux", "lux", 1.0
    sample_unit = "rays"
    samplers, precisions = SAMPLERS_ALL, _PRECISIONS
    reference_sampler, reference_precision = "sobol", "float64"

    def __init__(self, lens: Lens, focus, source: dict, *, light: str = "D65", pixel_um: float | None = None,
                 window_px: int | None = None, batches: int = 32, region_fraction: float = 0.2,
                 region_offset: tuple[float, float] = (0.0, 0.0), device: str | None = None) -> None:
        from ...analysis.bokeh.entry import prepare_spot
        self.lens, self.focus, self.batches, self.device = lens, focus, int(batches), device
        self.plan = prepare_spot(lens, focus, source, light=light, pixel_um=pixel_um, window_px=window_px,
                                 batches=batches, device=device, batch_noise=True)
        if not self.plan.batch_noise:
            raise LensrtError("the bokeh window is too large for per-batch histograms", hint="a larger --pixel-um")
        f, (fx0, fx1, fy0, fy1) = self.plan.frame, self.plan.footprint[0]
        side = max(float(region_fraction) * max(fx1 - fx0, fy1 - fy0), f.pitch_mm)
        cx = 0.5 * (fx0 + fx1) + region_offset[0] * max(fx1 - fx0, fy1 - fy0)
        cy = 0.5 * (fy0 + fy1) + region_offset[1] * max(fx1 - fx0, fy1 - fy0)
        ix = [int(round((cx - 0.5 * side - f.x0_mm) / f.pitch_mm)), int(round((cx + 0.5 * side - f.x0_mm) / f.pitch_mm))]
        iy = [int(round((cy - 0.5 * side - f.y0_mm) / f.pitch_mm)), int(round((cy + 0.5 * side - f.y0_mm) / f.pitch_mm))]
        ix[1], iy[1] = max(ix[1], ix[0] + 1), max(iy[1], iy[0] + 1)
        if ix[0] < 0 or iy[0] < 0 or ix[1] > f.nx or iy[1] > f.ny:
            raise LensrtError("the bokeh region lies outside the spot's window", hint="a smaller region")
        self.region_px = (iy[0], iy[1], ix[0], ix[1])  # frame rows (sensor orientation) and columns
        self.min_samples = 64 * self.batches
        self.label = (f"bokeh: mean Y over {ix[1] - ix[0]} x {iy[1] - iy[0]} px at ({cx:.3f}, {cy:.3f}) mm, "
                      f"source {source['depth_mm'] / 1000.0:g} m")

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        from ...analysis.bokeh.trace import stream_windows
        p = self.plan
        outs = stream_windows(self.lens, p.obj, p.boxes, p.footprint, p.frame, self.focus.sensor_z_mm, p.light,
                              int(samples), sampler=sampler, seed=seed, batches=self.batches, precision=precision,
                              device=self.device, batch_noise=True)
        o = outs[0]
        r0, r1, c0, c1 = self.region_px
        bx = o.batch_xyz[:, 1, r0 - o.iy0:r1 - o.iy0, c0 - o.ix0:c1 - o.ix0].astype(np.float64)
        if bx.shape[1] != r1 - r0 or bx.shape[2] != c1 - c0:
            raise LensrtError("the bokeh region is not inside the source's window")  # pragma: no cover
        v, se = batch_means(bx.mean(axis=(1, 2)))
        return Estimate(float(v), float(se), int(o.stats["rays"]), float(o.stats["seconds"]),
                        f"batch means over {self.batches} batches", "lux")

    def closed_form(self) -> tuple[Reference | None, str]:
        return None, "a real lens's bokeh has no closed form here"


def converge_psf(setup, f, samplers: Sequence[str] = ("random", "stratified", "sobol"),
                 precisions: Sequence[str] = ("float32", "float64"), ray_counts: Sequence[int] | None = None,
                 reference_factor: int = 8, seed: int = 0, device: str | None = None, repeats: int = 1) -> dict:
    """Error against run time of the RMS spot radius at field ``f`` (``lensrt psf --converge``).

    :func:`converge` on :class:`lensrt.studies.convergence.quantities.PsfRms` with ray counts up to
    ``setup.rays``, a reference of ``reference_factor`` x the largest count (Sobol', float64) or the
    closed form where the lens has one. Besides :func:`converge`'s keys, ``runs`` carry ``rays``,
    ``value_mm``, ``stderr_mm``, ``error_mm`` (the first repeat's) and ``slopes`` carry
    ``slope_stderr_vs_seconds``, ``slope_stderr_vs_rays``, ``slope_error_vs_seconds``.
    """
    q = PsfRms(setup, f, device)
    counts = list(ray_counts) if ray_counts else default_ray_counts(setup.rays, setup.batches)
    ref, _ = q.closed_form()
    data = converge(q, counts, samplers, precisions, repeats=repeats, seed=seed,
                    reference=None if ref is not None else int(reference_factor * max(counts)))
    for r in data["runs"]:
        r.update({"rays": r["samples"], "value_mm": r["values"][0], "stderr_mm": r["stderrs"][0],
                  "error_mm": abs(r["values"][0] - data["reference"]["value"])})
    for s in data["slopes"]:
        s.update({"slope_stderr_vs_seconds": s["stderr_vs_seconds"], "slope_stderr_vs_rays": s["stderr_vs_samples"],
                  "slope_error_vs_seconds": s["error_vs_seconds"]})
    rf = data["reference"]
    data["reference"].update({"value_mm": rf["value"], "stderr_mm": rf["stderr"], "rays": rf["samples"],
                              "sampler": q.reference_sampler, "precision": q.reference_precision})
    data.update({"field": f.to_dict(), "reference_mm": list(q.geom.reference_mm), "grid": q.grid.to_dict(),
                 "ray_counts": data["counts"], "batches": setup.batches})
    return data
