"""Report sections 1-2: the prescription with a layout drawing, and first-order (ynu) data beside
the real-ray values."""
from __future__ import annotations

import math

import numpy as np

from ..io.table import Table
from .model import Figure, ReportContext, Section

__all__ = ["lens_section", "first_order_section"]


def lens_section(ctx: ReportContext, sec: Section) -> None:
    """Prescription table (``lensrt lens show``) and the cross-section with ray bundles."""
    from ..views.lens import describe_aperture, describe_fields, lens_table
    from ..views.plots.layout import plot_layout
    from ..analysis.raysets import lens_fields
    lens = ctx.lens
    obj = "infinity" if math.isinf(lens.object_distance_mm) else f"{lens.object_distance_mm:g} mm"
    wl = ", ".join(f"{w:g}" + (" (primary)" if i == lens.wavelengths.primary else "")
                   for i, w in enumerate(lens.wavelengths.nm))
    facts = [f"Aperture: {describe_aperture(lens)}; object at {obj}; fields: {describe_fields(lens)}.",
             f"Wavelengths: {wl} nm."]
    if lens.source:
        facts.insert(0, f"Source: {lens.source.rstrip('.')}.")
    if lens.iris.blades:
        facts.append(f"Iris: {lens.iris.blades} blades, rotation {math.degrees(lens.iris.rotation_rad):g} deg.")
    for n in ctx.lens_notes:
        facts.append(f"For this report the lens was {n}.")
    for f in facts:
        sec.text(f)
    rows, headers = lens_table(lens)
    table = Table(rows, headers, digits=4, title=f"Surfaces (image surface at z = {lens.image_z_mm:.4f} mm from "
                                                  "surface 1; * semi-diameter computed)")
    sec.data["surfaces"] = [dict(zip(headers, r)) for r in rows]
    hy = [f.hy for f in lens_fields(lens)]
    path = plot_layout(ctx.path("layout.png"), lens, hy, lens.wavelengths.primary_nm, device=ctx.device,
                       title=lens.name or "")
    fig = Figure(path.name, "Cross-section to the clear apertures with meridional ray bundles at each field of the "
                            "lens (rays spread over the vignetted pupil, primary wavelength); the stop and the "
                            "image surface are marked.")
    fig.wide = True
    sec.blocks += [("figure", fig), ("table", table)]


def _last_finite(a) -> float:
    a = np.asarray(a, dtype=np.float64)
    good = a[np.isfinite(a)]
    return float(good[-1]) if good.size else math.nan


def first_order_section(ctx: ReportContext, sec: Section) -> None:
    """``lensrt info`` data, and the same quantities from real rays where they have a real counterpart."""
    from ..views.first_order import first_order_rows, info_data, seidel_rows
    lens = ctx.lens
    d = info_data(lens)
    sec.data["first_order"] = d
    real_error = None
    try:
        c = ctx.comparison()
    except Exception as err:  # noqa: BLE001 - the paraxial half stands on its own
        c, real_error = None, err
    rows = _paraxial_real_rows(ctx, d, c)
    sec.table(Table(rows, ["quantity", "paraxial (ynu)", "real rays", "unit", "real value from"], digits=4,
                    title=f"First-order data at {d['wavelength_nm']:g} nm beside real rays "
                          "(z from the first vertex, +z toward the image)"))
    if real_error is not None:
        sec.errors.append(f"real-ray values missing: {real_error}")
    obj = "infinity" if d["object_distance_mm"] is None else f"{d['object_distance_mm']:g} mm from the first vertex"
    sec.details("All first-order data (lensrt info), object at " + obj,
                [("table", Table(first_order_rows(d), ["quantity", "value", "unit"]))])
    seidel = d["seidel"]
    tr = d["third_order_transverse"]
    sec.details("Seidel sums and CODE V's third-order table",
                [("table", Table(seidel_rows(lens, d), ["surf", "S_I sph", "S_II coma", "S_III ast", "S_IV ptz",
                                                         "S_V dist", "C_I axcol", "C_II latcol"], digits=6,
                                 title=f"Seidel sums (mm; Welford; colour {seidel['short_nm']:g} - "
                                       f"{seidel['long_nm']:g} nm)")),
                 ("table", Table([[tr[k] for k in tr]], [k.rsplit("_", 1)[0] if not k.startswith("PTZ")
                                                         else "PTZ 1/mm" for k in tr], digits=6,
                                 title="CODE V transverse third order, SUM row (mm at full aperture and field)"))])


def _paraxial_real_rows(ctx: ReportContext, d: dict, c) -> list[list]:
    """Rows (quantity, paraxial, real, unit, how) -- real cells "-" when the comparison is missing."""
    lens = ctx.lens
    rows: list[list] = []

    def add(q, par, real, unit, how):
        rows.append([q, par, real if c is not None else "-", unit, how])
    foc = pup = dist = bf = None
    if c is not None:
        k = int(np.argmin([abs(f.wavelength_nm - c.primary_nm) for f in c.focal]))
        foc, pup, dist, bf = c.focal[k], c.pupils, c.distortion[c.primary_nm], c.best_focus["polychromatic"]
    add("effective focal length", d["efl_mm"], foc and foc.real_efl_near_axis_mm, "mm",
        "-h / (n' sin U') of a ray parallel to the axis near it")
    add("focal length, marginal ray", d["efl_mm"], foc and _last_finite(foc.real_efl_mm), "mm",
        "the same for the ray at the entrance-pupil rim")
    if ctx.infinite:
        add("equivalent focal length y'/tan(theta)", d["efl_mm"], foc and foc.equivalent_focal_length_mm, "mm",
            "real chief ray at a small field angle")
    else:
        add("magnification", d["magnification"], foc and foc.real_magnification, "",
            "real chief ray y'/h at a small object height")
    add("image plane z", d["image_z_mm"], bf and bf.z_mm, "mm",
        "best focus: least RMS spot on axis, all wavelengths")
    add("image distance (last vertex to image)", d["image_distance_mm"],
        bf and bf.z_mm - lens.length_mm, "mm", "best focus minus the last vertex")
    add("entrance pupil z", d["entrance_pupil_z_mm"], pup and float(pup.entrance_pupil_z_mm[0]), "mm",
        "axis crossing of the real chief ray near the axis")
    add("entrance pupil diameter", d["entrance_pupil_diameter_mm"], pup and float(pup.entrance_tangential_mm[0]),
        "mm", "real rays at the rim of the stop")
    add("exit pupil z", d["exit_pupil_z_mm"], pup and float(pup.exit_pupil_z_mm[0]), "mm",
        "axis crossing of the real chief ray in image space")
    add("exit pupil diameter", d["exit_pupil_diameter_mm"], pup and float(pup.exit_tangential_mm[0]), "mm",
        "real rays at the rim of the stop")
    add("working f-number", d["working_f_number"], pup and pup.real_working_f_number, "",
        "1 / (2 n' sin U') of the real axial marginal ray")
    if c is not None:
        for s, i in zip(c.fields, c.field_index):
            if s.hy == 0:
                continue
            add(f"image height at {s.label}", float(dist.paraxial_height_mm[i]), float(dist.real_height_mm[i]), "mm",
                f"real chief ray on the paraxial image plane (distortion {dist.distortion_percent[i]:+.3f} %)")
    else:
        for h in d["field_image_heights_mm"][1:]:
            add("image height at a field of the lens", h, None, "mm", "")
    return rows
