"""``lensrt compare``: the ynu paraxial trace against real rays -- focal length, image height and
distortion, focus and spherical aberration, field curvature, colour, pupils, vignetting and relative
illumination, ray fans and spots -- as tables, one JSON object, and PNG figures."""
from __future__ import annotations

import argparse
import math

from ._common import add_lens_argument, emit, print_json, lens_config

__all__ = ["register", "compare_report"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("compare", help="paraxial against real: distortion, focus, field curvature, colour, pupils, "
                                       "relative illumination",
                       description="Compare the ynu paraxial trace with real rays at every field point and "
                                   "wavelength of the lens (and any given here): focal lengths, image heights and "
                                   "distortion (textbook and CODE V definitions, fisheye mappings), best focus and "
                                   "longitudinal spherical aberration, sagittal/tangential field curvature and the "
                                   "Petzval surface, axial and lateral colour, paraxial against real pupils, "
                                   "vignetting and relative illumination against cos^4, spot diagrams and ray fans.")
    add_lens_argument(p)
    p.add_argument("--field", type=float, action="append", default=[], metavar="F",
                   help="an extra field point in the lens's field unit (deg for angles, mm for heights); repeatable")
    p.add_argument("--wavelength-nm", type=float, action="append", default=[], metavar="W",
                   help="an extra wavelength in nm; repeatable")
    p.add_argument("--rays", type=int, default=1 << 16, metavar="N",
                   help="Monte Carlo rays per field point for vignetting and relative illumination (default 65536)")
    p.add_argument("--spot-rays", type=int, default=1 << 14, metavar="N",
                   help="Monte Carlo rays per field and wavelength for the spot statistics (default 16384)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the Monte Carlo estimates (default 0)")
    p.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    p.add_argument("--json", action="store_true", help="print one JSON object (every unit in its key)")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.set_defaults(func=cmd_compare)


def compare_report(lens, fields_in_lens_unit=(), wavelengths_nm=(), rays: int = 1 << 16, spot_rays: int = 1 << 14,
                   seed: int = 0, device: str | None = None):
    """Check the options and run :func:`lensrt.analysis.compare.comparison.compare_lens`."""
    from ..analysis.compare.comparison import compare_lens
    from ..errors import LensrtError
    extra = []
    for f in fields_in_lens_unit:
        if not math.isfinite(f) or f < 0:
            raise LensrtError(f"--field {f!r} must be a non-negative number",
                              hint="field angles in degrees, heights in mm")
        extra.append(math.radians(f) if lens.fields.kind == "angle" else float(f))
    if lens.fields.kind == "angle" and any(v >= math.radians(108.0) for v in extra):
        raise LensrtError("--field beyond 108 degrees", hint="field angles are half-angles from the axis")
    if rays < 64 or spot_rays < 64:
        raise LensrtError("--rays and --spot-rays must be at least 64")
    if wavelengths_nm:
        lens.check_wavelengths(list(wavelengths_nm))  # an ExtrapolationWarning where a glass is extrapolated
    return compare_lens(lens, wavelengths_nm=list(wavelengths_nm), extra_fields=extra, device=device, rays=rays,
                        seed=seed, spot_rays=spot_rays)


def cmd_compare(args: argparse.Namespace) -> int:
    from ..loading import load_lens
    from ..paraxial import first_order
    lens = load_lens(args.file, config=lens_config(args))
    fo = first_order(lens)
    if fo.afocal:
        return _compare_afocal(args, lens, fo)
    c = compare_report(lens, args.field, args.wavelength_nm, args.rays, args.spot_rays, args.seed, args.device)
    written = []
    if args.plot:
        from ..views.plots.analysis import write_compare_plots
        written = write_compare_plots(c, args.plot)
    if args.json:
        d = c.to_dict()
        d["figures"] = [str(p) for p in written]
        print_json(d)
        return 0
    from ..views.compare import comparison_text
    emit(comparison_text(c))
    for p in written:
        emit(f"wrote {p}")
    return 0


def _compare_afocal(args: argparse.Namespace, lens, fo) -> int:
    """An afocal lens: spots in angle space (:mod:`lensrt.analysis.compare.afocal`) instead of image-plane tables."""
    from ..analysis.compare.afocal import angular_spots
    from ..errors import LensrtError
    from ..io.table import format_table
    if args.field or args.wavelength_nm or args.plot:
        raise LensrtError("--field, --wavelength-nm and --plot are not available for an afocal lens",
                          hint="lensrt compare on an afocal lens prints its angular spots at the lens's own fields")
    spots = angular_spots(lens, device=args.device)
    if args.json:
        print_json({"lens": lens.name, "afocal": True, "angular_magnification": fo.angular_magnification,
                    "wavelength_nm": fo.wavelength_nm, "angular_spots": [s.to_dict() for s in spots]})
        return 0
    emit(f"{lens.name or lens.path}: afocal, angular magnification {fo.angular_magnification:.6g} (paraxial); "
         f"image-plane tables do not apply: spots in angle space at {fo.wavelength_nm:g} nm (real-aimed pupil grid, "
         "angles to the real chief ray)")
    rows = [[s.field_deg if s.field_deg is not None else s.field_height_mm,
             "-" if s.paraxial_exit_deg is None else f"{s.paraxial_exit_deg:.6f}", f"{s.chief_exit_deg:.6f}",
             s.rms_mrad, s.max_mrad, s.rays] for s in spots]
    unit = "deg" if lens.fields.kind == "angle" else "mm"
    emit(format_table(rows, [f"field {unit}", "paraxial exit deg", "real chief exit deg", "RMS mrad", "max mrad",
                             "rays"], digits=6))
    return 0
