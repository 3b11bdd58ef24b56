"""The handful of numbers at the top of the page: focal length, f-number, field, distortion and
illumination at the edge, spot sizes, MTF centre and corner, hyperfocal distance -- each taken
from a section's results (left out where that section failed)."""
from __future__ import annotations

import math
from typing import Any

from .model import ReportContext, Section

__all__ = ["key_numbers"]


def key_numbers(ctx: ReportContext, sections: list[Section]) -> list[dict[str, Any]]:
    """``[{"label", "value", "note", "section"}]`` in display order."""
    from ..paraxial import first_order
    out: list[dict[str, Any]] = []
    by_key = {s.key: s for s in sections}

    def add(label: str, value: str, note: str, section: str) -> None:
        out.append({"label": label, "value": value, "note": note, "section": section})
    fo = first_order(ctx.lens, None, math.inf)
    add("focal length", f"{fo.efl_mm:.2f} mm", "paraxial, primary wavelength", "first_order")
    c = ctx._comparison
    f_note = "paraxial"
    if c is not None:
        f_note = f"real working f/{c.pupils.real_working_f_number:.3g}"
    add("f-number", f"f/{fo.f_number:.3g}", f_note, "first_order")
    f = ctx.lens.fields
    if f.kind == "angle":
        add("field of view", f"{2 * math.degrees(f.max_radial):.1f}\u00b0", "full, of the lens file", "lens")
    if c is not None:
        d = c.distortion[c.primary_nm]
        i, spec = c.field_index[-1], c.fields[-1]
        if math.isfinite(d.distortion_percent[i]):
            add("distortion", f"{d.distortion_percent[i]:+.2f} %", f"at {spec.label}", "aberrations")
        vg = c.vignetting
        ri = vg.relative_illumination[-1]
        if math.isfinite(ri.value):
            add("corner illumination", f"{100 * ri.value:.0f} %", f"cos\u2074 alone {100 * vg.cos4[-1]:.0f} %",
                "image_quality")
        if c.spots:
            a, b = c.spots[0].estimates.get("rms_radius_mm"), c.spots[-1].estimates.get("rms_radius_mm")
            if a is not None and b is not None:
                add("RMS spot radius", f"{1e3 * a.value:.1f} / {1e3 * b.value:.1f} \u00b5m",
                    f"{c.spots[0].label} / {c.spots[-1].label}", "image_quality")
    mtf = by_key.get("mtf")
    if mtf is not None and mtf.ok and "mtf" in mtf.data:
        m = mtf.data["mtf"]["mtf_vs_field"]
        fr = m["freqs_cpmm"]
        j = min(1, len(fr) - 1)
        s, t, h = m["sagittal"], m["tangential"], m["image_height_mm"]
        add(f"MTF {fr[j]:.3g} cycles/mm", f"{s[0][j]:.2f} / {s[-1][j]:.2f}",
            f"S, centre / {h[-1]:.1f} mm (T {t[0][j]:.2f} / {t[-1][j]:.2f})", "mtf")
    dof = by_key.get("dof")
    if dof is not None and dof.ok and dof.data.get("depth_of_field"):
        row = dof.data["depth_of_field"]["against_f_number"][0]
        add("hyperfocal distance", f"{row['hyperfocal_m']:.1f} m",
            f"at {row['f_number']}, CoC {dof.data['depth_of_field']['coc_mm']:g} mm", "dof")
    return out
