"""``lensrt psf``: PSFs of real rays at field points, or a PSF map over a sensor, with standard errors."""
from __future__ import annotations

import argparse

from ._common import emit, print_json, lens_config
from ._psf_options import add_psf_options, fields_from_args, host_device, print_psf_table, setup_from_args

__all__ = ["register", "cmd_psf"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("psf", help="point spread functions (geometric or diffraction) at field points or over a sensor",
                       description="PSFs of real rays: geometric (Monte Carlo rays streamed into a histogram) or "
                                   "diffraction (real-ray wavefront -> FFT/MFT/Huygens), at field points or as a "
                                   "map over a sensor (--grid 9x9 --sensor aps-c), each normalised to unit volume, "
                                   "with rays, seconds and standard errors. --out writes psf.json, psf.exr (one "
                                   "layer per field point) and psf.png.")
    add_psf_options(p, method_default="geometric")
    p.add_argument("--log", action="store_true", help="PNG on a log scale (1e-6 .. 1 of each peak)")
    p.add_argument("--converge", action="store_true",
                   help="error against run time at the first field point: RMS radius with random, stratified and "
                        "sobol sampling in float32 and float64, at ray counts up to --rays; prints the table and "
                        "fitted log-log slopes (writes converge.json/png with --out)")
    p.set_defaults(func=cmd_psf)


def cmd_psf(args: argparse.Namespace) -> int:
    from ..errors import LensrtError
    from ..loading import load_lens
    from ._common import reader_options
    from ._parallel import executor_from_args, progress_printer, run_summary_line
    from ..analysis.psf.map import run_psf_map
    if args.device and not args.devices:
        args.devices = args.device
    lens = load_lens(args.file, config=lens_config(args), **reader_options(args))
    dev = host_device(args)
    setup = setup_from_args(args, lens, dev)
    fields, shape = fields_from_args(args, lens, setup.plane_z_mm, dev)
    if args.converge:
        if setup.method != "geometric":
            raise LensrtError("--converge studies Monte Carlo (geometric) PSFs", hint="drop --method or use geometric")
        return _converge(args, setup, fields[0], dev)
    with executor_from_args(args, uses_device=True) as ex:
        pmap = run_psf_map(setup, fields, args.seed, ex, progress_printer(args, "fields"), shape,
                           args.sensor if args.grid else None)
    files = {}
    if args.out:
        from ..views.psf_files import write_psf_outputs
        files = write_psf_outputs(args.out, pmap, "psf", log=args.log)
    if args.json:
        d = pmap.to_dict()
        d["files"] = files
        print_json(d)
        return 0
    spec = setup.spectrum
    emit(f"{lens.name or lens.path}: {len(fields)} field point(s), spectrum {spec.name}, focus {setup.focus['focus']} "
         f"(z = {setup.plane_z_mm:.4f} mm, {setup.focus['shift_from_image_mm']:+.4f} mm from the image surface)")
    emit(f"method {setup.method}, sampler {setup.sampler}, {setup.precision}, seed {args.seed}; "
         f"{run_summary_line(_Summary(pmap))}")
    print_psf_table(pmap, emit)
    if files:
        emit("wrote " + ", ".join(files.values()))
    return 0


class _Summary:
    def __init__(self, pmap) -> None:
        self.n_items = len(pmap.results)
        self.seconds = pmap.seconds
        self.executor = pmap.run.get("executor", "")


def _converge(args: argparse.Namespace, setup, f, dev) -> int:
    from ..studies.convergence.quantities import converge_psf
    from ..io.table import dumps_json, format_table
    data = converge_psf(setup, f, seed=args.seed, device=dev)
    data["lens"] = setup.lens.name
    data["device"] = dev or "auto"
    if args.out:
        from ..io.paths import output_dir
        from ..views.plots.psf import plot_convergence
        d = output_dir(args.out)
        (d / "converge.json").write_text(dumps_json(data) + "\n")
        plot_convergence(d / "converge.png", data,
                         title=f"{setup.lens.name}\nRMS radius at {f.label}: error against run time")
        data["files"] = [str(d / "converge.json"), str(d / "converge.png")]
    if args.json:
        print_json(data)
        return 0
    ref = data["reference"]
    how = ("closed form: " + ref["description"] if ref["kind"] == "closed form"
           else f"{ref['rays']:.3g} rays, sobol float64")
    emit(f"{setup.lens.name}: RMS spot radius at field {f.label}; reference {ref['value_mm'] * 1e3:.5f} +- "
         f"{ref['stderr_mm'] * 1e3:.2g} um ({how}); lensrt converge repeats each point for RMS errors")
    rows = [[r["sampler"], r["precision"], r["rays"], r["seconds"], r["value_mm"] * 1e3, r["stderr_mm"] * 1e3,
             r["error_mm"] * 1e3] for r in data["runs"]]
    emit(format_table(rows, ["sampler", "precision", "rays", "seconds", "RMS (um)", "stderr (um)", "|error| (um)"],
                      digits=5))
    rows = [[s["sampler"], s["precision"], s["slope_stderr_vs_seconds"], s["slope_stderr_vs_rays"],
             s["slope_error_vs_seconds"] if s["slope_error_vs_seconds"] is not None else float("nan")]
            for s in data["slopes"]]
    emit(format_table(rows, ["sampler", "precision", "slope(stderr, s)", "slope(stderr, rays)", "slope(|error|, s)"],
                      digits=3, title="fitted log-log slopes (plain Monte Carlo: -0.5)"))
    if "files" in data:
        emit("wrote " + ", ".join(data["files"]))
    return 0
