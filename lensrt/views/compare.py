"""The terminal report of ``lensrt compare``: tables built from a :class:`lensrt.analysis.compare.comparison.Comparison`."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..io.table import Table

if TYPE_CHECKING:  # pragma: no cover
    from ..analysis.compare.comparison import Comparison

__all__ = ["comparison_text", "comparison_header", "comparison_tables"]


def _f(v: float, spec: str = ".4f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, spec)


def _est(e, spec: str = ".4f") -> str:
    if not math.isfinite(e.value):
        return "-"
    return f"{e.value:{spec}} +- {e.stderr:.1g}"


def _last_finite(a) -> float:
    a = np.asarray(a, dtype=np.float64)
    good = a[np.isfinite(a)]
    return float(good[-1]) if good.size else math.nan


def comparison_header(c: "Comparison") -> list[str]:
    """The first lines of the text: lens, device, seconds, wavelengths, fields, object."""
    lens, p = c.lens, c.primary_nm
    return [f"{lens.name or lens.path}: paraxial against real ({c.device}, {c.seconds:.1f} s)",
            "wavelengths " + ", ".join(f"{w:g}" + (" (primary)" if w == p else "") for w in c.wavelengths_nm)
            + " nm; fields " + ", ".join(s.label for s in c.fields)
            + ("; object at infinity" if c.infinite else f"; object {lens.object_distance_mm:g} mm from the first vertex")
            + "; z from the first vertex"]


def comparison_text(c: "Comparison") -> str:
    """All tables (see :mod:`lensrt.analysis.compare.comparison`)."""
    out = comparison_header(c) + [""]
    first = True
    for item in comparison_tables(c).values():
        if isinstance(item, Table):
            if not first:
                out.append("")
            out.append(item.text())
            first = False
        else:
            out.append(item)
    out += [f"note: {n}" for n in c.notes]
    return "\n".join(out)


def comparison_tables(c: "Comparison") -> dict[str, "Table | str"]:
    """The tables of :func:`comparison_text`, in order, by name (``focal_length``, ``image_height``,
    ``best_focus``, ``spherical_aberration``, ``field_curvature``, ``axial_colour``, ``lateral_colour``,
    ``pupils``, ``vignetting``, ``spots``); a ``str`` value is a line that belongs under the table
    before it (``fisheye_mapping``)."""
    from ..paraxial import first_order
    lens, p = c.lens, c.primary_nm
    fo = first_order(lens, p)
    fkey = c.field_key
    out: dict[str, Table | str] = {}
    if c.infinite:
        rows = [[f.wavelength_nm, f.paraxial_efl_mm, f.real_efl_near_axis_mm, _last_finite(f.real_efl_mm),
                 f.equivalent_focal_length_mm if f.equivalent_focal_length_mm is not None else math.nan]
                for f in c.focal]
        heads = ["wavelength_nm", "paraxial 1/Phi", "real, near axis", "real, marginal ray",
                 "y'/tan(theta), small angle"]
    else:
        rows = [[f.wavelength_nm, f.paraxial_efl_mm, f.real_efl_near_axis_mm, _last_finite(f.real_efl_mm),
                 f.paraxial_magnification, f.real_magnification] for f in c.focal]
        heads = ["wavelength_nm", "paraxial 1/Phi", "real, near axis", "real, marginal ray", "paraxial m",
                 "real m = y'/h, small h"]
    out["focal_length"] = Table(rows, heads, digits=5,
                            title="Focal length (mm): real EFL = -h / (n' sin U') of a ray parallel to the axis at "
                                  "height h (marginal: the largest traced h up to the entrance-pupil radius at infinity)")
    d = c.distortion[p]
    fish = c.infinite and max(s.object_value for s in c.fields) > math.radians(45.0)
    rows, heads = [], [fkey, "paraxial y'_mm", "real y'_mm", "distortion_%", "CODE V dist_%"]
    if fish:
        heads += ["f-theta_mm", "equisolid_mm", "stereogr_mm"]
    for s, i in zip(c.fields, c.field_index):
        r = [c.field_number(s), d.paraxial_height_mm[i], d.real_height_mm[i], d.distortion_percent[i],
             d.distortion_codev_percent[i]]
        if fish:
            r += [d.mapping_height_mm[k][i] for k in ("equidistant", "equisolid", "stereographic")]
        rows.append(r)
    title = (f"Image height at {p:g} nm on the paraxial image plane (z {fo.image_z_mm:.4f} mm); distortion "
             f"100 (y_real - y_par)/y_par, CODE V's referred to the image surface (z {lens.image_z_mm:.4f} mm)")
    out["image_height"] = Table(rows, heads, digits=4, title=title)
    if fish:
        out["fisheye_mapping"] = f"closest fisheye mapping: {d.closest_mapping()}"
    _aberration_tables(c, fo, out)
    _pupil_tables(c, out)
    return out


def _aberration_tables(c: "Comparison", fo, out: dict) -> None:
    """Best focus, spherical aberration, field curvature, axial and lateral colour tables into ``out``."""
    from ..paraxial import first_order
    lens, p, fkey = c.lens, c.primary_nm, c.field_key
    fc = c.field_curvature[p]
    bf = c.best_focus
    rows = [[k, v.z_mm, v.offset_from_paraxial_mm, v.rms_radius_mm * 1e3, v.rms_radius_paraxial_mm * 1e3]
            for k, v in bf.items()]
    out["best_focus"] = Table(rows, ["wavelength_nm", "best focus z_mm", "from paraxial_mm", "RMS spot_um",
                                    "RMS at paraxial_um"], digits=4,
                             title=f"Focus on axis: paraxial image z {fo.image_z_mm:.4f} mm, image surface z "
                                   f"{lens.image_z_mm:.4f} mm; best focus = minimum RMS spot radius about the "
                                   f"centroid, uniformly filled real pupil")
    la = c.lsa
    zones = [0.5, 0.7071, 1.0]
    cols = [int(np.argmin(np.abs(la.zones - z))) for z in zones]
    rows = [[w] + [la.focus_z_mm[k, j] - la.paraxial_focus_z_mm[k] for j in cols] + [la.correction(float(w))]
            for k, w in enumerate(la.wavelengths_nm)]
    out["spherical_aberration"] = Table(rows, ["wavelength_nm"] + [f"LSA zone {la.zones[j]:.2f}_mm" for j in cols]
                             + ["spherical aberration"], digits=5,
                             title="Longitudinal spherical aberration: real ray's axis crossing minus that wavelength's "
                                   "paraxial focus (zone = fraction of the paraxial EP radius)")
    rows = [[c.field_number(s), fc.sagittal_z_mm[i] - fc.paraxial_image_z_mm,
             fc.tangential_z_mm[i] - fc.paraxial_image_z_mm, fc.astigmatism_mm[i],
             fc.petzval_z_mm[i] - fc.paraxial_image_z_mm, fc.third_order_sagittal_z_mm[i] - fc.paraxial_image_z_mm,
             fc.third_order_tangential_z_mm[i] - fc.paraxial_image_z_mm] for s, i in zip(c.fields, c.field_index)]
    out["field_curvature"] = Table(rows, [fkey, "sagittal_mm", "tangential_mm", "T - S_mm", "Petzval_mm",
                                    "3rd-order S_mm", "3rd-order T_mm"], digits=4,
                             title=f"Field curvature at {p:g} nm: foci along z from the paraxial image plane "
                                   "(close rays about the real chief ray)")
    ch = c.chromatic
    rows = [[w, float(np.interp(w, ch.wavelength_nm, ch.paraxial_shift_mm)) if ch.wavelength_nm[0] <= w <=
             ch.wavelength_nm[-1] else first_order(lens, float(w)).image_z_mm - ch.reference_z_mm, b]
            for w, b in zip(ch.best_focus_wavelength_nm, ch.best_focus_shift_mm)]
    out["axial_colour"] = Table(rows, ["wavelength_nm", "paraxial focus_mm", "real best focus_mm"], digits=4,
                             title=f"Axial colour: focus from the paraxial focus at {p:g} nm")
    lat = c.lateral.to_dict()
    wl = c.lateral.wavelengths_nm
    rows = [[c.field_number(s)] + [v for pair in zip(lat["paraxial_from_primary_mm"][i],
                                                      lat["real_from_primary_mm"][i]) for v in pair]
            for i, s in enumerate(c.fields)]
    heads = [fkey] + [h for w in wl for h in (f"{w:g} parax_um", f"{w:g} real_um")]
    rows = [[r[0]] + [v * 1e3 for v in r[1:]] for r in rows]
    out["lateral_colour"] = Table(rows, heads, digits=2,
                             title=f"Lateral colour: chief-ray height minus the {p:g} nm one, on its paraxial image "
                                   "plane (um)")


def _pupil_tables(c: "Comparison", out: dict) -> None:
    """Pupil, vignetting and spot tables into ``out``."""
    p, fkey, okey = c.primary_nm, c.field_key, c.object_key
    pu = c.pupils
    par = pu.paraxial
    rows = [["paraxial", "-", par["entrance_pupil_z_mm"], par["entrance_pupil_diameter_mm"],
             par["entrance_pupil_diameter_mm"], par["exit_pupil_z_mm"], par["exit_pupil_diameter_mm"],
             par["exit_pupil_diameter_mm"], "-"]]
    areas = {round(o.object_value, 12): o.area_mm2 for o in pu.outlines}
    for k, s in enumerate(c.fields):
        # "-": a size whose stop-rim rays do not exist, an area where no ray passes
        rows.append(["real", c.field_number(s)] + [_f(float(v), ".3f") for v in (
            pu.entrance_pupil_z_mm[k], pu.entrance_tangential_mm[k], pu.entrance_sagittal_mm[k],
            pu.exit_pupil_z_mm[k], pu.exit_tangential_mm[k], pu.exit_sagittal_mm[k],
            areas.get(round(s.object_value, 12), math.nan))])
    out["pupils"] = Table(rows, ["pupils", fkey, "EP z_mm", "EP tan_mm", "EP sag_mm", "XP z_mm",
                                    "XP tan_mm", "XP sag_mm", "vignetted EP area_mm2"], digits=3,
                             title=f"Pupils at {p:g} nm (real: chief ray's axis crossings; sizes of the stop-rim rays; "
                                   f"area of the rays passing every aperture); real working f-number "
                                   f"{pu.real_working_f_number:.4f} (paraxial {par['working_f_number']:.4f})")
    vg = c.vignetting
    agree = vg.ri_methods_agree
    # "!" marks an exit-pupil value beyond the flux estimate's error: that method does not hold there
    rows = [[math.degrees(v) if c.infinite else v, _est(vg.vignetting_fraction[k]),
             _est(vg.relative_illumination[k]),
             _f(float(vg.relative_illumination_exit_pupil[k])) + ("!" if agree[k] is False else ""), vg.cos4[k]]
            for k, v in enumerate(vg.object_value)]
    out["vignetting"] = Table(rows, [okey, "unvignetted fraction", "rel. illumination",
                                    "RI exit pupil", "cos^4"], digits=4,
                             title=f"Vignetting and relative illumination at {p:g} nm ({vg.rays_per_field} Monte Carlo "
                                   f"rays per field and pupil, {sum(e.seconds for e in vg.relative_illumination):.3g} s; "
                                   f"+- one standard error, {vg.relative_illumination[0].method if vg.relative_illumination else ''}"
                                   "; RI exit pupil holds only where a field's image-space rays meet in one point: '!' "
                                   "marks a value beyond the flux estimate's error, read the flux column there)")
    if c.spots:
        rows = [[sp.label, _est(sp.estimates["rms_radius_mm"], ".5f"),
                 _est(sp.estimates["rms_radius_centroid_mm"], ".5f"), sp.geometric_radius_mm,
                 _est(sp.estimates["centroid_y_mm"], ".5f")] for sp in c.spots]
        out["spots"] = Table(rows, ["field", "RMS about chief_mm", "RMS about centroid_mm", "geometric radius_mm",
                                        "centroid y_mm"], digits=5,
                                 title="Spots on the image surface, polychromatic (lens weights), relative to the "
                                       f"primary chief ray ({c.spots[0].estimates['rms_radius_mm'].samples} Monte Carlo "
                                       f"rays per field, {c.spots[0].estimates['rms_radius_mm'].seconds:.3g} s for all"
                                       f" fields; +- one standard error, {c.spots[0].estimates['rms_radius_mm'].method}; "
                                       "geometric radius: the largest of a ray grid)")
