"""``lensrt lens show|convert|list``: look at and convert prescriptions."""
from __future__ import annotations

import argparse
import math

from ..views.lens import APERTURE_RULE_TEXT, describe_aperture, describe_fields, lens_table
from ._common import add_lens_argument, add_reader_options, emit, lens_config, print_json, reader_options

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("lens", help="show, convert and list lens prescriptions")
    lsub = p.add_subparsers(dest="lens_command", metavar="ACTION")
    lsub.required = True

    s = lsub.add_parser("show", help="surface table with materials and indices")
    add_lens_argument(s)
    add_reader_options(s)
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=cmd_show)

    c = lsub.add_parser("convert", help="convert any supported file to the native TOML format")
    c.add_argument("input", metavar="IN", help="lens file (.toml, .zmx, .seq, .dat) or library lens name")
    c.add_argument("output", metavar="OUT.toml")
    add_reader_options(c)
    c.set_defaults(func=cmd_convert)

    l_ = lsub.add_parser("list", help="the lens library with focal length, f-number and field")
    l_.add_argument("--json", action="store_true")
    l_.set_defaults(func=cmd_list)


def cmd_show(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..loading import load_lens
    lens = load_lens(args.file, config=lens_config(args), **reader_options(args))
    rows, headers = lens_table(lens)
    if args.json:
        print_json({"name": lens.name, "source": lens.source, "path": lens.path,
                    "aperture": {"type": lens.aperture.kind, "value": lens.aperture.value},
                    "object_distance_mm": lens.object_distance_mm,
                    "wavelengths_nm": list(lens.wavelengths.nm), "primary_nm": lens.wavelengths.primary_nm,
                    "fields": {"type": lens.fields.kind, "y": list(lens.fields.y), "x": list(lens.fields.x)},
                    "iris": {"blades": lens.iris.blades, "rotation_rad": lens.iris.rotation_rad},
                    "notes": lens.meta, "aperture_rule": lens.aperture_rule,
                    "warnings": [w.to_dict() for w in lens.warnings],
                    "surfaces": [dict(zip(headers, r)) for r in rows]})
        return 0
    emit(f"{lens.name or lens.path}")
    if "configuration" in lens.meta:
        emit(f"configuration {lens.meta['configuration']} (--config picks another; lensrt info --config all)")
    if not lens.focus.is_unit:
        emit(f"focus: {lens.focus.describe()}")
    if lens.source:
        emit(f"source: {lens.source}")
    obj = "infinity" if math.isinf(lens.object_distance_mm) else f"{lens.object_distance_mm:g} mm"
    emit(f"aperture: {describe_aperture(lens)}; object at {obj}; fields: {describe_fields(lens)}")
    emit("wavelengths: " + ", ".join(f"{w:g}" + ("*" if i == lens.wavelengths.primary else "")
                                     for i, w in enumerate(lens.wavelengths.nm)) + " nm (* primary)")
    if lens.iris.blades:
        emit(f"iris: {lens.iris.blades} blades, rotation {math.degrees(lens.iris.rotation_rad):g} deg")
    emit(f"aperture rule: {APERTURE_RULE_TEXT[lens.aperture_rule]}")
    emit(format_table(rows, headers))
    curved = "" if lens.image_curvature_per_mm == 0.0 else \
        f", a sphere of radius {1.0 / lens.image_curvature_per_mm:.4f} mm"
    emit(f"image surface at z = {lens.image_z_mm:.4f} mm from surface 1{curved}")
    if any(s.semi_diameter_auto for s in lens.surfaces):
        emit(f"* semi-diameter computed ({lens.meta.get('clear_apertures', 'automatic')})")
    for w in lens.warnings:
        emit(f"warning [{w.code}]" + (f" surface {w.surface + 1}" if w.surface is not None else "") + f": {w.text}")
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    from pathlib import Path
    from ..errors import LensrtError
    from ..prescription.formats import read_configurations
    from ..prescription.formats.native import write_native
    from ..io.paths import output_file
    from ..library import resolve_lens_path
    from ..loading import complete_lens
    out = Path(args.output)
    if out.suffix.lower() != ".toml":
        raise LensrtError(f"output {out} must be a .toml file (the native format)")
    family = read_configurations(resolve_lens_path(args.input), **reader_options(args))  # file or library name
    for lens in family.configurations():
        complete_lens(lens)  # fail on impossible geometry before writing anything
    write_native(family if family.count > 1 else family.base, output_file(out))
    more = f", {family.count} configurations" if family.count > 1 else ""
    emit(f"wrote {out} ({family.base.n_surfaces} surfaces{more})")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..library import library_lenses
    from ..loading import load_lens
    from ..paraxial import first_order
    rows = []
    for path in library_lenses():
        lens = load_lens(path)
        fo = first_order(lens)
        f = lens.fields
        if f.kind == "angle":
            field = f"{2 * math.degrees(f.max_radial):.1f} deg"
        else:
            field = f"{2 * f.max_radial:.1f} mm"
        if math.isinf(lens.object_distance_mm):
            fno, obj = f"{fo.f_number:.2f}", "inf"
        else:  # a lens stored at a finite conjugate (macro): its working f-number and magnification
            fno, obj = f"{fo.working_f_number:.2f}w", f"{lens.object_distance_mm:.1f} mm (m {fo.magnification:.2f})"
        rows.append([path.stem, fo.efl_mm, fno, field, obj, lens.n_surfaces, lens.name])
    if args.json:
        print_json([dict(zip(["name", "efl_mm", "f_number", "full_field", "object", "surfaces", "title"], r))
                    for r in rows])
        return 0
    emit(format_table(rows, ["name", "efl_mm", "f/#", "full field", "object", "surfaces", "title"], digits=2))
    emit("f/#: image-space f-number at infinity focus; 'w': working f-number at the stored object distance")
    return 0
