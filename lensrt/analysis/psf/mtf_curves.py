"""MTF of real lenses: curves, against field, through focus, and the camera system (p. 108-118).

Built on the PSFs of :mod:`lensrt.analysis.psf.map` (each carries its sagittal and
tangential MTF at the reference frequencies and along a frequency axis, with
jackknife standard errors for geometric PSFs):

* :func:`mtf_curves` -- per field point: lens MTF (S, T) with standard errors,
  the diffraction limit of a clear circular pupil at the lens's paraxial working
  f-number (spectrum-weighted), the detector aperture MTF (square aperture of
  width pitch x sqrt(fill factor), p. 115), the 4-spot OLPF MTF (p. 117-118),
  and the system MTF = lens x OLPF x detector along each direction; the sensor
  Nyquist frequency 1 / (2 pitch);
* :func:`mtf_against_field` -- S and T MTF at the reference frequencies
  (10/20/40 lp/mm on full frame, scaled by 43.27 mm / diagonal for other
  formats, p. 114) against image height, with standard errors;
* :func:`through_focus` -- S and T MTF at chosen frequencies on planes shifted
  by ``dz_mm``, with the best focus per frequency (parabola through the peak):
  geometric PSFs from one stream call with a source per plane; diffraction PSFs
  from the exact defocus term added to the pupil function.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ..fields import FieldSpec
from .otf import (detector_mtf, peak_position, nyquist_cpmm, olpf_mtf, polychromatic_diffraction_mtf, system_mtf,
                  tangential_angle_rad)
from .result import PsfResult
from .setup import PsfSetup

__all__ = ["Detector", "mtf_curves", "mtf_against_field", "through_focus", "diffraction_limit_f_number",
           "reference_table"]


@dataclass(frozen=True)
class Detector:
    """Pixel pitch (um), fill factor (area fraction; square aperture of width pitch sqrt(ff)), and the
    4-spot OLPF's spot separation (um; 0 = no OLPF; default = the pitch, first zero at Nyquist)."""

    pixel_pitch_um: float = 4.0
    fill_factor: float = 1.0
    olpf_um: float | None = None

    def __post_init__(self) -> None:
        if not (self.pixel_pitch_um > 0 and math.isfinite(self.pixel_pitch_um)):
            raise LensrtError(f"pixel pitch {self.pixel_pitch_um} um must be a positive number")
        if not 0 < self.fill_factor <= 1:
            raise LensrtError(f"fill factor {self.fill_factor} must be within (0, 1]")
        if self.olpf_um is not None and not (self.olpf_um >= 0 and math.isfinite(self.olpf_um)):
            raise LensrtError(f"OLPF separation {self.olpf_um} um must be a number >= 0 (0: no OLPF)")

    @property
    def aperture_um(self) -> float:
        return self.pixel_pitch_um * math.sqrt(self.fill_factor)

    @property
    def separation_um(self) -> float:
        return self.pixel_pitch_um if self.olpf_um is None else float(self.olpf_um)

    @property
    def nyquist_cpmm(self) -> float:
        return nyquist_cpmm(self.pixel_pitch_um)

    def to_dict(self) -> dict:
        return {"pixel_pitch_um": self.pixel_pitch_um, "fill_factor": self.fill_factor,
                "aperture_um": self.aperture_um, "olpf_separation_um": self.separation_um,
                "nyquist_cpmm": self.nyquist_cpmm}


def diffraction_limit_f_number(lens: Lens) -> float:
    """The lens's paraxial working f-number (primary wavelength): the diffraction limit's N."""
    from ...paraxial import first_order
    return float(first_order(lens).working_f_number)


def _on_axis(values, n: int) -> np.ndarray:
    """``values`` (a curve that may stop early) on an axis of ``n`` frequencies, NaN past its end."""
    v = np.asarray(values, dtype=np.float64).ravel()
    out = np.full(n, np.nan)
    out[:min(n, v.size)] = v[:n]
    return out


def mtf_curves(result: PsfResult, lens: Lens, detector: Detector | None = None,
               freqs_cpmm: Sequence[float] | None = None) -> dict:
    """Lens, diffraction-limit, detector, OLPF and system MTF curves of one PSF (module docstring).

    Needs a result computed with ``setup.mtf_curve_cpmm`` (its estimates ``mtf_curve_sagittal`` and
    ``mtf_curve_tangential``). Arrays are over ``freqs_cpmm``; "S"/"T" curves along the sagittal and
    tangential directions.

    A wide PSF's grid may be too coarse for the highest frequencies asked for (its curve stops at the
    grid's Nyquist frequency, :mod:`lensrt.analysis.psf.geometric`). Given ``freqs_cpmm`` (the setup's
    ``mtf_curve_cpmm``), every array is on that common axis, the lens (and system) MTF NaN beyond the
    curve's end, which ``curve_ends_cpmm`` gives; so curves of several field points line up.
    """
    if "mtf_curve_sagittal" not in result.estimates:
        raise LensrtError("this PSF carries no MTF curve", hint="compute it with mtf_curve_cpmm set")
    own = np.asarray(result.metadata["mtf_curve_freqs_cpmm"], dtype=np.float64)
    f = own if freqs_cpmm is None else np.asarray(freqs_cpmm, dtype=np.float64)
    if f.size < own.size or not np.allclose(f[:own.size], own, rtol=1e-12, atol=0.0):
        raise LensrtError("the common frequency axis does not start with this PSF's curve frequencies",
                          hint="pass the setup's mtf_curve_cpmm")
    s, t = result.estimates["mtf_curve_sagittal"], result.estimates["mtf_curve_tangential"]
    n_w = diffraction_limit_f_number(lens)
    out = {"freqs_cpmm": f, "lens_sagittal": _on_axis(s.value, f.size),
           "lens_sagittal_stderr": _on_axis(s.stderr, f.size),
           "lens_tangential": _on_axis(t.value, f.size), "lens_tangential_stderr": _on_axis(t.stderr, f.size),
           "diffraction_limit": polychromatic_diffraction_mtf(f, result.wavelengths_nm, result.weights, n_w),
           "diffraction_f_number": n_w, "kind": result.kind, "reference_mm": list(result.reference_mm),
           "samples": result.samples, "seconds": result.seconds,
           "curve_ends_cpmm": float(own[-1]) if own.size else 0.0}
    if detector is not None:
        tang = tangential_angle_rad(result.reference_mm)
        for name, ang in (("sagittal", tang + 0.5 * math.pi), ("tangential", tang)):
            fx, fy = f * math.cos(ang), f * math.sin(ang)
            det = detector_mtf(fx, fy, detector.aperture_um)
            olpf = olpf_mtf(fx, fy, detector.separation_um) if detector.separation_um > 0 else np.ones_like(f)
            out[f"detector_{name}"] = det
            out[f"olpf_{name}"] = olpf
            out[f"system_{name}"] = system_mtf(out[f"lens_{name}"], olpf, det)
        out["detector"] = detector.to_dict()
        out["nyquist_cpmm"] = detector.nyquist_cpmm
    return out


def mtf_against_field(results: Sequence[PsfResult]) -> dict:
    """S and T MTF at the reference frequencies against image height |reference point| (sorted by it).

    Returns ``{"freqs_cpmm", "image_height_mm", "sagittal", "tangential", "sagittal_stderr",
    "tangential_stderr"}`` (arrays (n_field, n_freq)), ready for :func:`lensrt.views.plots.psf.plot_mtf_vs_field`,
    and ``samples`` and ``seconds`` (n_field) of each field's estimates.
    """
    rows = [r for r in results if "mtf_sagittal" in r.estimates]
    if not rows:
        raise LensrtError("no PSF carries MTF estimates at reference frequencies")
    # a coarse grid (wide PSF) leaves out reference frequencies past its Nyquist frequency: the
    # longest list is the common axis, the missing tail NaN
    freqs = max((r.metadata["mtf_freqs_cpmm"] for r in rows), key=len)
    rows = [r for r in rows if r.metadata["mtf_freqs_cpmm"] == freqs[:len(r.metadata["mtf_freqs_cpmm"])]]
    h = np.array([math.hypot(*r.reference_mm) for r in rows])
    order = np.argsort(h, kind="stable")
    pick = lambda key, attr: np.array([_on_axis(getattr(rows[i].estimates[key], attr), len(freqs))  # noqa: E731
                                       for i in order])
    return {"freqs_cpmm": np.asarray(freqs, dtype=np.float64), "image_height_mm": h[order],
            "sagittal": pick("mtf_sagittal", "value"), "tangential": pick("mtf_tangential", "value"),
            "sagittal_stderr": pick("mtf_sagittal", "stderr"), "tangential_stderr": pick("mtf_tangential", "stderr"),
            "samples": np.array([int(rows[i].estimates["mtf_sagittal"].samples) for i in order], dtype=np.int64),
            "seconds": np.array([float(rows[i].estimates["mtf_sagittal"].seconds) for i in order])}


def through_focus(setup: PsfSetup, f: FieldSpec, dz_mm: Sequence[float], freqs_cpmm: Sequence[float],
                  seed: int = 0, device: str | None = None, method: str | None = None) -> dict:
    """S/T MTF against focus shift ``dz_mm`` (from the setup's plane) at ``freqs_cpmm`` (module docstring).

    ``method`` "geometric" or "diffraction" (default: the setup's, "auto" resolved at the nominal plane).
    Returns ``{"focus_mm" (shifts), "plane_z_mm", "freqs_cpmm", "sagittal", "tangential" (n_focus, n_freq),
    "best_focus_mm": {"sagittal", "tangential"} (shifts, per frequency), "method", "samples", "seconds"}``;
    geometric runs add ``sagittal_stderr`` and ``tangential_stderr`` (jackknife over the batches).
    """
    import time
    from .geometric import prepare_field
    t0 = time.perf_counter()
    dz = np.asarray(dz_mm, dtype=np.float64)
    fr = np.asarray(freqs_cpmm, dtype=np.float64)
    if dz.size < 3:
        raise LensrtError("through-focus needs at least 3 focus positions")
    geom = prepare_field(setup, f, device)
    method = method or setup.method
    wset = None
    if method != "geometric":
        from .diffraction import WavefrontSet, choose_method
        wset = WavefrontSet(setup, geom, device)
        choice, _ = choose_method(setup.with_(method="auto") if method == "auto" else setup, wset)
        method = "geometric" if choice == "geometric" else "diffraction"
    tang = tangential_angle_rad(geom.reference_mm)
    angles = {"sagittal": tang + 0.5 * math.pi, "tangential": tang}
    stderr = None
    if method == "geometric":
        sag, tan, samples, stderr = _through_focus_geometric(setup, geom, dz, fr, angles, seed, device)
    else:
        from .diffraction import sampled_pupils, pupil_mtf_function
        pupils, _, _, _ = sampled_pupils(setup, wset)
        w = np.asarray(setup.spectrum.line_weights)
        sag, tan = [], []
        for z in dz:
            fn = pupil_mtf_function([p.with_defocus(float(z)) for p in pupils], w, setup.padding, geom.reference_mm)
            sag.append(fn(fr, angles["sagittal"]))
            tan.append(fn(fr, angles["tangential"]))
        sag, tan, samples = np.array(sag), np.array(tan), wset.rays
    out = {"focus_mm": dz, "plane_z_mm": setup.plane_z_mm + dz, "freqs_cpmm": fr, "sagittal": sag,
           "tangential": tan, "method": method, "field": f.to_dict(), "reference_mm": list(geom.reference_mm),
           "samples": int(samples), "seconds": time.perf_counter() - t0}
    if stderr is not None:  # jackknife over the batches (NaN where per-batch histograms did not fit)
        out["sagittal_stderr"], out["tangential_stderr"] = stderr["sagittal"], stderr["tangential"]
    out["best_focus_mm"] = {k: np.array([peak_position(dz, out[k][:, j]) for j in range(fr.size)])
                            for k in ("sagittal", "tangential")}
    return out


def _through_focus_geometric(setup: PsfSetup, geom, dz: np.ndarray, fr: np.ndarray, angles: dict, seed: int,
                             device: str | None):
    """One stream call, one source (and histogram layer) per plane, all on one grid shape."""
    from ...trace.stream import Grid, StreamSource, stream
    from ..grid import ImageGrid
    from .otf import mtf_along, mtf_estimate
    from .geometric import psf_window
    halves = []
    for z in (dz.min(), 0.0, dz.max()):
        foc = dict(setup.focus, z_mm=setup.plane_z_mm + float(z))
        halves.append(psf_window(setup.with_(focus=foc, pitch_um=None), geom, device)[2])
    half = max(halves)
    nyq_pitch_mm = 0.45 / max(float(fr.max()), 1e-9)
    pixels = int(min(1024, max(setup.pixels, math.ceil(2 * half / nyq_pitch_mm))))
    pitch_mm = max(2 * half / pixels, 1e-6) if setup.pitch_um is None else setup.pitch_um / 1000.0
    dc = np.asarray(geom.chief_direction)
    sources = []
    for k, z in enumerate(dz):
        c = (geom.reference_mm[0] + z * dc[0] / dc[2], geom.reference_mm[1] + z * dc[1] / dc[2])
        sources.append(StreamSource(geom.fp, geom.box, setup.plane_z_mm + float(z), c, k, "lambertian"))
    n_rays = max(setup.batches * 64, int(setup.rays))
    # per-batch histograms of every plane (for jackknife standard errors) while they fit in 256 MiB
    per_batch = setup.batches * len(dz) * pixels * pixels * 8 <= (256 << 20)
    res = stream(setup.lens, sources, Grid(pixels, pixels, pitch_mm), n_rays,
                 spectrum=setup.spectrum.trace_spectrum(), sampler=setup.sampler, seed=int(seed),
                 batches=setup.batches, precision=setup.precision, device=device, batch_histograms=per_batch)
    grid = ImageGrid.centred((pixels, pixels), pitch_mm * 1000.0, geom.reference_mm)
    sag, tan, se = [], [], {"sagittal": [], "tangential": []}
    for k in range(len(dz)):
        img = res.image(k)[::-1, :]  # rows top-down
        if not img.sum() > 0:
            raise LensrtError(f"no light on the PSF grid at focus shift {dz[k]:g} mm")
        fk = fr[fr <= 0.5 / grid.pitch_mm]
        pad = np.full(fr.size - fk.size, np.nan)
        sag.append(np.concatenate([mtf_along(img, grid, fk, angles["sagittal"], binned=True), pad]))
        tan.append(np.concatenate([mtf_along(img, grid, fk, angles["tangential"], binned=True), pad]))
        for name in se:
            if per_batch:
                e = mtf_estimate(res.batch_histograms[k, :, 0, ::-1, :], grid, fk, angles[name])
                se[name].append(np.concatenate([np.atleast_1d(e.stderr), pad]))
            else:
                se[name].append(np.full(fr.size, np.nan))
    return np.array(sag), np.array(tan), res.rays_total, {k: np.array(v) for k, v in se.items()}


def reference_table(fields: Sequence[FieldSpec], results: Sequence[PsfResult], freqs_cpmm: Sequence[float]
                    ) -> tuple[list[list], list[str]]:
    """Rows and headings of a table of S and T MTF at the reference frequencies per field point:
    label, image height, method, rays, seconds, then "value +- standard error" per frequency and
    direction ("-" where a coarse PSF grid left the frequency out; no error for deterministic MTFs)."""
    rows = []
    for f, r in zip(fields, results):
        s, t = r.estimates.get("mtf_sagittal"), r.estimates.get("mtf_tangential")
        cells = []
        for j in range(len(freqs_cpmm)):
            for e in (s, t):
                if e is None or j >= np.size(e.value):
                    cells.append("-")
                else:
                    v, se = float(np.atleast_1d(e.value)[j]), float(np.atleast_1d(e.stderr)[j])
                    cells.append(f"{v:.3f}" + (f" +- {se:.1g}" if se else ""))
        rows.append([f.label, f"{math.hypot(*r.reference_mm):.3f}", r.kind.replace("diffraction-", "d-"),
                     f"{r.samples:.3g}", r.seconds] + cells)
    heads = ["field", "height (mm)", "method", "rays", "seconds"]
    for v in freqs_cpmm:
        heads += [f"S {v:.3g}", f"T {v:.3g}"]
    return rows, heads
