"""``lensrt info``: the Gaussian picture of a lens -- first-order data, Seidel sums, and with
``--sensor`` the photographer's numbers (AFoV, depth of field, hyperfocal distance, crop factor)."""
from __future__ import annotations

import argparse

from ..views.first_order import (afocal_line, first_order_rows, format_value, info_data, seidel_rows,
                                 virtual_image_line)
from ._common import add_lens_argument, add_reader_options, emit, lens_config, print_json, reader_options

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="first-order (Gaussian) data, Seidel sums, AFoV and depth of field",
                       description="First-order data of a lens at a wavelength and object distance "
                                   "(z positions from the first vertex, +z toward the image), its Seidel "
                                   "sums, and with --sensor the angle of view and depth of field.")
    add_lens_argument(p)
    add_reader_options(p)
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


def cmd_info(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..loading import load_lens
    config = lens_config(args, allow_all=True)
    if config is not None and config.lower() == "all":
        return _info_all(args)
    lens = load_lens(args.file, config=config, **reader_options(args))
    if args.breathing:
        return _info_breathing(args, lens)
    d = info_data(lens, args.wavelength_nm, args.object_distance_mm, args.sensor, args.coc_mm)
    if args.json:
        print_json(d)
        return 0
    obj = "infinity" if d["object_distance_mm"] is None else f"{d['object_distance_mm']:g} mm from the first vertex"
    emit(lens.name or str(lens.path))
    emit(f"first order at {d['wavelength_nm']:g} nm, object at {obj}; z from the first vertex, +z toward the image")
    if d["afocal"]:
        emit(afocal_line(d))
        for w in d["warnings"]:
            emit(f"warning [{w['code']}]: {w['text']}")
        return 0
    if d.get("unfolded_axis"):
        emit("the lens has tilts/decenters: these are the paraxial data of its unfolded axis (exact for tilted flat "
             "fold mirrors, not for genuinely decentred systems)")
    if lens.has_mirrors:
        emit("mirrors: z is along the unfolded axis; after an odd number of mirrors light travels toward -z "
             "(negative thicknesses, f' = n'/Phi with n' < 0)")
    if d["image_virtual"]:
        emit(virtual_image_line(d))
    emit(format_table(first_order_rows(d), ["quantity", "value", "unit"]))
    for w in d["warnings"]:
        emit(f"warning [{w['code']}]: {w['text']}")
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
        emit(f"depth of field (distances from the entrance pupil): focus {format_value(dof['focus_distance_from_entrance_pupil_mm'], '.1f')} mm, "
             f"near {format_value(dof['near_from_entrance_pupil_mm'], '.1f')} mm, far {format_value(dof['far_from_entrance_pupil_mm'], '.1f')} mm, "
             f"total {format_value(dof['total_mm'], '.1f')} mm; hyperfocal {format_value(dof['hyperfocal_from_entrance_pupil_mm'], '.1f')} mm")
    return 0


def _info_all(args: argparse.Namespace) -> int:
    """``info --config all``: one row per configuration (and the zoom curve with --out)."""
    from ..analysis.configurations import CONFIG_COLUMNS, configuration_rows, zoom_ratio
    from ..io.table import format_table
    from ..loading import load_configurations
    family = load_configurations(args.file, **reader_options(args))
    rows = configuration_rows(family, args.wavelength_nm)
    if args.out:
        from pathlib import Path
        from ..views.plots.zoom import plot_zoom_curve
        plot_zoom_curve(Path(args.out) / "zoom.png", family.names, [r["efl_mm"] for r in rows],
                        [r["f_number"] for r in rows], family.name)
    if args.json:
        print_json({"lens": family.name, "path": family.path, "configurations": rows,
                    "current": family.names[family.current],
                    "varying": [op.label for op in family.varying()]})
        return 0
    emit(f"{family.name or family.path}: {family.count} configuration(s), EFL ratio {zoom_ratio(rows):.3f}; "
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
        from ..views.plots.zoom import plot_breathing
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
