"""Report section: the lens's configurations (zoom/focus positions) and its focus breathing.

With ``lensrt report LENS --config all`` the section tabulates every configuration
(:func:`lensrt.analysis.configurations.configuration_rows`) and plots the focal-length
curve; the other sections analyse the file's current configuration. For every lens it
measures focus breathing with real rays for the lens's own focus mechanism beside the
unit-focus formula (:func:`lensrt.analysis.focusing.focus_breathing`).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import LensrtError
from ..io.table import Table
from .model import MonteCarlo, ReportContext, Section

__all__ = ["zoom_section", "BREATHING_DISTANCES_M"]

#: focus distances (m from the first vertex) of the breathing curve; those closer than 10 focal lengths are dropped
BREATHING_DISTANCES_M = (math.inf, 10.0, 5.0, 3.0, 2.0, 1.5, 1.0, 0.7, 0.5)


def _configurations(ctx: ReportContext, sec: Section) -> None:
    from ..analysis.configurations import CONFIG_COLUMNS, configuration_rows, zoom_ratio
    from ..views.plots.zoom import plot_zoom_curve
    family = ctx.cache["configurations"]
    rows = configuration_rows(family)
    sec.data["configurations"] = rows
    sec.data["varying"] = [op.label for op in family.varying()]
    sec.text(f"{family.count} configurations (longest over shortest EFL {zoom_ratio(rows):.3f}); what changes: "
             f"{', '.join(sec.data['varying']) or 'nothing'}. The other sections analyse configuration "
             f"{family.names[family.current]!r} (the file's current one, marked *).")
    table = [[r[k] if k != "name" else r[k] + (" *" if r["current"] else "") for k, _ in CONFIG_COLUMNS]
             for r in rows]
    sec.table(Table(table, [h for _, h in CONFIG_COLUMNS], digits=4,
                    title="Per configuration: first-order data (z from the first vertex, mm), full field, and the "
                          "real distortion at the largest field"))
    path = plot_zoom_curve(ctx.path("zoom.png"), family.names, [r["efl_mm"] for r in rows],
                           [r["f_number"] for r in rows], family.name)
    sec.figure(path, "Focal length (left axis) and f-number (right axis) of each configuration.")
    _configuration_mtf(ctx, sec, family)


def _configuration_mtf(ctx: ReportContext, sec: Section, family) -> None:
    """Geometric S/T MTF per configuration at Hy 0, 0.7, 1 and the reference frequencies (p. 114)."""
    from ..analysis.configurations import configuration_mtf, mtf_table
    from ..analysis.psf.otf import reference_frequencies_cpmm
    from ..paraxial.photographic import sensor_format
    from ..views.plots.zoom import plot_zoom_mtf
    o = ctx.options
    freqs = reference_frequencies_cpmm(sensor_format(o.sensor).diagonal_mm)
    mtf = configuration_mtf(family, freqs, rays=o.preset.mtf_rays, device=ctx.device, seed=o.seed,
                            precision=o.precision)
    sec.data["mtf"] = [{k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in m.items()} for m in mtf]
    rows, heads = mtf_table(mtf)
    sec.table(Table(rows, heads, title=f"Per configuration: geometric MTF, sagittal / tangential, at the reference "
                                       f"frequencies (cycles/mm), {o.preset.mtf_rays} rays per field point, "
                                       "observed at the real best focus of the axial point (the image surface "
                                       "where that search fails: column focus)"))
    path = plot_zoom_mtf(ctx.path("zoom_mtf.png"), mtf, f"{family.name}: MTF per configuration")
    se = np.concatenate([np.ravel(m[k]) for m in mtf for k in ("sagittal_stderr", "tangential_stderr")])
    se_max = float(np.nanmax(se)) if np.isfinite(se).any() else 0.0
    rec = MonteCarlo("zoom_mtf.png", "MTF per configuration", sum(m["samples"] for m in mtf),
                     sum(m["seconds"] for m in mtf), f"largest {se_max:.2g} (MTF units) over configurations, fields "
                     "and reference frequencies", "jackknife over batches", se_max, "")
    sec.figure(path, "Sagittal (solid) and tangential (dashed) geometric MTF of each configuration at the "
                     f"reference frequencies, one colour per normalised field Hy. Rays: {rec.samples:,} in "
                     f"{rec.seconds:.1f} s; standard error: {rec.stderr}.")
    sec.mc(rec)


def _breathing(ctx: ReportContext, sec: Section) -> None:
    from ..analysis.focusing import focus_breathing, image_circle_radius_mm
    from ..views.plots.zoom import plot_breathing
    from ..paraxial import first_order
    from ..paraxial import photographic as ph
    lens = ctx.file_lens if "configurations" not in ctx.cache else ctx.cache["configurations"].configuration()
    lens = lens.replace(object_distance_mm=math.inf) if not math.isinf(lens.object_distance_mm) else lens
    fmt = ph.sensor_format(ctx.options.sensor or "full-frame")
    efl = abs(first_order(lens).efl_mm)
    dists = [d * 1000.0 for d in BREATHING_DISTANCES_M if d * 1000.0 >= 10.0 * efl]
    where = fmt.name
    try:
        curve = focus_breathing(lens, dists, fmt.diagonal_mm).to_dict()
    except LensrtError:  # no chief ray reaches the sensor corner: measure at 95 % of the lens's field
        circle = 2.0 * image_circle_radius_mm(lens)
        where = f"95 % of the image circle of the lens's largest field ({circle:.2f} mm; {fmt.name} is larger)"
        curve = focus_breathing(lens, dists, 0.95 * circle).to_dict()
    sec.data["breathing"] = curve
    path = plot_breathing(ctx.path("breathing.png"), curve, f"{lens.name}: focus breathing")
    change = curve["afov_real_deg"][-1] - curve["afov_real_deg"][0]
    formula = curve["afov_unit_focus_formula_deg"][-1] - curve["afov_unit_focus_formula_deg"][0]
    sec.text(f"Focus breathing ({curve['mechanism']}): from infinity to {dists[-1] / 1000.0:g} m the diagonal angle "
             f"of view on {where} changes by {change:+.2f} deg with real rays (the lens focused by its own "
             f"mechanism, real best focus on the sensor); the unit-focus formula of the Field Guide (p. 18) gives "
             f"{formula:+.2f} deg.")
    sec.figure(path, "Diagonal angle of view against focus distance: real chief rays to the sensor corner for the "
                     "lens's focus mechanism, and the unit-focus formula 2 atan(d / (2 b f)).")
    rows = [[d / 1000.0, a, u, t] for d, a, u, t in zip(curve["distance_mm"], curve["afov_real_deg"],
                                                         curve["afov_unit_focus_formula_deg"], curve["travel"])]
    sec.table(Table(rows, ["focus m", "AFoV real deg", "AFoV unit formula deg",
                           f"travel ({curve['travel_unit']})"], digits=4, title="Focus breathing"))


def zoom_section(ctx: ReportContext, sec: Section) -> None:
    """Per-configuration tables and the zoom curve (``--config all``), then focus breathing."""
    if "configurations" in ctx.cache and ctx.cache["configurations"].count > 1:
        _configurations(ctx, sec)
    else:
        sec.text("One configuration (give a multi-configuration lens and --config all for a table per zoom or "
                 "focus position).")
    _breathing(ctx, sec)
