"""``lensrt info``: the Gaussian picture of a lens -- first-order data, Seidel sums, and with
``--sensor`` the photographer's numbers (AFoV, depth of field, hyperfocal distance, crop factor)."""
from __future__ import annotations

import argparse

from ..views.first_order import first_order_rows, format_value, info_data, seidel_rows
from ._common import add_lens_argument, add_reader_options, emit, print_json, reader_options

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
    p.set_defaults(func=cmd_info)


def cmd_info(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..loading import load_lens
    lens = load_lens(args.file, **reader_options(args))
    d = info_data(lens, args.wavelength_nm, args.object_distance_mm, args.sensor, args.coc_mm)
    if args.json:
        print_json(d)
        return 0
    obj = "infinity" if d["object_distance_mm"] is None else f"{d['object_distance_mm']:g} mm from the first vertex"
    emit(lens.name or str(lens.path))
    emit(f"first order at {d['wavelength_nm']:g} nm, object at {obj}; z from the first vertex, +z toward the image")
    if d["afocal"]:
        emit(f"afocal (no power): angular magnification {d['angular_magnification']:.6g}; entrance pupil "
             f"z = {d['entrance_pupil_z_mm']:.6g} mm, diameter {d['entrance_pupil_diameter_mm']:.6g} mm; exit pupil "
             f"z = {d['exit_pupil_z_mm']:.6g} mm, diameter {d['exit_pupil_diameter_mm']:.6g} mm")
        return 0
    if d.get("unfolded_axis"):
        emit("the lens has tilts/decenters: these are the paraxial data of its unfolded axis (exact for tilted flat "
             "fold mirrors, not for genuinely decentred systems)")
    if lens.has_mirrors:
        emit("mirrors: z is along the unfolded axis; after an odd number of mirrors light travels toward -z "
             "(negative thicknesses, f' = n'/Phi with n' < 0)")
    if d["image_virtual"]:
        emit(f"virtual image: the rays leave the lens diverging; their paraxial image lies "
             f"{-d['image_distance_mm']:.4g} mm in front of the last vertex (the object is inside the front "
             f"focal point, z = {d['front_focal_z_mm']:.4g} mm), upright (m = {d['magnification']:+.4g})")
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
