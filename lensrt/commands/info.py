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
                   help="angle of view against focus distance, real rays beside the unit-focus formula (p. 18); "
                        "with --config all, one curve per configuration")
    b.add_argument("--distances-m", metavar="LIST", default="inf,10,5,3,2,1.5,1,0.7,0.5",
                   help="focus distances in m from the first vertex (default inf,10,5,3,2,1.5,1,0.7,0.5)")
    b.add_argument("--out", metavar="DIR", help="write breathing.json and breathing.png (and zoom.png) here")
    z = p.add_argument_group("configurations (--config all)")
    z.add_argument("--mtf", action="store_true",
                   help="also the geometric S/T MTF per configuration at Hy 0, 0.7, 1 and the reference frequencies "
                        "(10/20/40 lp/mm on full frame scaled to --sensor, p. 114), real best focus")
    z.add_argument("--mtf-rays", type=int, default=20_000, metavar="N",
                   help="Monte Carlo rays per field point of --mtf (default 20000)")
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
        emit(_decentred_line(d))
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


def _decentred_line(d: dict) -> str:
    """What the first-order table means for a lens with tilts/decenters (``first_order_method``)."""
    method = d["first_order_method"]
    if d.get("parabasal") is None:
        return (f"first_order_method = \"{method}\": the lens has tilts/decenters; the real rays about the chief "
                f"ray failed ({d.get('parabasal_error', '')}), so these are the paraxial data of its unfolded axis "
                "(exact for tilted flat fold mirrors only)")
    if method.startswith("paraxial"):
        return (f"first_order_method = \"{method}\": the lens has tilts/decenters, and real rays about the central "
                "field's chief ray confirm the focal length of its unfolded axis (rows marked [parabasal]; their "
                "distances run along the chief ray)")
    return (f"first_order_method = \"{method}\": the lens is genuinely decentred or tilted; its first-order data "
            "are the rows marked [parabasal] (real rays about the central field's chief ray, y-z and x-z sections, "
            "as CODE V); the other rows are the y-nu trace of the unfolded axis, for reference only")


def _info_all(args: argparse.Namespace) -> int:
    """``info --config all``: one row per configuration (and the zoom curve with --out)."""
    from ..analysis.configurations import CONFIG_COLUMNS, configuration_rows, zoom_ratio
    from ..io.table import format_table
    from ..loading import load_configurations
    family = load_configurations(args.file, **reader_options(args))
    if args.breathing:
        return _info_breathing_all(args, family)
    rows = configuration_rows(family, args.wavelength_nm)
    if args.out:
        from pathlib import Path
        from ..views.plots.zoom import plot_zoom_curve
        plot_zoom_curve(Path(args.out) / "zoom.png", family.names, [r["efl_mm"] for r in rows],
                        [r["f_number"] for r in rows], family.name)
    mtf = _configuration_mtf(args, family) if args.mtf else None
    if args.json:
        print_json({"lens": family.name, "path": family.path, "configurations": rows,
                    "current": family.names[family.current],
                    "varying": [op.label for op in family.varying()], **({"mtf": mtf} if mtf else {})})
        return 0
    emit(f"{family.name or family.path}: {family.count} configuration(s), EFL ratio {zoom_ratio(rows):.3f}; "
         f"varying: {', '.join(op.label for op in family.varying()) or 'nothing'}")
    table = [[r[k] if k != "name" else r[k] + (" *" if r["current"] else "") for k, _ in CONFIG_COLUMNS]
             for r in rows]
    emit(format_table(table, [h for _, h in CONFIG_COLUMNS], digits=4))
    emit("* the file's current configuration; z from the first vertex (mm); distortion: real chief ray at the "
         "largest field against the paraxial image height")
    if mtf:
        from ..analysis.configurations import mtf_table
        mrows, heads = mtf_table(mtf)
        emit("")
        emit(format_table(mrows, heads, title=f"geometric MTF, sagittal / tangential, at cycles/mm "
                                              f"({mtf[0]['rays']} rays per field point; focus: real best focus "
                                              "of the axial point, or the image surface where that search fails)"))
    return 0


def _configuration_mtf(args: argparse.Namespace, family) -> list[dict]:
    """``info --config all --mtf``: :func:`lensrt.analysis.configurations.configuration_mtf` as JSON-ready dicts."""
    from ..analysis.configurations import configuration_mtf
    from ..analysis.psf.otf import reference_frequencies_cpmm
    from ..errors import LensrtError
    from ..paraxial.photographic import sensor_format
    if args.mtf_rays < 100:
        raise LensrtError(f"--mtf-rays {args.mtf_rays} is too few for an MTF", hint="use 1000 or more")
    freqs = reference_frequencies_cpmm(sensor_format(args.sensor or "full-frame").diagonal_mm)
    out = configuration_mtf(family, freqs, rays=args.mtf_rays)
    return [{k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in m.items()} for m in out]


def _breathing_distances_mm(args: argparse.Namespace) -> list[float]:
    from ..errors import LensrtError
    try:
        dists = [float(v) * 1000.0 for v in args.distances_m.split(",") if v.strip()]
    except ValueError:
        raise LensrtError(f"--distances-m {args.distances_m!r} is not a list of numbers",
                          hint="e.g. --distances-m inf,3,1,0.5") from None
    if not dists or any(not d > 0 for d in dists):
        raise LensrtError("--distances-m must list positive distances in m (inf allowed)")
    return dists


def _breathing_table(data: dict, travel_unit: str) -> str:
    from ..io.table import format_table
    rows = [[d / 1000.0, a, u, a - data["afov_real_deg"][0], t] for d, a, u, t in
            zip(data["distance_mm"], data["afov_real_deg"], data["afov_unit_focus_formula_deg"], data["travel"])]
    return format_table(rows, ["focus m", "AFoV real deg", "AFoV unit formula deg", "real change deg",
                               f"travel {travel_unit.split(' ')[0]}"], digits=4)


def _info_breathing_all(args: argparse.Namespace, family) -> int:
    """``info --config all --breathing``: the breathing curve of every configuration (zoom position)."""
    from ..analysis.focusing import focus_breathing
    from ..paraxial import photographic as ph
    dists = _breathing_distances_mm(args)
    fmt = ph.sensor_format(args.sensor or "full-frame")
    curves = [focus_breathing(lens, dists, fmt.diagonal_mm, args.wavelength_nm) for lens in family.configurations()]
    data = {"lens": family.name, "sensor": fmt.name,
            "configurations": [{"name": n, **c.to_dict()} for n, c in zip(family.names, curves)]}
    if args.out:
        from pathlib import Path
        from ..io.paths import output_file
        from ..io.table import dumps_json
        from ..views.plots.zoom import plot_breathing_family
        out = Path(args.out)
        output_file(out / "breathing.json").write_text(dumps_json(data) + "\n")
        plot_breathing_family(out / "breathing.png", data["configurations"],
                              f"{family.name}: focus breathing per configuration ({fmt.name})")
    if args.json:
        print_json(data)
        return 0
    for c, curve in zip(data["configurations"], curves):
        emit(f"{c['name']}: {curve.mechanism}; sensor {fmt.name} (diagonal {fmt.diagonal_mm:.2f} mm)")
        emit(_breathing_table(c, curve.travel_unit))
    return 0


def _info_breathing(args: argparse.Namespace, lens) -> int:
    """``info --breathing``: real AFoV against focus distance for the lens's mechanism and the p. 18 formula."""
    from ..analysis.focusing import focus_breathing
    from ..paraxial import photographic as ph
    dists = _breathing_distances_mm(args)
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
    emit(_breathing_table(data, curve.travel_unit))
    return 0
