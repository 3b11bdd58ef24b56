"""Options shared by ``lensrt psf`` and ``lensrt mtf``: fields, spectrum, focus, method, sampling, stopping."""
from __future__ import annotations

import argparse
import math
from typing import Any

from ..errors import LensrtError
from ._limits import MAX_COUNT, parse_count, parse_seed  # MAX_COUNT, parse_count: re-exported

__all__ = ["MAX_COUNT", "add_psf_options", "parse_list", "parse_count", "setup_from_args", "fields_from_args", "host_device",
           "print_psf_table"]


def parse_list(text: str | None, what: str) -> list[float] | None:
    """``"0,10,20"`` -> [0.0, 10.0, 20.0] (finite numbers)."""
    if text is None:
        return None
    try:
        vals = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError:
        raise LensrtError(f"bad {what} list {text!r}", hint="give comma-separated numbers, e.g. 0,10,20") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise LensrtError(f"{what} list {text!r} must hold finite numbers")
    return vals


def add_psf_options(p: argparse.ArgumentParser, method_default: str = "geometric") -> None:
    from ..commands._common import add_lens_argument, add_reader_options
    add_lens_argument(p)
    add_reader_options(p)
    g = p.add_argument_group("field points (default: the lens file's fields)")
    g.add_argument("--field-deg", metavar="LIST", help="field angles in degrees along +y, e.g. 0,10,20")
    g.add_argument("--field", metavar="LIST", help="normalised fields Hy in [0, 1] (beyond 1 allowed), e.g. 0,0.7,1")
    g.add_argument("--object-height-mm", metavar="LIST", help="object heights (mm) for a lens with a near object")
    g.add_argument("--image-height-mm", metavar="LIST",
                   help="real image heights (mm) along +y, mapped to fields through the real chief ray")
    g.add_argument("--grid", metavar="RxC", help="a RxC grid of image positions over --sensor, corners included "
                                                   "(a PSF map), e.g. 9x9")
    g.add_argument("--sensor", default="full-frame",
                   help="sensor format for --grid and the MTF reference frequencies: full-frame, aps-c, mft, 1-inch, "
                        "... or WxH in mm (default full-frame)")
    g = p.add_argument_group("spectrum and focus")
    g.add_argument("--wavelength-nm", metavar="LIST", help="wavelength(s) in nm, equal weights (default: the lens file's)")
    g.add_argument("--spectrum", metavar="NAME",
                   help="lens (default), a CIE illuminant (D65, A, D50, FL2, ...), planck:<K>K or daylight:<K>K, "
                        "sampled continuously over --band")
    g.add_argument("--band", metavar="MIN:MAX", help="wavelength band of --spectrum in nm (default 400:700)")
    g.add_argument("--lines", type=int, default=7, metavar="N",
                   help="wavelengths a diffraction PSF sums for --spectrum (midpoints of N equal bins; default 7)")
    g.add_argument("--focus", default="image", metavar="FOCUS",
                   help="image (the file's image surface, default), paraxial, best (minimum axial RMS spot at the "
                        "primary wavelength), a shift in mm from the image surface, or e.g. best+0.01")
    g = p.add_argument_group("method and sampling")
    g.add_argument("--method", choices=["geometric", "diffraction", "auto"], default=method_default,
                   help=f"geometric (ray histogram), diffraction (wavefront -> FFT/MFT/Huygens) or auto "
                        f"(per field; see docs/explanation/how-psfs-are-made.md) (default {method_default})")
    g.add_argument("--rays", type=parse_count, default=1 << 20, metavar="N",
                   help="Monte Carlo rays per field point (geometric; 1e6 notation ok; default 1048576)")
    g.add_argument("--sampler", choices=["random", "stratified", "sobol", "r2"], default="sobol",
                   help="pupil sampler: random (plain Monte Carlo), stratified (jittered), sobol (scrambled, "
                        "default) or r2 (low-discrepancy)")
    g.add_argument("--seed", type=parse_seed, default=0,
                   help="job seed, 0..2^63-1; each field's seed derives from it (default 0)")
    g.add_argument("--batches", type=int, default=32, help="independent batches for standard errors (default 32)")
    g.add_argument("--precision", choices=["float32", "float64"], default="float32",
                   help="geometric stream kernel precision (default float32; wavefronts are always float64)")
    g.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    g.add_argument("--pixels", type=int, default=128, help="PSF grid pixels per side (default 128)")
    g.add_argument("--pitch-um", type=float, default=None, help="PSF grid pitch in um (default: automatic per field)")
    g.add_argument("--pupil-samples", type=int, default=128, help="diffraction pupil grid (doubled as needed; default 128)")
    g = p.add_argument_group("error against run time")
    g.add_argument("--target-error", type=float, default=None, metavar="E",
                   help="add rays until the error reaches E: the RMS radius's relative standard error (--target rms, "
                        "e.g. 0.001) or the largest standard error of the MTF at the reference frequencies (--target mtf)")
    g.add_argument("--target", choices=["rms", "mtf"], default=None, help="what --target-error measures")
    g.add_argument("--time-budget", type=float, default=None, metavar="S",
                   help="seconds per field point for a progressive run (stops before the next round would overrun)")
    g = p.add_argument_group("output")
    g.add_argument("--out", metavar="DIR", help="write JSON, EXR and PNG files into DIR")
    g.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    from ._limits import add_max_memory_argument, add_max_rays_argument
    add_max_memory_argument(p)
    add_max_rays_argument(p)
    from ._parallel import add_parallel_arguments
    add_parallel_arguments(p)


def host_device(args: argparse.Namespace) -> str | None:
    """The device for host-side set-up traces (focus search, field mapping)."""
    if args.device:
        return args.device
    devs = getattr(args, "devices", None)
    if devs and devs not in ("auto", "all") and "," not in devs:
        return devs
    if devs and "," in devs:
        return devs.split(",")[0]
    return None


def fields_from_args(args: argparse.Namespace, lens, plane_z_mm: float, device: str | None):
    """(fields, grid shape or None) from the field options."""
    from ..analysis import fields as F
    given = [k for k in ("field_deg", "field", "object_height_mm", "image_height_mm", "grid") if getattr(args, k)]
    if len(given) > 1:
        raise LensrtError("give one way of naming field points: " + ", ".join("--" + k.replace("_", "-") for k in given))
    if args.grid:
        shape = F.parse_grid(args.grid)
        from ._limits import check_psf_budget
        check_psf_budget(args, shape[0] * shape[1])
        return F.sensor_grid_fields(lens, args.sensor, shape, plane_z_mm, device), shape
    if args.field_deg:
        return F.angle_fields(lens, parse_list(args.field_deg, "field angle")), None
    if args.field:
        return F.normalised_fields(parse_list(args.field, "field")), None
    if args.object_height_mm:
        return F.height_fields(lens, parse_list(args.object_height_mm, "object height")), None
    if args.image_height_mm:
        return F.image_height_fields(lens, parse_list(args.image_height_mm, "image height"), plane_z_mm, device), None
    return F.lens_fields(lens), None


def setup_from_args(args: argparse.Namespace, lens, device: str | None, **overrides: Any):
    """The :class:`~lensrt.analysis.psf.setup.PsfSetup` the options describe."""
    from ..analysis.psf.otf import reference_frequencies_cpmm
    from ..analysis.psf.setup import make_setup
    from ..analysis.psf.spectrum import parse_band, parse_spectrum
    from ..paraxial.photographic import sensor_format
    from ._limits import check_psf_budget
    check_psf_budget(args)  # rays, grids and pupils of one field point, before the focus search
    spec = parse_spectrum(lens, parse_list(args.wavelength_nm, "wavelength"), args.spectrum, parse_band(args.band),
                          args.lines)
    fmt = sensor_format(args.sensor)
    target = args.target or ("mtf" if getattr(args, "command", "") == "mtf" else "rms")
    opts = dict(method=args.method, rays=args.rays, sampler=args.sampler, batches=args.batches,
                precision=args.precision, pixels=args.pixels, pitch_um=args.pitch_um,
                mtf_freqs_cpmm=tuple(float(v) for v in reference_frequencies_cpmm(fmt.diagonal_mm)),
                target_error=args.target_error, target_quantity=target, time_budget_s=args.time_budget,
                pupil_samples=args.pupil_samples)
    opts.update(overrides)
    return make_setup(lens, spec, args.focus, device, **opts)


def print_psf_table(pmap, emit) -> None:
    """One row per field: where, how, how long, and the estimates with standard errors (um)."""
    from ..io.table import format_table
    from ..units import UM_PER_MM

    def pm(r, key: str) -> str:
        e = r.estimates.get(key)
        if e is None:
            return "-"
        if e.stderr:
            return f"{float(e.value) * UM_PER_MM:.4g} +- {float(e.stderr) * UM_PER_MM:.2g}"
        return f"{float(e.value) * UM_PER_MM:.4g}"
    rows = []
    for f, r in zip(pmap.fields, pmap.results):
        rows.append([f.label, f"{r.reference_mm[0]:.3f}, {r.reference_mm[1]:.3f}", r.kind.replace("diffraction-", "d-"),
                     f"{r.samples:.3g}", r.seconds, pm(r, "rms_radius_mm"), pm(r, "ee50_radius_mm"),
                     pm(r, "ee80_radius_mm"), f"{r.grid.pitch_um:.3g}"])
    emit(format_table(rows, ["field", "chief x, y (mm)", "method", "rays", "seconds", "RMS radius (um)",
                             "EE50 radius (um)", "EE80 radius (um)", "pitch (um)"], digits=3))
