"""``lensrt converge``: error against run time of a Monte Carlo quantity, per sampler and precision."""
from __future__ import annotations

import argparse
import math

from ._common import add_lens_argument, emit, print_json, lens_config

__all__ = ["register", "cmd_converge", "QUANTITIES", "build_quantity", "converge_table"]

QUANTITIES = ("psf-rms", "mtf", "rel-illum", "bokeh", "render")
#: default largest sample count per quantity (rays; paths per pixel for the render)
DEFAULT_MAX = {"psf-rms": 1 << 20, "mtf": 1 << 20, "rel-illum": 1 << 18, "bokeh": 1 << 20, "render": 1024}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("converge", help="error against run time: a Monte Carlo quantity at growing sample counts "
                                        "against a reference, per sampler and precision, with fitted slopes",
                       description="Runs one Monte Carlo quantity at growing sample counts with each sampler "
                                   "(random, stratified, low-discrepancy) and precision, --repeats times per point "
                                   "with independent seeds, and measures the RMS error against a reference -- a "
                                   "closed form where the lens has one (pure defocus of a stigmatic lens, the cos^4 "
                                   "case), else a high-sample run -- beside the RMS of the reported standard errors; "
                                   "fits log-log slopes of error against seconds and samples (plain Monte Carlo: "
                                   "-0.5) and says what stratification buys. --out writes converge.json and "
                                   "converge.png.")
    add_lens_argument(p)
    p.add_argument("--quantity", choices=QUANTITIES, default="psf-rms",
                   help="psf-rms: RMS spot radius; mtf: MTF at --freq-cpmm; rel-illum: relative illumination; "
                        "bokeh: mean Y over a region of a bokeh spot; render: mean Y over a window of a small render "
                        "(default psf-rms)")
    g = p.add_argument_group("the study")
    g.add_argument("--samples", type=float, default=None, metavar="N",
                   help="largest sample count: rays (paths per pixel for render); default 2^20 (rel-illum 2^18, "
                        "render 1024)")
    g.add_argument("--min-samples", type=float, default=None, metavar="N",
                   help="smallest sample count (default: --samples / 64, at least 64 per batch; render 16)")
    g.add_argument("--points", type=int, default=7, help="sample counts (powers of two) between them (default 7)")
    g.add_argument("--repeats", type=int, default=8, help="independent runs per point for the RMS error (default 8)")
    g.add_argument("--reference", default="auto", metavar="N|closed|auto",
                   help="N: a high-sample run of N samples (sobol, float64; render: random); closed: the closed form "
                        "(an error where there is none); auto (default): closed form if any, else 16 x --samples")
    g.add_argument("--samplers", default=None, metavar="LIST",
                   help="comma list of random, stratified, sobol, r2 (default random,stratified,sobol; render: "
                        "random,stratified)")
    g.add_argument("--precisions", default=None, metavar="LIST",
                   help="comma list of float32, float64 (default both; the render is float32 only)")
    g.add_argument("--batches", type=int, default=16, help="independent batches behind each standard error "
                                                          "(default 16)")
    g.add_argument("--seed", type=int, default=0, help="seed of the study (default 0)")
    g.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    g = p.add_argument_group("psf-rms, mtf, rel-illum")
    g.add_argument("--field", type=float, default=None, metavar="HY",
                   help="normalised field Hy (default 0.7; rel-illum 1.0; the closed forms need 0 for psf-rms)")
    g.add_argument("--focus", default="image", help="psf-rms/mtf focus as for lensrt psf (default image)")
    g.add_argument("--wavelength-nm", default=None, metavar="LIST", help="wavelengths (default: the lens file's; "
                                                                        "rel-illum: the primary)")
    g.add_argument("--freq-cpmm", type=float, default=20.0, help="mtf: spatial frequency (default 20 cycles/mm)")
    g.add_argument("--azimuth", choices=("tangential", "sagittal"), default="tangential", help="mtf direction")
    g = p.add_argument_group("bokeh")
    g.add_argument("--focus-m", type=float, default=2.0, help="focus distance in m (default 2)")
    g.add_argument("--source-m", type=float, default=10.0, help="point source on the axis at D m (default 10)")
    g.add_argument("--pixel-um", type=float, default=None, help="pixel pitch (default: about 200 px across the spot)")
    g.add_argument("--region", type=float, default=0.2, metavar="F",
                   help="region side as a fraction of the spot's size (default 0.2)")
    g.add_argument("--region-offset", default="0,0", metavar="DX,DY",
                   help="region centre from the spot centre, in spot sizes (default 0,0; e.g. 0.4,0 near the rim)")
    g = p.add_argument_group("render")
    g.add_argument("--scene", default=None, help="scene file or built-in name (default: the default scene); FILE "
                                                 "replaces its lens")
    g.add_argument("--width", type=int, default=72, help="image width in pixels (default 72)")
    g.add_argument("--window", default=None, metavar="R0,R1,C0,C1",
                   help="the pixel region (default: the central 8 x 8 pixels)")
    g = p.add_argument_group("output")
    g.add_argument("--out", metavar="DIR", help="write converge.json and converge.png into DIR")
    g.add_argument("--json", action="store_true", help="print one JSON object instead of the tables")
    p.set_defaults(func=cmd_converge)


def _names(text: str | None, allowed: tuple[str, ...], what: str) -> list[str] | None:
    from ..errors import LensrtError
    if text is None:
        return None
    vals = [t.strip() for t in text.split(",") if t.strip()]
    bad = [v for v in vals if v not in allowed]
    if not vals or bad:
        raise LensrtError(f"bad {what} {text!r}", hint=f"a comma list of {', '.join(allowed)}")
    return vals


def _ints(text: str, n: int, what: str) -> tuple[float, ...]:
    from ..errors import LensrtError
    try:
        vals = tuple(float(t) for t in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise LensrtError(f"bad {what} {text!r}", hint=f"{n} comma-separated numbers")
    return vals


def build_quantity(args: argparse.Namespace):
    """The :class:`lensrt.studies.convergence.study.Quantity` the options describe."""
    from ..studies.convergence import quantities as CQ
    from ..errors import LensrtError
    from ..loading import load_lens
    from ..units import MM_PER_M
    dev = args.device
    if args.quantity == "render":
        from ..studies.convergence.render import RenderRegion
        from ..render.scene.load import load_scene
        scene = load_scene(args.scene)
        lens = load_lens(args.file, config=lens_config(args)) if args.file else None
        window = tuple(int(v) for v in _ints(args.window, 4, "--window")) if args.window else None
        if not 1 <= args.width <= 4096:
            raise LensrtError("--width must be 1-4096 pixels")
        return RenderRegion(scene, lens, args.width, window, dev)
    lens = load_lens(args.file, config=lens_config(args))
    if args.quantity == "bokeh":
        from ..analysis.bokeh.entry import focus_lens, spot_source
        if not (args.source_m > 0 and args.focus_m > 0 and 0 < args.region <= 1):
            raise LensrtError("--source-m and --focus-m must be positive and --region within (0, 1]")
        focus = focus_lens(lens, args.focus_m * MM_PER_M)
        src = spot_source(lens, focus, args.source_m * MM_PER_M, device=dev)
        return CQ.BokehRegion(lens, focus, src, pixel_um=args.pixel_um, batches=args.batches,
                              region_fraction=args.region, region_offset=_ints(args.region_offset, 2, "--region-offset"),
                              device=dev)
    if args.quantity == "rel-illum":
        hy = 1.0 if args.field is None else args.field
        if not hy > 0:
            raise LensrtError("rel-illum needs a field off the axis (--field > 0)")
        wl = None
        if args.wavelength_nm:
            from ._psf_options import parse_list
            wl = parse_list(args.wavelength_nm, "wavelength")[0]
        return CQ.RelIllum(lens, hy, wl, args.batches, dev)
    from ..analysis.fields import normalised_fields
    from ..analysis.psf.setup import make_setup
    from ..analysis.psf.spectrum import parse_spectrum
    from ._psf_options import parse_list
    spec = parse_spectrum(lens, parse_list(args.wavelength_nm, "wavelength"), None, None, 7)
    hy = 0.7 if args.field is None else args.field
    f = normalised_fields([hy])[0]
    if args.quantity == "mtf":
        if not (args.freq_cpmm > 0 and math.isfinite(args.freq_cpmm)):
            raise LensrtError(f"--freq-cpmm {args.freq_cpmm:g} must be a positive frequency (cycles/mm)")
        setup = make_setup(lens, spec, args.focus, dev, rays=1 << 16, batches=args.batches, pixels=128,
                           ee_fractions=(), mtf_freqs_cpmm=(), max_pitch_um=0.4e3 / args.freq_cpmm)
        return CQ.PsfMtf(setup, f, args.freq_cpmm, args.azimuth, dev)
    setup = make_setup(lens, spec, args.focus, dev, rays=1 << 16, batches=args.batches, pixels=64,
                       ee_fractions=(), mtf_freqs_cpmm=())
    return CQ.PsfRms(setup, f, dev)


def converge_table(data: dict) -> str:
    """The terminal report of a :func:`lensrt.studies.convergence.study.converge` result."""
    from ..io.table import format_table
    sc, u = data["display_scale"], data["display_unit"]
    unit = f" ({u})" if u else ""
    ref = data["reference"]
    rk = (f"closed form {ref['value'] * sc:.9g}{unit}: {ref['description']}" if ref["kind"] == "closed form" else
          f"{ref['value'] * sc:.9g} +- {ref['stderr'] * sc:.2g}{unit}, high-sample run: {ref['description']} "
          f"({ref['seconds']:.3g} s)")
    out = [f"{data['label']}", f"reference: {rk}",
           f"{data['repeats']} independent runs per point; RMS error over them against the reference, beside the RMS "
           f"reported standard error (ratio measured / expected, expected = hypot(reported, reference's); about 1 "
           f"when the reported errors are honest)"]
    rows = [[r["sampler"], r["precision"], r["samples"], f"{r['seconds']:.3g}", f"{r['rms_error'] * sc:.3g}",
             f"{r['rms_stderr'] * sc:.3g}", r["error_ratio"],
             f"{r['bias'] * sc:+.2g}", "ref." if r["reference_limited"] else ""] for r in data["runs"]]
    out.append(format_table(rows, ["sampler", "precision", data["sample_unit"], "seconds", f"RMS error{unit}",
                                   f"RMS stderr{unit}", "ratio", f"bias{unit}", "limited"], digits=2))
    gains = {(g["sampler"], g["precision"]): g for g in data["gains"]}
    rows = []  # None (nothing to fit or divide) prints as "-"
    for s in data["slopes"]:
        g = gains[(s["sampler"], s["precision"])]
        rows.append([s["sampler"], s["precision"], s["error_vs_seconds"], s["error_vs_samples"],
                     s["stderr_vs_samples"], s["pooled_error_ratio"], g["variance_ratio"],
                     g["variance_ratio_reported"], g["efficiency_ratio"]])
    out.append(format_table(rows, ["sampler", "precision", "slope(error, s)", f"slope(error, {data['sample_unit']})",
                                   "slope(stderr, samples)", "pooled ratio", "variance gain", "(reported)",
                                   "efficiency gain"],
                            digits=3,
                            title="fitted log-log slopes (plain Monte Carlo: -0.5); measured / expected RMS error pooled "
                                  "over the points; gains over random sampling of the same precision at the largest "
                                  "count: variance ratio (measured errors; reported standard errors), and variance x "
                                  "seconds"))
    if any(s["points"] < 2 for s in data["slopes"]):
        out.append("-: fewer than two points are not limited by the reference's error, so no error slope; "
                   "give a larger --reference (or fewer --samples)")
    out.append(f"{data['seconds']:.3g} s in all")
    return "\n".join(out)


def cmd_converge(args: argparse.Namespace) -> int:
    from ..studies.convergence.study import converge, default_counts
    from ..errors import LensrtError
    from ..io.table import dumps_json
    q = build_quantity(args)
    top = DEFAULT_MAX[args.quantity] if args.samples is None else args.samples
    low = max(q.min_samples, top / 64) if args.min_samples is None else args.min_samples
    if not (math.isfinite(top) and math.isfinite(low) and top >= low >= q.min_samples):
        raise LensrtError(f"--samples {top:g} and --min-samples {low:g} must satisfy samples >= min-samples >= "
                          f"{q.min_samples}")
    if not 2 <= args.points <= 24 or not 1 <= args.repeats <= 1000:
        raise LensrtError("--points must be 2-24 and --repeats 1-1000")
    ref = args.reference
    if ref not in ("auto", "closed"):
        try:
            ref = int(float(ref))
        except ValueError:
            raise LensrtError(f"--reference {args.reference!r} is not a count, closed or auto") from None
    counts = default_counts(int(top), int(low), args.points)
    samplers = _names(args.samplers, q.samplers, "--samplers") or [s for s in ("random", "stratified", "sobol")
                                                                    if s in q.samplers]
    precisions = _names(args.precisions, q.precisions, "--precisions") or list(q.precisions)
    from ._parallel import progress_printer
    data = converge(q, counts, samplers, precisions, repeats=args.repeats, seed=args.seed, reference=ref,
                    progress=None if args.json else progress_printer(args, "converge: runs"))
    data["lens"] = getattr(getattr(q, "lens", None), "name", None) or args.file
    data["command"] = "lensrt converge " + " ".join(_argv_of(args))
    if args.out:
        from ..io.paths import output_dir
        from ..views.plots.convergence import plot_error_vs_time
        d = output_dir(args.out)
        plot_error_vs_time(d / "converge.png", data)
        data["files"] = [str(d / "converge.json"), str(d / "converge.png")]
        (d / "converge.json").write_text(dumps_json(data) + "\n")
    if args.json:
        print_json(data)
        return 0
    emit(converge_table(data))
    if "files" in data:
        emit("wrote " + ", ".join(data["files"]))
    return 0


def _argv_of(args: argparse.Namespace) -> list[str]:
    """The options that differ from the defaults, as a command line (for the record in converge.json)."""
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    register(sub)
    defaults = vars(sub.choices["converge"].parse_args([]))
    out = [args.file] if args.file else []
    for k, v in vars(args).items():
        if k in ("func", "file", "command") or k not in defaults or v == defaults[k]:
            continue
        flag = "--" + k.replace("_", "-")
        out += [flag] if v is True else [flag, str(v)]
    return out
