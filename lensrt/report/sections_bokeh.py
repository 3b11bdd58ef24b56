"""Report sections 7-8: a bokeh map at a near and a far depth, and the depth-of-field /
hyperfocal tables for the lens on the chosen sensor (Field Guide p. 22-24)."""
from __future__ import annotations

import math

from ..io.table import Table
from .model import MonteCarlo, ReportContext, Section
from .options import default_near_focus_mm

__all__ = ["bokeh_section", "dof_section", "focus_distance_mm", "STANDARD_F_NUMBERS"]

#: full stops (and the usual marked values) for the hyperfocal table
STANDARD_F_NUMBERS = (1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 11.0, 16.0, 22.0, 32.0)

#: focus distances of the depth-of-field table, m from the first vertex
DOF_DISTANCES_M = (0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0)


def focus_distance_mm(ctx: ReportContext) -> tuple[float, str]:
    """The finite focus distance (mm from the first vertex) for bokeh and depth of field, and why."""
    d = ctx.options.object_distance_mm
    if d is None:
        d = ctx.lens.object_distance_mm
    if math.isfinite(d):
        return float(d), "the report's focus"
    from ..paraxial import first_order
    return (default_near_focus_mm(first_order(ctx.lens).efl_mm),
            "20 focal lengths: the report's focus is at infinity; choose another with --focus-m")


def bokeh_section(ctx: ReportContext, sec: Section) -> None:
    """``bokeh_near_far``: sources on a grid over the sensor, a near and a far one in each cell."""
    from ..analysis.bokeh.entry import bokeh_near_far, near_far_depths_mm
    from ..views.bokeh_files import write_bokeh_files
    from ..parallel.local import LocalExecutor
    from ..paraxial.photographic import sensor_format
    o, q = ctx.options, ctx.options.preset
    fmt = sensor_format(o.sensor)
    focus_mm, why = focus_distance_mm(ctx)
    near, far = near_far_depths_mm(focus_mm)
    width = q.bokeh_width_px
    pixels = (width, max(1, round(width * fmt.height_mm / fmt.width_mm)))
    with LocalExecutor(ctx.device) as ex:
        img = bokeh_near_far(ctx.lens, focus_mm, grid=q.bokeh_grid, pixels=pixels,
                             sensor_mm=(fmt.width_mm, fmt.height_mm), rays=q.bokeh_rays, executor=ex,
                             precision=o.precision, seed=o.seed, progress=ctx.progress)
    paths = write_bokeh_files(img, ctx.out_dir, "bokeh_map")
    d = img.to_dict()
    nz = d["noise"]
    noise = (f"per-pixel relative standard error of Y in the discs {nz['rel_stderr_median']:.2g} (median over "
             f"sources), {nz['rel_stderr_max']:.2g} (worst source)" if nz["rel_stderr_median"] is not None
             else "no disc reached the sensor")
    rec = MonteCarlo("bokeh_map.png", "bokeh map (CIE XYZ per pixel)", int(img.rays), float(img.seconds), noise,
                     nz["method"], nz["rel_stderr_max"], "relative")
    s = d["settings"]
    iris = s["iris"]
    sec.text(f"Focused at {focus_mm / 1000:.4g} m ({why}) by unit focusing; in each of the "
             f"{q.bokeh_grid[0]} x {q.bokeh_grid[1]} cells a point source at {near / 1000:.3g} m (left, foreground) "
             f"and at {far / 1000:.3g} m (right, background), depths with equal paraxial blur; sources placed by "
             f"their real chief rays, uniform on the {fmt.name} sensor; D65 light; "
             + ("circular iris" if not iris["blades"] else f"iris of {iris['blades']} blades")
             + f"; stop radius {s['stop_radius_mm']:.4g} mm.")
    sec.figure(paths["png"], "Bokeh map, upright as a photograph (sRGB, exposure at the 99.5th percentile): "
               "cat's eyes toward the corners come from mechanical vignetting, bright or soft rims from "
               f"spherical aberration, coloured rims from axial colour. Monte Carlo: {rec.samples:,} rays in "
               f"{rec.seconds:.1f} s; {noise}.", wide=True)
    sec.mc(rec)
    sec.files([(paths["exr"], "linear CIE XYZ (Y = illuminance on the sensor, lux) and the per-pixel relative "
                              "standard error of Y"),
               (paths["json"], "every source: object point, depth, pupil transmission, centroid and RMS radius "
                               "with standard errors, rays, seconds")])
    sec.data["bokeh"] = {k: v for k, v in d.items() if k != "sources"}
    sec.data["bokeh"]["focus_distance_mm"] = focus_mm
    sec.data["bokeh"]["depths_mm"] = [near, far]


def dof_section(ctx: ReportContext, sec: Section) -> None:
    """Angle of view, depth of field against focus distance, hyperfocal distance against f-number."""
    from ..views.first_order import info_data
    from ..paraxial import first_order
    from ..paraxial import photographic as ph
    o = ctx.options
    lens = ctx.lens
    fmt = ph.sensor_format(o.sensor)
    c = fmt.coc_mm if o.coc_mm is None else float(o.coc_mm)
    focus_mm, why = focus_distance_mm(ctx)
    info = info_data(lens, None, focus_mm, o.sensor, c)["sensor"]
    fo = first_order(lens, None, math.inf)
    f, n0, s_ep, z_ep = fo.front_focal_length_mm, fo.f_number, fo.entrance_pupil_distance_mm, fo.entrance_pupil_z_mm
    a = info["afov_deg"]
    sec.text(f"Sensor {info['name']} ({info['width_mm']:g} x {info['height_mm']:g} mm), circle of confusion "
             f"{c:g} mm (p. 22), crop factor {info['crop_factor']:.3f}, equivalent focal length "
             f"{info['equivalent_focal_length_mm']:.1f} mm; angle of view at {focus_mm / 1000:.4g} m "
             f"(bellows factor {info['bellows_factor']:.3f}): horizontal {a['horizontal']:.1f}, vertical "
             f"{a['vertical']:.1f}, diagonal {a['diagonal']:.1f} deg.")
    sec.text("Distances in metres from the lens's first vertex (focused there by unit focusing); the formulas "
             f"use distances from the entrance pupil, which lies {z_ep:.1f} mm behind the first vertex "
             f"(s_EP = {s_ep:.2f} mm, p. 23-24).")
    near_limit_mm = -fo.front_focal_z_mm + 1.0  # closer than the front focal point there is no real image
    dists = sorted({d for d in DOF_DISTANCES_M if d * 1000.0 > 2.0 * near_limit_mm} | {focus_mm / 1000.0})
    hyper = ph.hyperfocal_distance_mm(f, n0, c, s_ep) - z_ep

    def m(v_from_ep: float) -> float:
        return (v_from_ep - z_ep) / 1000.0 if math.isfinite(v_from_ep) else math.inf
    rows_focus = []
    for dm in dists + [hyper / 1000.0]:
        dof = ph.depth_of_field_mm(dm * 1000.0 + z_ep, f, n0, c, s_ep)
        label = f"{dm:.3g}" + (" (hyperfocal)" if dm == hyper / 1000.0 else "") \
            + (" (report focus)" if abs(dm * 1000.0 - focus_mm) < 1e-6 else "")
        rows_focus.append([label, m(dof.near_mm), m(dof.far_mm), dof.total_mm / 1000.0])
    sec.table(Table(rows_focus, ["focus (m)", "near limit (m)", "far limit (m)", "depth of field (m)"], digits=3,
                    title=f"Depth of field at f/{n0:.3g} on {fmt.name}, CoC {c:g} mm"))
    stops = [n0] + [n for n in STANDARD_F_NUMBERS if n > n0 * 1.05]
    rows_stops = []
    for n in stops:
        h = ph.hyperfocal_distance_mm(f, n, c, s_ep)
        dof = ph.depth_of_field_mm(focus_mm + z_ep, f, n, c, s_ep)
        rows_stops.append([f"f/{n:.3g}", m(h), m(0.5 * h) if math.isfinite(h) else math.inf,
                     m(dof.near_mm), m(dof.far_mm), dof.total_mm / 1000.0])
    sec.table(Table(rows_stops, ["f-number", "hyperfocal (m)", "near limit at hyperfocal (m)",
                           f"near at {focus_mm / 1000:.3g} m", f"far at {focus_mm / 1000:.3g} m",
                           "depth of field (m)"], digits=3,
                    title=f"Hyperfocal distance and depth of field against f-number, focus {focus_mm / 1000:.4g} m "
                          f"({why})"))
    sec.data["sensor"] = info
    sec.data["depth_of_field"] = {
        "coc_mm": c, "focus_mm": focus_mm, "f_number": n0, "distances": "m from the first vertex",
        "against_focus": [dict(zip(["focus_m", "near_m", "far_m", "total_m"], r)) for r in rows_focus],
        "against_f_number": [dict(zip(["f_number", "hyperfocal_m", "hyperfocal_near_m", "near_m", "far_m", "total_m"],
                                      r)) for r in rows_stops]}
