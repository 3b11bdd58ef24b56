"""Report sections 5-6: a PSF map over the sensor, and MTF curves (against frequency, against
field at the reference frequencies, the camera system) with the diffraction limit."""
from __future__ import annotations


import numpy as np

from ..errors import LensrtError
from ..io.table import Table
from .model import MonteCarlo, ReportContext, Section
from .sections_compare import estimates_record

__all__ = ["psf_section", "mtf_section", "psf_focus"]

#: share of ``--time-budget`` for the PSF map (the rest goes to the MTF fields)
PSF_BUDGET_SHARE = 0.5


def psf_focus(ctx: ReportContext) -> dict:
    """The observation plane of the PSFs and MTFs: best focus (least axial RMS spot, primary
    wavelength), searched once and shared by both sections."""
    if "psf_focus" not in ctx.cache:
        from ..analysis.psf.focus import focus_plane
        ctx.cache["psf_focus"] = focus_plane(ctx.lens, "best", ctx.device)
    return ctx.cache["psf_focus"]


def _executor(ctx: ReportContext):
    from ..parallel.local import LocalExecutor
    return LocalExecutor(ctx.device)


def _groups(ctx: ReportContext, n_fields: int) -> int | None:
    """Work items of a map: the stage's default on every device (one group on one device: the fewest
    launches, the same count on a CPU and a GPU; the map is the same bits for any grouping)."""
    return None


def _budget(ctx: ReportContext, share: float, n_fields: int) -> dict:
    """Setup keywords for a time budget: seconds per field and the high preset's rays as the cap."""
    from .options import QUALITIES
    t = ctx.options.time_budget_s
    if t is None:
        return {}
    return {"time_budget_s": max(share * t / max(n_fields, 1), 0.05), "rays": QUALITIES["high"].psf_rays}


def psf_section(ctx: ReportContext, sec: Section) -> None:
    """Geometric PSFs on a grid over the sensor (``lensrt psf --grid``): PNG mosaic, EXR, JSON."""
    from ..analysis.fields import sensor_grid_fields
    from ..analysis.psf.otf import reference_frequencies_cpmm
    from ..analysis.psf.map import run_psf_map
    from ..analysis.psf.setup import make_setup
    from ..views.psf_files import write_psf_outputs
    from ..paraxial.photographic import sensor_format
    from ..units import UM_PER_MM
    o, q = ctx.options, ctx.options.preset
    fmt = sensor_format(o.sensor)
    rows_cols = q.psf_grid
    opts = dict(method="geometric", rays=q.psf_rays, pixels=q.psf_pixels, precision=o.precision,
                mtf_freqs_cpmm=tuple(float(v) for v in reference_frequencies_cpmm(fmt.diagonal_mm)))
    opts.update(_budget(ctx, PSF_BUDGET_SHARE, rows_cols[0] * rows_cols[1]))
    setup = make_setup(ctx.lens, None, psf_focus(ctx), ctx.device, **opts)
    half = 0.5 * fmt.diagonal_mm
    radius, why = usable_image_radius(ctx, setup.plane_z_mm, half)
    for attempt, shrink in enumerate((1.0, 0.8, 0.6)):
        scale = shrink * radius / half
        grid_sensor = o.sensor if scale == 1.0 else f"{fmt.width_mm * scale:.4g}x{fmt.height_mm * scale:.4g}"
        fields = sensor_grid_fields(ctx.lens, grid_sensor, rows_cols, setup.plane_z_mm, ctx.device)
        try:
            with _executor(ctx) as ex:
                pmap = run_psf_map(setup, fields, o.seed, ex, ctx.progress, rows_cols, grid_sensor,
                                      groups=_groups(ctx, len(fields)))
            break
        except LensrtError as err:
            if attempt == 2:
                raise
            why += f" A grid {100 * scale:.0f} % of the sensor failed ({err}); the grid was pulled in."
    if scale < 1.0:
        why += (f" The grid spans {fmt.width_mm * scale:.3g} x {fmt.height_mm * scale:.3g} mm "
                f"({100 * scale:.0f} % of the sensor).")
    files = write_psf_outputs(ctx.out_dir, pmap, "psf", log=True)
    rec = estimates_record("psf.png", "PSF RMS radius", [r.estimates.get("rms_radius_mm") for r in pmap.results],
                           "um", UM_PER_MM)
    rec.samples, rec.seconds = pmap.rays, pmap.seconds
    foc = setup.focus
    sec.text(f"{rows_cols[0]} x {rows_cols[1]} image positions over the {fmt.name} sensor "
             f"({fmt.width_mm:g} x {fmt.height_mm:g} mm), corners included, each placed by its real chief ray; "
             f"focus: {foc['focus']} (z = {setup.plane_z_mm:.4f} mm, {foc['shift_from_image_mm']:+.4f} mm from the "
             f"image surface); spectrum: {setup.spectrum.name}; {setup.sampler} samples, {setup.precision}."
             + (" " + why.strip() if why else ""))
    sec.figure(files["png"], f"Geometric PSFs (Monte Carlo rays through the real, vignetted pupil), log10 of each "
                             f"tile's peak down to 1e-6, with a um scale bar. Monte Carlo: {rec.samples:,} rays in "
                             f"{rec.seconds:.1f} s; standard error of the RMS radius: {rec.stderr}.", wide=True)
    sec.mc(rec)
    rows = []
    for f, r in zip(pmap.fields, pmap.results):
        rows.append([f.label, f"{r.reference_mm[0]:.2f}, {r.reference_mm[1]:.2f}", f"{r.samples:.3g}", r.seconds,
                     _pm(r, "rms_radius_mm"), _pm(r, "ee50_radius_mm"), _pm(r, "ee80_radius_mm")])
    sec.details("PSF of every grid point: rays, seconds, RMS and encircled-energy radii (um, +- one standard error)",
                [("table", Table(rows, ["field", "chief ray x, y (mm)", "rays", "seconds", "RMS radius",
                                        "EE50 radius", "EE80 radius"], digits=3))])
    sec.files([(files["exr"], "every PSF as a layer of one multi-layer EXR (1/mm^2, with per-pixel standard "
                              "errors; read with lensrt.views.psf_files.read_psf_map_exr)"),
               (files["json"], "the same without pixels: fields, estimates, run")])
    sec.data["psf_map"] = {"grid": list(rows_cols), "sensor": fmt.name, "grid_sensor": grid_sensor,
                           "rays_total": pmap.rays,
                           "seconds": pmap.seconds, "setup": setup.to_dict(), "files": files}


def usable_image_radius(ctx: ReportContext, plane_z_mm: float, half_diagonal_mm: float) -> tuple[float, str]:
    """The image radius the PSF and MTF fields may reach: the sensor's half-diagonal, or 90 % of the
    largest real chief-ray height when the lens covers less (a circular fisheye); and why."""
    from ..analysis.fields import chief_height_table
    cover = chief_height_table(ctx.lens, plane_z_mm, device=ctx.device).max_height_mm
    if 0.98 * cover >= half_diagonal_mm:
        return half_diagonal_mm, ""
    r = 0.9 * cover
    return r, (f"The lens's real chief rays reach {cover:.2f} mm at most, less than the sensor's half-diagonal "
               f"{half_diagonal_mm:.2f} mm: the field points stay within {r:.2f} mm.")


def _pm(r, key: str) -> str:
    from ..units import UM_PER_MM
    e = r.estimates.get(key)
    if e is None:
        return "-"
    if e.stderr:
        return f"{float(e.value) * UM_PER_MM:.4g} +- {float(e.stderr) * UM_PER_MM:.2g}"
    return f"{float(e.value) * UM_PER_MM:.4g}"


def mtf_section(ctx: ReportContext, sec: Section) -> None:
    """MTF curves at real image heights from the centre to the corner of the sensor, against field at
    10/20/40 lp/mm (scaled to the format), and the system MTF with the sensor's pixels."""
    from ..analysis.psf.otf import reference_frequencies_cpmm
    from ..analysis.psf.mtf_curves import Detector, mtf_against_field, mtf_curves, reference_table
    from ..analysis.psf.map import run_psf_map
    from ..analysis.psf.setup import make_setup
    from ..analysis.fields import image_height_fields
    from ..views.plots.psf import plot_mtf_curves, plot_mtf_vs_field, plot_system_mtf
    from ..io.table import write_json
    from ..paraxial.photographic import sensor_format
    from ..views.plots.figure import defer
    o, q = ctx.options, ctx.options.preset
    fmt = sensor_format(o.sensor)
    detector = Detector(o.pixel_pitch_um)
    fmax = 2.0 * detector.nyquist_cpmm
    freqs = np.linspace(0.0, fmax, q.mtf_freqs)
    ref = tuple(float(v) for v in reference_frequencies_cpmm(fmt.diagonal_mm))
    # the PSF grids' pitch is capped so that their Nyquist frequency passes the largest reference
    # frequency (not fmax: a wide aberrated PSF would need thousands of pixels); curves of such fields
    # stop at their grid's Nyquist frequency
    opts = dict(method=q.mtf_method, rays=q.mtf_rays, precision=o.precision, mtf_freqs_cpmm=ref,
                mtf_curve_cpmm=tuple(float(v) for v in freqs), pixels=q.psf_pixels,
                max_pitch_um=0.45e3 / max(ref), target_quantity="mtf")
    foc = psf_focus(ctx)
    setup = make_setup(ctx.lens, None, foc, ctx.device, **opts)
    radius, why = usable_image_radius(ctx, setup.plane_z_mm, 0.5 * fmt.diagonal_mm)
    heights = [round(float(v), 3) for v in np.linspace(0.0, radius, q.mtf_fields)] if ctx.lens.fields.max_radial > 0 \
        else [0.0]
    setup = setup.with_(**_budget(ctx, 1.0 - PSF_BUDGET_SHARE, len(heights))) if o.time_budget_s else setup
    dropped = []
    while True:
        fields = image_height_fields(ctx.lens, heights, setup.plane_z_mm, ctx.device)
        try:
            with _executor(ctx) as ex:
                pmap = run_psf_map(setup, fields, o.seed, ex, ctx.progress, None, None,
                                      groups=_groups(ctx, len(fields)))
            break
        except LensrtError as err:
            if len(heights) <= 2:
                raise
            dropped.append(f"{heights[-1]:g} mm ({err})")
            heights = heights[:-1]
    if dropped:
        why += " Left out: " + "; ".join(dropped) + "."
    curves = [mtf_curves(r, ctx.lens, detector, freqs) for r in pmap.results]
    vs_field = mtf_against_field(pmap.results)
    name = ctx.lens.name or "lens"
    sel = list(range(len(curves))) if len(curves) <= 4 else \
        sorted({0, len(curves) // 3, (2 * len(curves)) // 3, len(curves) - 1})
    c0 = curves[0]
    kinds = sorted({r.kind for r in pmap.results})
    p1 = plot_mtf_curves(ctx.path("mtf.png"), c0["freqs_cpmm"],
                         [(pmap.fields[i].label, curves[i]["lens_sagittal"], curves[i]["lens_tangential"])
                          for i in sel], diffraction=c0["diffraction_limit"], nyquist_cpmm=c0.get("nyquist_cpmm"),
                         title=f"{name}\nlens MTF (S solid, T dashed), diffraction limit f/"
                               f"{c0['diffraction_f_number']:.3g}")
    p2 = plot_mtf_vs_field(ctx.path("mtf_field.png"), vs_field,
                           title=f"{name}\nMTF against image height at {', '.join(f'{v:.3g}' for v in ref)} "
                                 "cycles/mm (S solid, T dashed)")
    p3 = plot_system_mtf(ctx.path("mtf_system.png"), c0,
                         title=f"{name}, {pmap.fields[0].label}\nsystem MTF = lens x OLPF x detector "
                               f"({detector.pixel_pitch_um:g} um pixels)")
    rec = _mtf_record(pmap, vs_field)
    sec.text(f"{len(fields)} real image heights from the centre to the corner of the {fmt.name} sensor; "
             f"focus as the PSF map; method {setup.method}"
             + (f" (used: {', '.join(k.replace('diffraction-', 'diffraction, ') for k in kinds)})"
                if setup.method == "auto" else "") + ". Reference frequencies "
             f"10/20/40 lp/mm on full frame scaled by 43.27 mm / diagonal (p. 114): "
             f"{', '.join(f'{v:.3g}' for v in ref)} cycles/mm. The diffraction limit is that of a clear circular "
             f"pupil at the paraxial working f-number (p. 112); a geometric MTF leaves diffraction out. A curve "
             "stops at its PSF grid's Nyquist frequency where a wide PSF needs a coarser grid."
             + (" " + why.strip() if why else ""))
    sec.figure(p1, "Sagittal (solid) and tangential (dashed) MTF against frequency at "
               f"{len(sel)} image heights, the diffraction limit in grey, the sensor Nyquist frequency dotted. "
               + _mtf_caption(rec))
    sec.figure(p2, "MTF against image height at the reference frequencies. " + _mtf_caption(rec))
    sec.mc(rec)
    rows, heads = reference_table(pmap.fields, pmap.results, ref)
    sec.table(Table(rows, heads, digits=3, title="MTF at the reference frequencies (cycles/mm), +- one standard "
                                                 "error (none for deterministic diffraction MTFs)"))
    wfe = _wavefront_rows(ctx, foc, fields)
    if wfe:
        sec.table(Table([[r["field"], r.get("rms_waves_no_tilt", "-"), r.get("pv_waves", "-"), r.get("strehl", "-"),
                          r.get("strehl_marechal", "-"), r.get("error", "")] for r in wfe],
                        ["field", "RMS WFE no tilt (waves)", "PV (waves)", "Strehl", "Marechal", "note"], digits=4,
                        title=f"Wavefront error and Strehl ratio against field at {ctx.lens.wavelengths.primary_nm:g} nm, "
                              "same focus, reference sphere on the chief ray (lensrt wavefront); deterministic"))
    sec.figure(p3, "Lens, 4-spot OLPF, detector aperture and system MTF on axis "
                   f"({detector.pixel_pitch_um:g} um pixels, fill factor 1, OLPF spot separation = pitch).")
    out = {"lens": ctx.lens.name, "setup": setup.to_dict(), "sensor": fmt.name, "detector": detector.to_dict(),
           "reference_freqs_cpmm": list(ref), "seconds": pmap.seconds, "rays_total": pmap.rays,
           "fields": [dict(label=f.label, **c) for f, c in zip(fields, curves)], "mtf_vs_field": vs_field}
    defer(write_json, ctx.path("mtf.json"), out)  # by a figure worker process where there is one
    sec.files([("mtf.json", "curves (lens, diffraction limit, detector, OLPF, system) with standard errors, and "
                            "MTF against field")])
    sec.data["mtf"] = {"reference_freqs_cpmm": list(ref), "mtf_vs_field": vs_field, "seconds": pmap.seconds,
                       "rays_total": pmap.rays, "methods": kinds, "wavefront_vs_field": wfe}


def _wavefront_rows(ctx: ReportContext, focus: dict, fields) -> list[dict]:
    """RMS wavefront error and Strehl ratio at the MTF's field points (primary wavelength, same focus)."""
    from ..analysis.psf.setup import make_setup
    from ..analysis.psf.spectrum import line_spectrum
    from ..analysis.psf.wavefront_error import wavefront_error_table
    setup = make_setup(ctx.lens, line_spectrum([ctx.lens.wavelengths.primary_nm]), focus, ctx.device,
                       method="diffraction", pupil_samples=64)
    return wavefront_error_table(setup, fields, device=ctx.device)


def _mtf_record(pmap, vs_field: dict) -> MonteCarlo:
    se = np.concatenate([np.ravel(vs_field["sagittal_stderr"]), np.ravel(vs_field["tangential_stderr"])])
    mc = [r for r in pmap.results if r.kind == "geometric"]
    n_det = len(pmap.results) - len(mc)
    note = f"; {n_det} of {len(pmap.results)} fields diffraction (deterministic)" if n_det else ""
    text = f"largest {float(np.nanmax(se)) if se.size else 0.0:.2g} (MTF units) over fields and reference " \
           f"frequencies{note}"
    return MonteCarlo("mtf.png, mtf_field.png", "MTF at the reference frequencies", pmap.rays, pmap.seconds, text,
                      "jackknife over batches" if mc else "deterministic",
                      float(np.nanmax(se)) if se.size else 0.0, "")


def _mtf_caption(rec: MonteCarlo) -> str:
    return f"Rays: {rec.samples:,} in {rec.seconds:.1f} s; standard error: {rec.stderr}."
