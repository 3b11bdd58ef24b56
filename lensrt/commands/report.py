"""``lensrt report``: the lens's data sheet -- one self-contained HTML page with the PNG/EXR/JSON
files behind it (docs/tutorials/first-report.md)."""
from __future__ import annotations

import argparse
import math
import shlex
import sys

from ._common import add_lens_argument, add_reader_options, emit, reader_options, lens_config

__all__ = ["register", "cmd_report", "EXIT_SECTION_FAILED"]

#: exit status when the page was written but at least one section failed (bad input: 2, a bug: 3)
EXIT_SECTION_FAILED = 1


def register(sub: argparse._SubParsersAction) -> None:
    from ..report.options import QUALITIES
    from ..report.run import section_keys
    p = sub.add_parser("report", help="the lens's data sheet: one HTML page with every analysis",
                       description="Write a self-contained HTML report of a lens into --out: prescription and "
                                   "layout, first-order data beside real rays, paraxial against real (distortion, "
                                   "focus, spherical aberration, colour), spots, ray fans, relative illumination, a "
                                   "PSF map, MTF curves with the diffraction limit, a bokeh map and the depth of "
                                   "field; every Monte Carlo figure with its samples, seconds and standard error. "
                                   "A section that fails says why and the others run on. Exit status: 0 all "
                                   "sections made; 1 the page was written but a section failed; 2 bad input "
                                   "(nothing written); 3 an internal error.")
    add_lens_argument(p)
    add_reader_options(p)
    p.add_argument("--out", default="report", metavar="DIR",
                   help="output folder for index.html, report.json and the figures (default: report)")
    g = p.add_argument_group("camera")
    g.add_argument("--sensor", default="full-frame", metavar="FORMAT",
                   help="full-frame (default), aps-c, mft, 1-inch, 2/3-inch, 1/1.7-inch, 1/2.5-inch, or WxH in mm: "
                        "PSF map, MTF fields and frequencies, bokeh frame, depth of field")
    f = g.add_mutually_exclusive_group()
    f.add_argument("--focus-m", type=float, metavar="S",
                   help="focus distance in m from the first vertex ('inf' allowed), by unit focusing; default: the "
                        "lens file's object distance (if that is infinity, the bokeh map and depth-of-field table "
                        "use 20 focal lengths, rounded)")
    f.add_argument("--object-distance-mm", type=float, metavar="D", help="the same in mm")
    g.add_argument("--f-number", type=float, metavar="N", help="stop the lens down to f/N (default: full aperture)")
    g.add_argument("--coc-mm", type=float, metavar="C",
                   help="circle of confusion for the depth of field (default: the format's, Field Guide p. 22)")
    g.add_argument("--pixel-pitch-um", type=float, default=4.0, metavar="P",
                   help="pixel pitch for the system MTF and the MTF curves' range (default 4.0)")
    m = p.add_argument_group("Monte Carlo")
    m.add_argument("--quality", choices=list(QUALITIES), default="normal",
                   help="sample counts: draft (a quick look), normal (default), high (smoother figures, about 4x "
                        "longer); docs/tutorials/first-report.md lists them")
    m.add_argument("--time-budget", type=float, default=None, metavar="S",
                   help="seconds for the PSF map and MTF together: each field point gets its share as a "
                        "progressive run (rays added until the share is spent)")
    m.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    m.add_argument("--precision", choices=["float32", "float64"], default="float32",
                   help="precision of the Monte Carlo stream kernels (default float32; the paraxial-against-real "
                        "analyses are float64)")
    m.add_argument("--seed", type=int, default=0, help="seed of every Monte Carlo estimate (default 0)")
    p.add_argument("--skip", action="append", default=[], choices=section_keys(), metavar="SECTION",
                   help="leave a section out (repeatable): " + ", ".join(section_keys()))
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    from ..errors import LensrtError
    from ..loading import load_lens
    from ..report import ReportOptions, build_report
    from ..units import MM_PER_M
    distance = args.object_distance_mm
    if args.focus_m is not None:
        if math.isnan(args.focus_m) or args.focus_m <= 0:
            raise LensrtError(f"--focus-m {args.focus_m:g} must be a positive distance in m (or inf)")
        distance = args.focus_m * MM_PER_M
    options = ReportOptions(quality=args.quality, sensor=args.sensor, object_distance_mm=distance,
                            f_number=args.f_number, coc_mm=args.coc_mm, pixel_pitch_um=args.pixel_pitch_um,
                            time_budget_s=args.time_budget, device=args.device, precision=args.precision,
                            seed=args.seed, command_line=" ".join(
                                ["lensrt"] + [shlex.quote(a) for a in getattr(args, "argv", sys.argv[1:])]))
    config = lens_config(args, allow_all=True)
    if config is not None and config.lower() == "all":
        from ..loading import load_configurations
        lens = load_configurations(args.file, **reader_options(args))
    else:
        lens = load_lens(args.file, config=config, **reader_options(args))
    if not args.quiet:
        sys.stderr.write(f"lensrt report: {lens.name or lens.path} -> {args.out}/ (quality {args.quality}; "
                         "a first run also compiles the Warp kernels)\n")
    report = build_report(lens, args.out, options, skip=args.skip, quiet=args.quiet)
    emit(f"{report.lens_name}: {len(report.sections) - len(report.failed)} of {len(report.sections)} sections in "
         f"{report.seconds:.1f} s on {report.device_name}")
    for sec in report.failed:
        emit(f"  section '{sec.key}' failed: {sec.errors[0]}")
    emit(f"wrote {report.html_path} ({len(report.referenced_files())} files beside it, report.json with everything)")
    return EXIT_SECTION_FAILED if report.failed else 0
