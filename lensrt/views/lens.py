"""What a person reads about a lens prescription: the surface table and one-line aperture/field descriptions
(shared by ``lensrt lens show`` and the report)."""
from __future__ import annotations

import math

__all__ = ["describe_aperture", "describe_fields", "lens_table", "clipping", "surface_kind", "APERTURE_RULE_TEXT"]


def describe_aperture(lens) -> str:
    ap = lens.aperture
    return {"epd": f"entrance pupil diameter {ap.value:g} mm", "image_fno": f"image-space f/{ap.value:g}",
            "object_na": f"object NA {ap.value:g}", "float_by_stop": "float by stop size"}[ap.kind]


def describe_fields(lens) -> str:
    f = lens.fields
    if f.kind == "angle":
        vals = ", ".join(f"{math.degrees(v):g}" for v in f.y)
        return f"angles {vals} deg"
    return f"{f.kind.replace('_', ' ')}s {', '.join(f'{v:g}' for v in f.y)} mm"


def clipping(lens, i: int) -> str:
    """What vignettes at surface ``i``: its semi-diameter (or not, under the aperture rule), its apertures."""
    s = lens.surfaces[i]
    parts = []
    if i == lens.stop_index:
        parts.append("stop")
    elif s.semi_diameter_mm is not None:
        parts.append("sd" if lens.clips_semi_diameter(i) else "none (sd not clipping)")
    parts += [a.describe() for a in s.apertures]
    return "; ".join(parts) or "none"


def surface_kind(s) -> str:
    """plane/sphere/conic/asph or the shape's kind (odd, qbfs, ...; ``ideal f=50`` for an ideal paraxial lens),
    with "mirror" and "tilt/dec" where they apply."""
    kind = "asph" if s.asphere else ("conic" if s.conic else ("plane" if s.curvature_per_mm == 0 else "sphere"))
    if getattr(s, "shape", None) is not None:
        kind = s.shape.kind
    if getattr(s, "ideal_focal_mm", None) is not None:
        kind = f"ideal f={s.ideal_focal_mm:g}"
    if s.mirror:
        kind += " mirror"
    if s.transform_before is not None or s.transform_after is not None:
        kind += " tilt/dec"
    return kind


#: the aperture rules in words (``lens show``)
APERTURE_RULE_TEXT = {
    "every_surface": "every_surface (every semi-diameter vignettes: the photographic reading, as pbrt's tables "
                     "mean it)",
    "opticstudio": "opticstudio (only user-defined semi-diameters, surface apertures and the stop vignette)"}


def lens_table(lens) -> tuple[list[list], list[str]]:
    """Rows and headers of the surface table at the primary wavelength (with what vignettes where)."""
    wl = lens.wavelengths.primary_nm
    n = lens.indices(wl)
    rows = []
    for i, s in enumerate(lens.surfaces):
        sd = s.semi_diameter_mm
        sd_text = "-" if sd is None else (f"{sd:.4f}" + ("*" if s.semi_diameter_auto else ""))
        rows.append(["STO" if s.is_stop else str(i + 1), s.radius_mm, s.thickness_mm,
                     s.material.describe() if not s.material.is_air else "air", float(n[i + 1]), sd_text,
                     s.conic, surface_kind(s), clipping(lens, i)])
    return rows, ["surf", "radius_mm", "thickness_mm", "material", f"n@{wl:g}nm", "semi_diam_mm", "conic", "type",
                  "vignettes"]
