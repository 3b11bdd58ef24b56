"""``lensrt wavefront``: RMS and PV wavefront error, Strehl ratio and Zernike coefficients per field and wavelength."""
from __future__ import annotations

import argparse

from ._common import add_lens_argument, add_reader_options, emit, print_json, lens_config

__all__ = ["register", "cmd_wavefront"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("wavefront", help="RMS/PV wavefront error, Strehl ratio and Zernike coefficients of the OPD",
                       description="The wavefront of real rays at field points: RMS and PV wavefront error about the "
                                   "mean (with and without tilt), the Strehl ratio (diffraction PSF peak against the "
                                   "same pupil without aberration, with the Marechal estimate), and the Zernike "
                                   "coefficients of the OPD in Noll and Fringe order (normalisation stated, fit "
                                   "residual reported), against a chosen reference sphere. Waves at each wavelength.")
    add_lens_argument(p)
    add_reader_options(p)
    g = p.add_argument_group("field points, spectrum and focus (as lensrt psf)")
    g.add_argument("--field-deg", metavar="LIST", help="field angles in degrees along +y, e.g. 0,10,20")
    g.add_argument("--field", metavar="LIST", help="normalised fields Hy, e.g. 0,0.7,1")
    g.add_argument("--object-height-mm", metavar="LIST", help="object heights (mm) for a lens with a near object")
    g.add_argument("--image-height-mm", metavar="LIST", help="real image heights (mm) along +y")
    g.add_argument("--wavelength-nm", metavar="LIST", help="wavelength(s) in nm (default: the lens file's)")
    g.add_argument("--focus", default="image", metavar="FOCUS",
                   help="image (default), paraxial, best, a shift in mm, or e.g. paraxial+1.0 or best+0.01")
    g = p.add_argument_group("wavefront")
    g.add_argument("--reference", choices=["chief", "centroid", "best_fit"], default="chief",
                   help="reference sphere: centred on the chief ray's image point (default), on the spot's "
                        "centroid, or the best-fit sphere (tilt and defocus removed)")
    g.add_argument("--zernike-terms", type=int, default=37, metavar="N", help="Zernike terms fitted (default 37)")
    g.add_argument("--pupil-samples", type=int, default=128, help="pupil grid cells a side (default 128)")
    g.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    g = p.add_argument_group("output")
    g.add_argument("--json", action="store_true", help="print one JSON object")
    g.add_argument("--plot", action="store_true", help="write an OPD map and a Zernike bar chart per field (--out)")
    g.add_argument("--out", metavar="DIR", help="write wavefront.json (and the plots) into DIR")
    p.set_defaults(func=cmd_wavefront, grid=None, sensor="full-frame")


def cmd_wavefront(args: argparse.Namespace) -> int:
    from ..analysis.psf.setup import make_setup
    from ..analysis.psf.spectrum import parse_spectrum
    from ..analysis.psf.wavefront_error import wavefront_error
    from ..errors import LensrtError
    from ..io.table import format_table
    from ..loading import load_lens
    from ._common import reader_options
    from ._psf_options import fields_from_args, parse_list
    if not 4 <= args.zernike_terms <= 231:
        raise LensrtError(f"--zernike-terms {args.zernike_terms} must be between 4 and 231")
    if not 32 <= args.pupil_samples <= 1024:
        raise LensrtError(f"--pupil-samples {args.pupil_samples} must be between 32 and 1024")
    if args.plot and not args.out:
        raise LensrtError("--plot writes files: give --out DIR")
    lens = load_lens(args.file, config=lens_config(args), **reader_options(args))
    spec = parse_spectrum(lens, parse_list(args.wavelength_nm, "wavelength"), None, (400.0, 700.0), 7)
    setup = make_setup(lens, spec, args.focus, args.device, method="diffraction", pupil_samples=args.pupil_samples)
    fields, _ = fields_from_args(args, lens, setup.plane_z_mm, args.device)
    results = []
    for f in fields:
        results.append((f, wavefront_error(setup, f, reference=args.reference, n_terms=args.zernike_terms,
                                           device=args.device)))
    data = {"lens": lens.name or str(lens.path), "focus": setup.focus["focus"], "plane_z_mm": setup.plane_z_mm,
            "reference": args.reference,
            "fields": [{"field": f.to_dict(), "wavelengths": [m.to_dict() for m in ms]} for f, ms in results]}
    files = _write(args, results, data) if args.out else []
    data["files"] = files
    if args.json:
        print_json(data)
        return 0
    emit(f"{data['lens']}: wavefront at focus {data['focus']} (z = {setup.plane_z_mm:.4f} mm), reference sphere "
         f"{args.reference}; waves at each wavelength")
    rows = [[f.label, m.wavelength_nm, m.rms_waves, m.pv_waves, m.rms_waves_no_tilt, m.strehl, m.strehl_marechal]
            for f, ms in results for m in ms]
    emit(format_table(rows, ["field", "wavelength_nm", "RMS_waves", "PV_waves", "RMS no tilt_waves", "Strehl",
                             "Marechal"], digits=4))
    for f, ms in results:
        m = ms[0]
        terms = ", ".join(f"Z{j + 1} {v:+.4f}" for j, v in enumerate(m.zernike_noll_waves[:11]))
        emit(f"{f.label} {m.wavelength_nm:g} nm Noll (unit RMS) waves: {terms} ... "
             f"(fit residual RMS {m.zernike_noll_residual_rms_waves:.2e})")
    if files:
        emit("wrote " + ", ".join(files))
    return 0


def _write(args: argparse.Namespace, results, data: dict) -> list[str]:
    from ..io.paths import output_dir
    from ..io.table import dumps_json
    out = output_dir(args.out)
    files = [str(out / "wavefront.json")]
    (out / "wavefront.json").write_text(dumps_json({**data, "files": files}), encoding="utf-8")
    if args.plot:
        from ..views.plots.wavefront import plot_wavefront
        for k, (f, ms) in enumerate(results):
            path = out / f"wavefront_{k}.png"
            plot_wavefront(ms[0], f.label, path)
            files.append(str(path))
    return files
