"""Report sections 3-4 from :func:`lensrt.analysis.compare.comparison.compare_lens`: paraxial against real
(distortion, focus, spherical aberration, field curvature, colour), and spots, ray fans, pupils and
relative illumination against cos^4."""
from __future__ import annotations

import numpy as np

from .model import MonteCarlo, ReportContext, Section

__all__ = ["aberrations_section", "image_quality_section", "estimates_record"]


def estimates_record(figure: str, quantity: str, estimates: list, unit: str = "", scale: float = 1.0,
                     spec: str = ".2g") -> MonteCarlo:
    """One :class:`MonteCarlo` record for a list of :class:`lensrt.stats.Estimate` (one per field):
    total samples and seconds, and the largest standard error (``scale`` converts to ``unit``)."""
    est = [e for e in estimates if e is not None and np.isfinite(e.value)]
    if not est:
        return MonteCarlo(figure, quantity, 0, 0.0, "no estimates")
    se = np.array([float(e.stderr) for e in est]) * scale
    val = np.array([abs(float(e.value)) for e in est]) * scale
    k = int(np.argmax(se))
    rel = f" ({100.0 * se[k] / val[k]:.2g} % of its value)" if val[k] > 0 else ""
    text = f"largest {se[k]:{spec}} {unit}".rstrip() + rel + f" over {len(est)} field point{'s' * (len(est) > 1)}"
    return MonteCarlo(figure, quantity, int(sum(e.samples for e in est)), float(sum(e.seconds for e in est)),
                      text, est[0].method, float(se[k]), unit)


def aberrations_section(ctx: ReportContext, sec: Section) -> None:
    """Distortion, focus, spherical aberration, field curvature and colour: tables and figures."""
    from ..views.compare import comparison_header, comparison_tables
    from ..views.plots.analysis import plot_field_curvature_distortion, plot_grid_distortion, plot_longitudinal
    c = ctx.comparison()
    tables = comparison_tables(c)
    sec.text(comparison_header(c)[1] + f". Real rays traced in float64 on {c.device} in {c.seconds:.1f} s "
             "(the whole comparison, shared with the next section).")
    name = c.lens.name or "lens"
    p = c.primary_nm
    sec.figure(plot_field_curvature_distortion(ctx.path("field_curvature_distortion.png"), c.field_curvature[p],
                                               c.distortion[p], title=name),
               "Field curvature (sagittal and tangential foci, Petzval and third-order surfaces) and distortion "
               "against field.", wide=True)
    if c.grid is not None:
        sec.figure(plot_grid_distortion(ctx.path("grid_distortion.png"), c.grid),
                   "Grid distortion: ideal (paraxial) image points against the real chief rays.")
    sec.figure(plot_longitudinal(ctx.path("longitudinal.png"), c.lsa, c.chromatic, title=name),
               "Longitudinal spherical aberration against pupil zone per wavelength, with the third-order curve; "
               "chromatic focal shift.", wide=True)
    sec.table(tables["image_height"])
    if "fisheye_mapping" in tables:
        sec.text(tables["fisheye_mapping"])
    for key in ("field_curvature", "focal_length", "best_focus", "spherical_aberration", "axial_colour",
                "lateral_colour"):
        sec.table(tables[key])
    for n in c.notes:
        sec.text(f"Note: {n}.")
    sec.data["comparison"] = c.to_dict()


def image_quality_section(ctx: ReportContext, sec: Section) -> None:
    """Spot diagrams, ray and OPD fans, real pupils and relative illumination against cos^4."""
    from ..views.compare import comparison_tables
    from ..views.plots.analysis import (plot_opd_fans, plot_pupils, plot_ray_fans, plot_relative_illumination,
                                     plot_spots)
    from ..paraxial import first_order
    from ..units import NM_PER_MM, UM_PER_MM
    c = ctx.comparison()
    tables = comparison_tables(c)
    p = c.primary_nm
    if c.spots:
        fo = first_order(c.lens, p)
        airy = 1.22 * p / NM_PER_MM * fo.working_f_number
        rec = estimates_record("spots.png", "RMS spot radius about the chief ray",
                               [s.estimates.get("rms_radius_mm") for s in c.spots], "um", UM_PER_MM)
        sec.figure(plot_spots(ctx.path("spots.png"), c.spots, airy_radius_mm=airy),
                   f"Spot diagrams on the image surface, wavelengths coloured, one scale for all panels; the circle "
                   f"is the Airy radius {airy * UM_PER_MM:.2f} um. " + _mc_caption(rec), wide=True)
        sec.mc(rec)
    else:
        sec.text("No spot diagrams: " + "; ".join(c.notes or ["every ray is vignetted"]) + ".")
    if c.fans:
        sec.figure(plot_ray_fans(ctx.path("ray_fans.png"), c.fans),
                   "Transverse ray fans: e_y against Py (tangential) and e_x against Px (sagittal), um.")
        sec.figure(plot_opd_fans(ctx.path("opd_fans.png"), c.fans), "Optical path difference fans in waves.")
    vg = c.vignetting
    rec = estimates_record("relative_illumination.png", "relative illumination (flux method)",
                           vg.relative_illumination)
    sec.figure(plot_relative_illumination(ctx.path("relative_illumination.png"), vg),
               "Relative illumination of a uniform Lambertian object against field: the flux (Monte Carlo, "
               "+-2 standard errors) and exit-pupil methods, the unvignetted fraction, and cos^4. "
               + _mc_caption(rec))
    sec.mc(rec)
    sec.mc(estimates_record("relative_illumination.png", "unvignetted fraction of the pupil",
                            vg.vignetting_fraction))
    if c.pupils.outlines:
        sec.figure(plot_pupils(ctx.path("pupils.png"), c.pupils),
                   "The real entrance pupil seen from each field point (the rays that pass every aperture).")
    if c.spots:
        sec.table(tables["spots"])
    sec.table(tables["vignetting"])
    sec.table(tables["pupils"])


def _mc_caption(rec: MonteCarlo) -> str:
    return (f"Monte Carlo: {rec.samples:,} rays in {rec.seconds:.2f} s; standard error {rec.stderr}.")
