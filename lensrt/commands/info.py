"""``lensrt info``: the Gaussian picture of a lens -- first-order data, Seidel sums, and with
``--sensor`` the photographer's numbers (AFoV, depth of field, hyperfocal distance, crop factor)."""
from __future__ import annotations

import argparse
import math
from typing import Any

from ._common import add_lens_argument, emit, print_json, lens_config

__all__ = ["register", "info_data", "first_order_rows", "seidel_rows"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="first-order (Gaussian) data, Seidel sums, AFoV and depth of field",
                       description="First-order data of a lens at a wavelength and object distance "
                                   "(z positions from the first vertex, +z toward the image), its Seidel "
                                   "sums, and with --sensor the angle of view and depth of field.")
    add_lens_argument(p)
    p.add_argument("--wavelength-nm", type=float, metavar="W", help="wavelength in nm (default: the lens's primary)")
    p.add_argument("--object-distance-mm", type=float, metavar="D",
                   help="object plane to first vertex in mm, 'inf' for infinity (default: the lens's own)")
    p.add_argument("--sensor", metavar="FORMAT",
                   help="full-frame, aps-c, mft, 1-inch, 2/3-inch, 1/1.7-inch, 1/2.5-inch, or WxH in mm")
    p.add_argument("--coc-mm", type=float, metavar="C",
                   help="circle-of-confusion diameter in mm (default: the format's, Field Guide p. 22)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    b = p.add_argument_group("focus breathing (real rays, the lens's own focus mechanism)")
    b.add_argument("--breathing", action="store_true",
                   help="angle of view against focus distance, real rays beside the unit-focus formula (p. 18)")
    b.add_argument("--distances-m", metavar="LIST", default="inf,10,5,3,2,1.5,1,0.7,0.5",
                   help="focus distances in m from the first vertex (default inf,10,5,3,2,1.5,1,0.7,0.5)")
    b.add_argument("--out", metavar="DIR", help="write breathing.json and breathing.png (and zoom.png) here")
    p.set_defaults(func=cmd_info)


def info_data(lens, wavelength_nm: float | None = None, object_distance_mm: float | None = None,
              sensor: str | None = None, coc_mm: float | None = None) -> dict[str, Any]:
    """Everything ``lensrt info --json`` prints, as a dict (infinities as ``inf``)."""
    from ..errors import LensrtError
    from ..paraxial import first_order, seidel_sums
    from ..paraxial import photographic as ph

    if wavelength_nm is not None and not (math.isfinite(wavelength_nm) and 200.0 <= wavelength_nm <= 20000.0):
        raise LensrtError(f"--wavelength-nm {wavelength_nm:g} is outside 200..20000 nm",
                          hint="wavelengths are in nanometres, e.g. 587.56")
    if object_distance_mm is not None and (math.isnan(object_distance_mm) or object_distance_mm <= 0):
        raise LensrtError(f"--object-distance-mm {object_distance_mm:g} must be positive",
                          hint="give the distance from the object to the first vertex in mm, or inf")
    if wavelength_nm is not None:
        lens.check_wavelengths(wavelength_nm)  # an ExtrapolationWarning where a glass's formula is extrapolated
    fo = first_order(lens, wavelength_nm, object_distance_mm)
    sums = seidel_sums(lens, fo.wavelength_nm, object_distance_mm)
    data: dict[str, Any] = {"lens": lens.name, "path": lens.path}
    data.update(fo.to_dict())
    data["field_image_heights_mm"] = list(fo.field_image_heights_mm)
    data["seidel"] = sums.to_dict()
    data["third_order_transverse"] = {(f"{k}_per_mm" if k == "PTZ" else f"{k}_mm"): v
                                      for k, v in sums.transverse_totals().items()}
    if sensor is None:
        if coc_mm is not None:
            raise LensrtError("--coc-mm needs --sensor", hint="add --sensor full-frame (or another format)")
        return data
    fmt = ph.sensor_format(sensor)
    c = fmt.coc_mm if coc_mm is None else float(coc_mm)
    if not (math.isfinite(c) and c > 0):
        raise LensrtError(f"--coc-mm {c:g} must be a positive diameter in mm")
    f, N, s_ep = fo.front_focal_length_mm, fo.f_number, fo.entrance_pupil_distance_mm
    b = fo.bellows_factor
    afov = {k: math.degrees(ph.afov_rad(d, fo.efl_mm, b)) for k, d in
            (("horizontal", fmt.width_mm), ("vertical", fmt.height_mm), ("diagonal", fmt.diagonal_mm))}
    focus_u = math.inf if fo.object_distance_mm is None else fo.object_distance_mm + fo.entrance_pupil_z_mm
    dof = ph.depth_of_field_mm(focus_u, f, N, c, s_ep)
    z_ep = fo.entrance_pupil_z_mm
    data["sensor"] = {
        "name": fmt.name, "width_mm": fmt.width_mm, "height_mm": fmt.height_mm, "diagonal_mm": fmt.diagonal_mm,
        "coc_mm": c, "crop_factor": fmt.crop_factor,
        "equivalent_focal_length_mm": float(ph.equivalent_focal_length_mm(fo.efl_mm, fmt.crop_factor)),
        "bellows_factor": b, "afov_deg": afov,
        "image_half_diagonal_mm": 0.5 * fmt.diagonal_mm,
        "depth_of_field": {
            "focus_distance_from_entrance_pupil_mm": focus_u,
            "near_from_entrance_pupil_mm": dof.near_mm, "far_from_entrance_pupil_mm": dof.far_mm,
            "near_z_mm": z_ep - dof.near_mm, "far_z_mm": z_ep - dof.far_mm, "total_mm": dof.total_mm,
            "hyperfocal_from_entrance_pupil_mm": dof.hyperfocal_mm, "hyperfocal_z_mm": z_ep - dof.hyperfocal_mm,
        },
    }
    return data


def _fmt(v: Any, spec: str = ".4f") -> str:
    if v is None:
        return "inf"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return format(v, spec)


def first_order_rows(d: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, unit) rows of the first-order table from :func:`info_data`'s dict."""
    rows = [
        ("effective focal length f_E = 1/Phi", d["efl_mm"], "mm"),
        ("front / rear focal length f, f'", f"{_fmt(d['front_focal_length_mm'])} / {_fmt(d['rear_focal_length_mm'])}", "mm"),
        ("back focal length (last vertex to F')", d["bfl_mm"], "mm"),
        ("front focal length FFL (z of F)", d["ffl_mm"], "mm"),
        ("front / rear focal point z", f"{_fmt(d['front_focal_z_mm'])} / {_fmt(d['rear_focal_z_mm'])}", "mm"),
        ("front / rear principal point z", f"{_fmt(d['front_principal_z_mm'])} / {_fmt(d['rear_principal_z_mm'])}", "mm"),
        ("front / rear nodal point z", f"{_fmt(d['front_nodal_z_mm'])} / {_fmt(d['rear_nodal_z_mm'])}", "mm"),
        ("entrance pupil z / diameter", f"{_fmt(d['entrance_pupil_z_mm'])} / {_fmt(d['entrance_pupil_diameter_mm'])}", "mm"),
        ("exit pupil z / diameter", f"{_fmt(d['exit_pupil_z_mm'])} / {_fmt(d['exit_pupil_diameter_mm'])}", "mm"),
        ("pupil magnification mp = D_XP/D", d["pupil_magnification"], ""),
        ("s_EP (P to EP) / s'_XP (P' to XP)", f"{_fmt(d['entrance_pupil_distance_mm'])} / {_fmt(d['exit_pupil_distance_mm'])}", "mm"),
        ("f-number N = f/D", d["f_number"], ""),
        ("working f-number Nw = b N", d["working_f_number"], f"b = {d['bellows_factor']:.4f}"),
        ("paraxial image z / magnification", f"{_fmt(d['image_z_mm'])} / {_fmt(d['magnification'], '.6f')}", "mm"),
        ("image distance (last vertex to image)", d["image_distance_mm"], "mm"),
        ("unit-focus extension e", d["unit_focus_extension_mm"], "mm"),
        ("image surface (last vertex to it)", d["image_surface_distance_mm"], "mm"),
        ("overall length / total track", f"{_fmt(d['overall_length_mm'])} / {_fmt(d['total_track_mm'])}", "mm"),
        ("half field / paraxial image height", f"{_fmt(d['half_field_deg'])} deg / {_fmt(d['paraxial_image_height_mm'])}", "mm"),
        ("image height at each field", ", ".join(_fmt(h) for h in d["field_image_heights_mm"]), "mm"),
        ("Lagrange invariant H", d["lagrange_invariant"], "mm"),
        ("Petzval sum (sum Phi/(n n'))", _fmt(d["petzval_sum_per_mm"], ".6g"), "1/mm"),
    ]
    return [(a, _fmt(b) if not isinstance(b, str) else b, c) for a, b, c in rows]


def seidel_rows(lens, d: dict[str, Any]) -> list[list]:
    """Per-surface Seidel rows (``STO`` for the stop) and the ``SUM`` row, columns as :data:`SEIDEL_NAMES`."""
    from ..paraxial import SEIDEL_NAMES
    seidel = d["seidel"]
    per = seidel["per_surface_mm"]
    scale = max(abs(v) for k in SEIDEL_NAMES for v in per[k]) or 1.0
    srows = [[("STO" if i == lens.stop_index else str(i + 1))]
             + [per[k][i] if abs(per[k][i]) > 1e-12 * scale else 0.0 for k in SEIDEL_NAMES]
             for i in range(lens.n_surfaces)]
    srows.append(["SUM"] + [seidel[f"{k}_mm"] for k in SEIDEL_NAMES])
    return srows


def cmd_info(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..loading import load_lens
    config = lens_config(args, allow_all=True)
    if config is not None and config.lower() == "all":
        return _info_all(args)
    lens = load_lens(args.file, config=config)
    if args.breathing:
        return _info_breathing(args, lens)
    d = info_data(lens, args.wavelength_nm, args.object_distance_mm, args.sensor, args.coc_mm)
    if args.json:
        print_json(d)
        return 0
    obj = "infinity" if d["object_distance_mm"] is None else f"{d['object_distance_mm']:g} mm from the first vertex"
    emit(lens.name or str(lens.path))
    emit(f"first order at {d['wavelength_nm']:g} nm, object at {obj}; z from the first vertex, +z toward the image")
    if d["image_virtual"]:
        emit(f"virtual image: the rays leave the lens diverging; their paraxial image lies "
             f"{-d['image_distance_mm']:.4g} mm in front of the last vertex (the object is inside the front "
             f"focal point, z = {d['front_focal_z_mm']:.4g} mm), upright (m = {d['magnification']:+.4g})")
    emit(format_table(first_order_rows(d), ["quantity", "value", "unit"]))
    seidel = d["seidel"]
    srows = seidel_rows(lens, d)
    emit("")
    emit(format_table(srows, ["surf", "S_I sph", "S_II coma", "S_III ast", "S_IV ptz", "S_V dist",
                              "C_I axcol", "C_II latcol"], digits=6,
                      title=f"Seidel sums (mm; Welford; colour {seidel['short_nm']:g} - {seidel['long_nm']:g} nm)"))
    tr = d["third_order_transverse"]
    emit(format_table([[tr[k] for k in tr]], [k.rsplit("_", 1)[0] if not k.startswith("PTZ") else "PTZ 1/mm"
                                             for k in tr], digits=6,
                      title="CODE V transverse third order, SUM row (mm at full aperture and field)"))
    if "sensor" in d:
        s = d["sensor"]
        dof = s["depth_of_field"]
        emit("")
        emit(f"sensor {s['name']} ({s['width_mm']:g} x {s['height_mm']:g} mm), CoC {s['coc_mm']:g} mm, "
             f"crop factor {s['crop_factor']:.4f}, equivalent focal length {s['equivalent_focal_length_mm']:.2f} mm")
        a = s["afov_deg"]
        emit(f"angle of view (bellows factor {s['bellows_factor']:.4f}): horizontal {a['horizontal']:.2f}, "
             f"vertical {a['vertical']:.2f}, diagonal {a['diagonal']:.2f} deg")
        emit(f"depth of field (distances from the entrance pupil): focus {_fmt(dof['focus_distance_from_entrance_pupil_mm'], '.1f')} mm, "
             f"near {_fmt(dof['near_from_entrance_pupil_mm'], '.1f')} mm, far {_fmt(dof['far_from_entrance_pupil_mm'], '.1f')} mm, "
             f"total {_fmt(dof['total_mm'], '.1f')} mm; hyperfocal {_fmt(dof['hyperfocal_from_entrance_pupil_mm'], '.1f')} mm")
    return 0


def _info_all(args: argparse.Namespace) -> int:
    """``info --config all``: one row per configuration (and the zoom curve with --out)."""
    from ..analysis.configurations import CONFIG_COLUMNS, configuration_rows, zoom_ratio
    from ..io.table import format_table
    from ..loading import load_configurations
    family = load_configurations(args.file)
    rows = configuration_rows(family, args.wavelength_nm)
    if args.out:
        from pathlib import Path
        from ..io.plots_zoom import plot_zoom_curve
        plot_zoom_curve(Path(args.out) / "zoom.png", family.names, [r["efl_mm"] for r in rows],
                        [r["f_number"] for r in rows], family.name)
    if args.json:
        print_json({"lens": family.name, "path": family.path, "configurations": rows,
                    "current": family.names[family.current],
                    "varying": [op.label for op in family.varying()]})
        return 0
    emit(f"{family.name or family.path}: {family.count} configuration(s), zoom ratio {zoom_ratio(rows):.3f}; "
         f"varying: {', '.join(op.label for op in family.varying()) or 'nothing'}")
    table = [[r[k] if k != "name" else r[k] + (" *" if r["current"] else "") for k, _ in CONFIG_COLUMNS]
             for r in rows]
    emit(format_table(table, [h for _, h in CONFIG_COLUMNS], digits=4))
    emit("* the file's current configuration; z from the first vertex (mm); distortion: real chief ray at the "
         "largest field against the paraxial image height")
    return 0


def _info_breathing(args: argparse.Namespace, lens) -> int:
    """``info --breathing``: real AFoV against focus distance for the lens's mechanism and the p. 18 formula."""
    from ..analysis.focusing import focus_breathing
    from ..errors import LensrtError
    from ..io.table import format_table
    from ..paraxial import photographic as ph
    try:
        dists = [float(v) * 1000.0 for v in args.distances_m.split(",") if v.strip()]
    except ValueError:
        raise LensrtError(f"--distances-m {args.distances_m!r} is not a list of numbers",
                          hint="e.g. --distances-m inf,3,1,0.5") from None
    if not dists or any(not d > 0 for d in dists):
        raise LensrtError("--distances-m must list positive distances in m (inf allowed)")
    fmt = ph.sensor_format(args.sensor or "full-frame")
    curve = focus_breathing(lens, dists, fmt.diagonal_mm, args.wavelength_nm)
    data = curve.to_dict()
    if args.out:
        from pathlib import Path
        from ..io.paths import output_file
        from ..io.plots_zoom import plot_breathing
        from ..io.table import dumps_json
        out = Path(args.out)
        output_file(out / "breathing.json").write_text(dumps_json(data) + "\n")
        plot_breathing(out / "breathing.png", data, f"{lens.name}: focus breathing ({fmt.name})")
    if args.json:
        print_json(data)
        return 0
    emit(f"{lens.name or lens.path}: {curve.mechanism}; sensor {fmt.name} (diagonal {fmt.diagonal_mm:.2f} mm)")
    rows = [[d / 1000.0, a, u, a - data["afov_real_deg"][0], t] for d, a, u, t in
            zip(data["distance_mm"], data["afov_real_deg"], data["afov_unit_focus_formula_deg"], data["travel"])]
    emit(format_table(rows, ["focus m", "AFoV real deg", "AFoV unit formula deg", "real change deg",
                             f"travel {curve.travel_unit.split(' ')[0]}"], digits=4))
    return 0
