"""``lensrt mtf``: MTF of real rays -- curves, against field, through focus, and with the sensor (system MTF)."""
from __future__ import annotations

import argparse
import math

import numpy as np

from ._common import emit, print_json, lens_config
from ._psf_options import add_psf_options, fields_from_args, host_device, setup_from_args

__all__ = ["register", "cmd_mtf", "default_mtf_fields"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mtf", help="MTF curves, MTF against field and through focus, system MTF with the sensor",
                       description="Sagittal and tangential MTF of real-ray PSFs (geometric, diffraction or auto per "
                                   "field) against frequency (cycles/mm), against field at the reference frequencies "
                                   "(10/20/40 lp/mm on full frame, scaled for --sensor, p. 114), through focus, with "
                                   "the diffraction limit, the detector aperture, a 4-spot OLPF and their product, the "
                                   "system MTF; the sensor Nyquist frequency is marked. Default fields: 7 real image "
                                   "heights from the centre to the corner of --sensor.")
    add_psf_options(p, method_default="auto")
    g = p.add_argument_group("frequencies and sensor")
    g.add_argument("--freq-max", type=float, default=None, metavar="CPMM",
                   help="highest frequency of the curves (default: twice the sensor Nyquist frequency)")
    g.add_argument("--n-freqs", type=int, default=65, help="frequencies along each curve (default 65)")
    g.add_argument("--pixel-pitch-um", type=float, default=4.0, help="sensor pixel pitch (default 4.0 um)")
    g.add_argument("--fill-factor", type=float, default=1.0, help="light-sensitive area fraction of a pixel (default 1)")
    g.add_argument("--olpf-um", type=float, default=None,
                   help="4-spot OLPF spot separation in um (default: the pixel pitch; 0: no OLPF)")
    g.add_argument("--through-focus", metavar="RANGE:STEPS",
                   help="through-focus MTF at the reference frequencies over +-RANGE mm in STEPS planes, e.g. 0.1:21")
    p.set_defaults(func=cmd_mtf)


def default_mtf_fields(lens, sensor: str, plane_z_mm: float, device, n: int = 7):
    """``n`` real image heights from 0 to the sensor's half-diagonal, or to the lens's coverage if that is
    smaller: where the real chief ray still passes every clear aperture (a circular fisheye's rim is dark)."""
    from ..analysis.fields import chief_height_table, image_height_fields
    from ..paraxial.photographic import sensor_format
    half = 0.5 * sensor_format(sensor).diagonal_mm
    if lens.fields.max_radial <= 0:
        return image_height_fields(lens, [0.0], plane_z_mm, device)
    cover = chief_height_table(lens, plane_z_mm, device=device).clear_height_mm
    top = min(half, 0.98 * cover)
    return image_height_fields(lens, [round(v, 3) for v in np.linspace(0.0, top, n)], plane_z_mm, device)


def _through_focus_arg(text: str) -> np.ndarray:
    from ..errors import LensrtError
    try:
        rng, steps = text.split(":")
        r, k = float(rng), int(steps)
    except ValueError:
        raise LensrtError(f"bad --through-focus {text!r}", hint="give RANGE:STEPS, e.g. 0.1:21 (mm, planes)") from None
    if not (r > 0 and math.isfinite(r) and 3 <= k <= 201):
        raise LensrtError(f"--through-focus {text!r}: RANGE must be > 0 mm and STEPS within 3..201")
    return np.linspace(-r, r, k)


def cmd_mtf(args: argparse.Namespace) -> int:
    from ..analysis.psf.mtf_curves import Detector, mtf_against_field, mtf_curves, through_focus
    from ..analysis.psf.map import run_psf_map
    from ..errors import LensrtError
    from ..loading import load_lens
    from ._common import reader_options
    from ._parallel import executor_from_args, progress_printer
    if args.device and not args.devices:
        args.devices = args.device
    detector = Detector(args.pixel_pitch_um, args.fill_factor, args.olpf_um)
    fmax = 2.0 * detector.nyquist_cpmm if args.freq_max is None else float(args.freq_max)
    if not (fmax > 0 and math.isfinite(fmax)) or args.n_freqs < 3:
        raise LensrtError("--freq-max must be positive and --n-freqs at least 3")
    dz = _through_focus_arg(args.through_focus) if args.through_focus else None
    lens = load_lens(args.file, config=lens_config(args), **reader_options(args))
    dev = host_device(args)
    freqs = np.linspace(0.0, fmax, args.n_freqs)
    setup = setup_from_args(args, lens, dev, mtf_curve_cpmm=tuple(float(v) for v in freqs),
                            max_pitch_um=0.45e3 / fmax)
    given = any(getattr(args, k) for k in ("field_deg", "field", "object_height_mm", "image_height_mm", "grid"))
    if given:
        fields, shape = fields_from_args(args, lens, setup.plane_z_mm, dev)
    else:
        fields, shape = default_mtf_fields(lens, args.sensor, setup.plane_z_mm, dev), None
    with executor_from_args(args, uses_device=True) as ex:
        pmap = run_psf_map(setup, fields, args.seed, ex, progress_printer(args, "fields"), shape,
                           args.sensor if args.grid else None)
    curves = [mtf_curves(r, lens, detector, freqs) for r in pmap.results]
    vs_field = mtf_against_field(pmap.results)
    focus = spots = None
    if dz is not None:
        from ..analysis.psf.focus_spots import through_focus_spots
        focus = [through_focus(setup, f, dz, setup.mtf_freqs_cpmm, args.seed, dev) for f in fields]
        spots = [through_focus_spots(setup, f, dz, device=dev) for f in fields]
    out = {"lens": lens.name, "setup": setup.to_dict(), "sensor": args.sensor, "detector": detector.to_dict(),
           "reference_freqs_cpmm": list(setup.mtf_freqs_cpmm), "seconds": pmap.seconds, "rays_total": pmap.rays,
           "fields": [dict(label=f.label, **c) for f, c in zip(fields, curves)], "mtf_vs_field": vs_field,
           "through_focus": focus, "through_focus_spots": [sp.to_dict() for sp in spots] if spots else None,
           "psf": [r.to_dict() for r in pmap.results]}
    files = _write(args, pmap, out, curves, vs_field, focus, spots) if args.out else {}
    out["files"] = files
    if args.json:
        print_json(out)
        return 0
    _print(lens, setup, fields, pmap, detector, focus)
    if files:
        emit("wrote " + ", ".join(files.values()))
    return 0


def _print(lens, setup, fields, pmap, detector, focus) -> None:
    from ..io.table import format_table
    fr = setup.mtf_freqs_cpmm
    emit(f"{lens.name or lens.path}: MTF at {', '.join(f'{v:.3g}' for v in fr)} cycles/mm "
         f"(10/20/40 lp/mm scaled to the sensor), spectrum {setup.spectrum.name}, focus {setup.focus['focus']}; "
         f"sensor Nyquist {detector.nyquist_cpmm:.4g} cycles/mm ({detector.pixel_pitch_um:g} um pixels)")
    from ..analysis.psf.mtf_curves import reference_table
    rows, heads = reference_table(fields, pmap.results, fr)
    emit(format_table(rows, heads, digits=3))
    if focus:
        rows = [[f.label] + [f"{v * 1e3:+.1f}" for v in d["best_focus_mm"]["sagittal"]]
                + [f"{v * 1e3:+.1f}" for v in d["best_focus_mm"]["tangential"]] for f, d in zip(fields, focus)]
        heads = ["field"] + [f"S {v:.3g}" for v in fr] + [f"T {v:.3g}" for v in fr]
        emit(format_table(rows, heads, title="best focus from the through-focus MTF (um from the focus plane)"))


def _write(args, pmap, out: dict, curves, vs_field, focus, spots=None) -> dict:
    from ..io.paths import output_dir
    from ..views.plots.psf import (plot_mtf_curves, plot_mtf_vs_field, plot_system_mtf, plot_through_focus,
                                   plot_through_focus_spots)
    from ..views.psf_files import write_psf_map_exr
    from ..io.table import dumps_json
    d = output_dir(args.out)
    lens = pmap.setup.lens.name or "lens"
    files = {"json": d / "mtf.json", "exr": d / "psf.exr", "png": d / "mtf.png", "system": d / "mtf_system.png",
             "field": d / "mtf_field.png"}
    write_psf_map_exr(files["exr"], pmap)
    sel = list(range(len(curves))) if len(curves) <= 4 else \
        sorted({0, len(curves) // 3, (2 * len(curves)) // 3, len(curves) - 1})
    c0 = curves[0]
    plot_mtf_curves(files["png"], c0["freqs_cpmm"],
                    [(pmap.fields[i].label, curves[i]["lens_sagittal"], curves[i]["lens_tangential"]) for i in sel],
                    diffraction=c0["diffraction_limit"], nyquist_cpmm=c0.get("nyquist_cpmm"),
                    title=f"{lens}\nlens MTF (S solid, T dashed)")
    plot_system_mtf(files["system"], c0, title=f"{lens}, {pmap.fields[0].label}\nsystem MTF = lens x OLPF x detector")
    plot_mtf_vs_field(files["field"], vs_field, title=f"{lens}\nMTF against image height (S solid, T dashed)")
    if focus:
        files["focus"] = d / "mtf_focus.png"
        plot_through_focus(files["focus"], focus[0], title=f"{lens}, {pmap.fields[0].label}\nthrough-focus MTF")
    for k, sp in enumerate(spots or []):
        files[f"spots{k}"] = d / f"mtf_focus_spots_{k}.png"
        plot_through_focus_spots(files[f"spots{k}"], sp, title=f"{lens}, {sp.label}: through-focus spot diagrams")
    files["json"].write_text(dumps_json(out) + "\n")
    return {k: str(v) for k, v in files.items()}
