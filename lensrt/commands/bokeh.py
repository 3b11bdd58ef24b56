"""``lensrt bokeh``: defocused point sources through the real lens -- one spot, or a map across the frame."""
from __future__ import annotations

import argparse
import math
from typing import Any

from ._common import add_lens_argument, emit, print_json, lens_config
from ._parallel import add_parallel_arguments, executor_from_args, progress_printer
from ._limits import add_max_memory_argument, add_max_rays_argument, parse_seed
from ._psf_options import parse_count

__all__ = ["register", "parse_pair", "parse_list", "add_tilt_shift_arguments"]


def register(sub: argparse._SubParsersAction) -> None:
    from ..analysis.bokeh.light import SPECTRUM_HELP
    p = sub.add_parser("bokeh", help="bokeh of point sources out of focus: one spot, or a map across the frame",
                       description="Traces Monte Carlo rays from point sources over the real (vignetted) entrance "
                                   "pupil and a spectrum onto the sensor of a lens focused by unit focusing, and "
                                   "writes the blur spots as an sRGB PNG, a linear CIE XYZ EXR (Y = illuminance in "
                                   "lux) and a JSON summary with rays, seconds and the noise level. Distances are "
                                   "measured from the lens's first vertex in its focused position. Pictures are "
                                   "upright, as a photograph.")
    add_lens_argument(p)
    g = p.add_argument_group("focus (one of; default --focus-m 2)")
    g.add_argument("--focus-m", type=float, metavar="S", help="focus distance in m ('inf' for infinity)")
    g.add_argument("--focus-mm", type=float, metavar="S", help="focus distance in mm")
    g.add_argument("--extension-mm", type=float, metavar="E",
                   help="unit-focus extension: the lens moved out by E mm from infinity focus (p. 12)")
    g.add_argument("--sensor-z-mm", type=float, metavar="Z", help="sensor plane at z = Z mm behind the first vertex")
    s = p.add_argument_group("sources")
    s.add_argument("--source-m", type=float, default=10.0, metavar="D",
                   help="distance of the point source in m (default 10; a map's depth unless --depths-m)")
    s.add_argument("--field-deg", metavar="[X,]Y",
                   help="one source seen at this field angle from the entrance pupil (deg; default on axis)")
    s.add_argument("--object-mm", metavar="X,Y", help="one source at this lateral position (mm)")
    s.add_argument("--image-mm", metavar="X,Y",
                   help="one source whose real chief ray meets the sensor at (X, Y) mm")
    s.add_argument("--map", metavar="COLSxROWS",
                   help="a bokeh map: sources on a COLS x ROWS grid over the frame (uniform on the sensor, placed "
                        "by the real chief ray), one per depth in each cell, in one image")
    s.add_argument("--depths-m", metavar="LIST", help="map depths in m, comma separated (e.g. 1,5,20)")
    s.add_argument("--spectrum", default="D65", metavar="NAME", help="source spectrum: " + SPECTRUM_HELP)
    s.add_argument("--intensity-cd", type=float, default=1.0, metavar="I",
                   help="luminous intensity of each source in cd (default 1)")
    s.add_argument("--intensity-scaling", choices=("distance2", "none"), default="distance2",
                   help="maps: distance2 (default) makes a source at d as bright as I cd at 1 m (I (d/1 m)^2) so "
                        "every depth shows; none: I cd each")
    o = p.add_argument_group("sensor and pixels")
    o.add_argument("--sensor", default="full-frame", metavar="FORMAT",
                   help="sensor format name or WxH in mm (default full-frame 36 x 24)")
    o.add_argument("--pixels", metavar="WxH", help="map resolution (default 1500 wide, square pixels)")
    o.add_argument("--pixel-um", type=float, metavar="P",
                   help="spot: pixel pitch in um (default: about 200 pixels across the spot)")
    o.add_argument("--window-px", type=int, metavar="N", help="spot: a square window of N pixels")
    a = p.add_argument_group("aperture and iris (default: the lens file's)")
    a.add_argument("--f-number", type=float, metavar="N", help="stop the lens to f/N (the real stop radius for D = f/N)")
    a.add_argument("--blades", type=int, metavar="N", help="iris blades (0 = circular, 3..64)")
    a.add_argument("--blade-rotation-deg", type=float, metavar="DEG",
                   help="iris rotation: a vertex at this angle from +x (deg)")
    a.add_argument("--blade-roundness", type=float, metavar="R",
                   help="blade curvature: 0 straight blades .. 1 a circle")
    add_tilt_shift_arguments(p, "tilt-shift (the whole lens moved in front of the fixed sensor; docs/guide/reflex.md)")
    m = p.add_argument_group("Monte Carlo")
    m.add_argument("--rays", type=parse_count, default=1_000_000, metavar="N", help="rays per source (default 1e6)")
    m.add_argument("--sampler", choices=("sobol", "random", "stratified", "r2"), default="sobol",
                   help="pupil and wavelength samples (default sobol)")
    m.add_argument("--seed", type=parse_seed, default=0, help="random seed, 0..2^63-1 (default 0)")
    m.add_argument("--batches", type=int, default=32, help="independent batches for standard errors (default 32)")
    m.add_argument("--precision", choices=("float32", "float64"), default="float32")
    m.add_argument("--target-error", type=float, default=None, metavar="E",
                   help="add rays (doubling rounds, --rays the cap) until the RMS over each disc of the per-pixel "
                        "relative standard error of Y is at most E (e.g. 0.05)")
    m.add_argument("--time-budget", type=float, default=None, metavar="S",
                   help="one spot: stop adding rays before the next round would overrun S seconds of tracing")
    w = p.add_argument_group("output")
    w.add_argument("--out", default=".", metavar="DIR", help="output folder (default: here)")
    w.add_argument("--name", default=None, help="file name stem (default bokeh or bokeh_map)")
    w.add_argument("--exposure", type=float, default=None, metavar="K",
                   help="PNG exposure: multiply XYZ by K before sRGB (default: 99.5th percentile at white)")
    w.add_argument("--no-files", action="store_true", help="write nothing, print the summary only")
    w.add_argument("--json", action="store_true", help="print the JSON summary instead of the table")
    add_max_memory_argument(p)
    add_max_rays_argument(p)
    add_parallel_arguments(p)
    p.add_argument("--device", dest="devices", metavar="DEVICE", help="alias of --devices (cpu, cuda, cuda:N)")
    p.set_defaults(func=cmd_bokeh)


def add_tilt_shift_arguments(p: argparse.ArgumentParser, title: str) -> None:
    """--lens-tilt-deg, --lens-swing-deg, --lens-shift-mm (bokeh and render) in a group named ``title``."""
    t = p.add_argument_group(title)
    t.add_argument("--lens-tilt-deg", type=float, metavar="T",
                   help="tilt the lens by T deg about the sensor's x axis through its stop (T > 0 turns its axis "
                        "toward +y): the plane of sharp focus tilts by the Scheimpflug condition")
    t.add_argument("--lens-swing-deg", type=float, metavar="S",
                   help="swing the lens by S deg about its own y axis (S > 0 turns its axis toward +x)")
    t.add_argument("--lens-shift-mm", metavar="[X,]Y", help="shift the lens across the sensor by (X, Y) mm")


def parse_pair(text: str, what: str, allow_single: bool = False) -> tuple[float, float]:
    """``"X,Y"`` -> (X, Y); ``"Y"`` -> (0, Y) when ``allow_single``."""
    from ..errors import LensrtError
    parts = [t.strip() for t in str(text).split(",")]
    try:
        vals = [float(t) for t in parts]
    except ValueError:
        vals = []
    if len(vals) == 1 and allow_single:
        vals = [0.0, vals[0]]
    if len(vals) != 2 or not all(math.isfinite(v) for v in vals):
        raise LensrtError(f"{what} {text!r} is not " + ("[X,]Y" if allow_single else "X,Y"), hint="e.g. 0,10")
    return vals[0], vals[1]


def parse_list(text: str, what: str) -> list[float]:
    from ..errors import LensrtError
    try:
        vals = [float(t) for t in str(text).split(",") if t.strip()]
    except ValueError:
        vals = []
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise LensrtError(f"{what} {text!r} is not a comma list of positive numbers", hint="e.g. 1,5,20")
    return vals


def _grid(text: str, what: str) -> tuple[int, int]:
    from ..errors import LensrtError
    a, sep, b = str(text).lower().partition("x")
    try:
        v = (int(a), int(b))
    except ValueError:
        v = (0, 0)
    if not sep or v[0] < 1 or v[1] < 1:
        raise LensrtError(f"{what} {text!r} is not COLSxROWS with positive integers", hint="e.g. 15x10")
    return v


def _checked_name(args: argparse.Namespace) -> str | None:
    """``--name`` as a plain file stem (never a path out of ``--out``)."""
    from ._limits import safe_stem
    return None if args.name is None else safe_stem(args.name, "--name")


def _check_map_budget(args: argparse.Namespace, pixels: tuple[int, int], grid: tuple[int, int], n_depths: int) -> None:
    """Memory of the map image and the total ray count, before anything is traced."""
    from ..core.budget import check_memory, estimate_bokeh_map_bytes
    from ._limits import check_rays, memory_limit
    n_sources = grid[0] * grid[1] * n_depths
    check_memory(estimate_bokeh_map_bytes(pixels[1], pixels[0], n_sources, args.batches, "--pixels: a map"),
                 memory_limit(args))
    check_rays(args, float(args.rays) * n_sources, f"--map {grid[0]}x{grid[1]} x {n_depths} depth(s) x --rays")


def _check_spot_budget(args: argparse.Namespace) -> None:
    from ..core.budget import MAX_SIDE_PX, check_memory, estimate_bokeh_map_bytes
    from ..errors import LensrtError
    from ._limits import check_rays, memory_limit
    check_rays(args, float(args.rays))
    if args.window_px is not None:
        if not 1 <= args.window_px <= MAX_SIDE_PX:
            raise LensrtError(f"--window-px {args.window_px} must be 1..{MAX_SIDE_PX} pixels")
        check_memory(estimate_bokeh_map_bytes(args.window_px, args.window_px, 1, args.batches, "--window-px: a spot"),
                     memory_limit(args))
    if args.pixel_um is not None and not (math.isfinite(args.pixel_um) and args.pixel_um > 0):
        raise LensrtError(f"--pixel-um {args.pixel_um:g} must be a positive pitch in um")


def _focus(args: argparse.Namespace, lens: Any):
    from ..analysis.bokeh.entry import focus_lens
    from ..errors import LensrtError
    from ..units import MM_PER_M
    given = [k for k in ("focus_m", "focus_mm", "extension_mm", "sensor_z_mm") if getattr(args, k) is not None]
    if len(given) > 1:
        raise LensrtError("give one of --focus-m, --focus-mm, --extension-mm, --sensor-z-mm")
    if args.extension_mm is not None:
        return lens, focus_lens(lens, extension_mm=args.extension_mm)
    if args.sensor_z_mm is not None:
        return lens, focus_lens(lens, sensor_z_mm=args.sensor_z_mm)
    d = args.focus_mm if args.focus_mm is not None else (2.0 if args.focus_m is None else args.focus_m) * MM_PER_M
    if lens.focus.is_unit:
        return lens, focus_lens(lens, d)
    # a focus group / floating groups: move them (real best focus on the fixed sensor)
    from ..analysis.focusing import focus_at
    moved = focus_at(lens, d).lens
    return moved, focus_lens(moved, sensor_z_mm=moved.image_z_mm)


def _iris(args: argparse.Namespace, lens: Any):
    from ..errors import LensrtError
    from ..prescription.model import Iris
    if args.blades is None and args.blade_rotation_deg is None and args.blade_roundness is None:
        return None
    base = lens.iris
    try:
        return Iris(base.blades if args.blades is None else args.blades,
                    base.rotation_rad if args.blade_rotation_deg is None else math.radians(args.blade_rotation_deg),
                    base.roundness if args.blade_roundness is None else args.blade_roundness,
                    base.obstruction_ratio)
    except LensrtError as err:
        raise LensrtError(f"iris: {err.message}", hint="--blades 0 or 3..64, --blade-roundness 0..1") from None


def _obscured(lens: Any) -> bool:
    """True when some surface carries a central circular obscuration (a reflex lens's secondary)."""
    return any(a.obscuration and a.shape == "circle" and not (a.decenter_x_mm or a.decenter_y_mm)
               for s in lens.surfaces for a in s.apertures)


def _annulus(img: Any) -> dict:
    """The ring of an obscured lens's axial spot: radii and their ratio with standard errors."""
    from ..analysis.bokeh.measure import annulus_radii
    (inner, outer, ratio), (se_in, se_out, se_ratio) = annulus_radii(img)
    return {"inner_radius_mm": float(inner), "inner_radius_stderr_mm": float(se_in),
            "outer_radius_mm": float(outer), "outer_radius_stderr_mm": float(se_out),
            "ratio": float(ratio), "ratio_stderr": float(se_ratio),
            "method": "moments of r^2 about the centroid (a uniformly lit annulus), jackknife over the batches"}


def _tilt_shift(args: argparse.Namespace, lens: Any) -> tuple[Any, bool]:
    """The lens tilted/swung/shifted by --lens-tilt-deg/--lens-swing-deg/--lens-shift-mm (and whether it moved)."""
    if args.lens_tilt_deg is None and args.lens_swing_deg is None and args.lens_shift_mm is None:
        return lens, False
    from ..prescription.tilt_shift import tilt_shift_lens
    tilt = math.radians(0.0 if args.lens_tilt_deg is None else args.lens_tilt_deg)
    swing = math.radians(0.0 if args.lens_swing_deg is None else args.lens_swing_deg)
    shift = (0.0, 0.0) if args.lens_shift_mm is None else parse_pair(args.lens_shift_mm, "--lens-shift-mm", True)
    return tilt_shift_lens(lens, tilt, shift, swing_rad=swing), True


def cmd_bokeh(args: argparse.Namespace) -> int:
    from ..analysis.bokeh.entry import bokeh_map, bokeh_spot, gaussian_blur, spot_source, stop_radius_for_f_number
    from ..errors import LensrtError
    from ..loading import load_lens
    from ..paraxial.photographic import sensor_format
    from ..units import MM_PER_M
    lens = load_lens(args.file, config=lens_config(args))
    lens, focus = _focus(args, lens)
    iris = _iris(args, lens)
    if args.f_number is not None:
        from ..paraxial.fnumber import check_f_number
        check_f_number(lens, args.f_number)  # as render and sweep refuse it: never wider than the lens opens
    stop_r = None if args.f_number is None else stop_radius_for_f_number(lens, args.f_number)
    lens, moved = _tilt_shift(args, lens)
    rays = args.rays
    stem = _checked_name(args)
    if not rays >= args.batches >= 2:
        raise LensrtError(f"--rays {rays:g} must be at least --batches ({args.batches}) and --batches >= 2")
    if not (math.isfinite(args.source_m) and args.source_m > 0):
        raise LensrtError(f"--source-m {args.source_m:g} must be a positive distance in m")
    for name in ("target_error", "time_budget", "exposure"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise LensrtError(f"--{name.replace('_', '-')} {v:g} must be positive")
    common = dict(light=args.spectrum, intensity_cd=args.intensity_cd, rays=rays, iris=iris, stop_radius_mm=stop_r,
                  sampler=args.sampler, seed=args.seed, batches=args.batches, precision=args.precision,
                  target_error=args.target_error)
    if args.map:
        if args.field_deg or args.object_mm or args.image_mm:
            raise LensrtError("--map places its own sources: drop --field-deg/--object-mm/--image-mm")
        if args.time_budget is not None:
            raise LensrtError("--time-budget applies to one spot", hint="use --target-error (per source) for a map")
        fmt = sensor_format(args.sensor)
        if args.pixels:
            pixels = _grid(args.pixels, "--pixels")
        else:
            pixels = (1500, max(1, round(1500 * fmt.height_mm / fmt.width_mm)))
        depths = parse_list(args.depths_m, "--depths-m") if args.depths_m else [args.source_m]
        _check_map_budget(args, pixels, _grid(args.map, "--map"), len(depths))
        with executor_from_args(args, uses_device=True) as ex:
            img = bokeh_map(lens, focus, grid=_grid(args.map, "--map"), depths_mm=[d * MM_PER_M for d in depths],
                            sensor_mm=(fmt.width_mm, fmt.height_mm), pixels=pixels,
                            intensity_scaling=args.intensity_scaling, executor=ex,
                            progress=progress_printer(args, "source batches"), **common)
        name = stem or "bokeh_map"
        extra = {"sensor": fmt.name, "depths_m": depths}
    else:
        from ..parallel.local import resolve_devices
        field = parse_pair(args.field_deg, "--field-deg", True) if args.field_deg else None
        obj = parse_pair(args.object_mm, "--object-mm") if args.object_mm else None
        im = parse_pair(args.image_mm, "--image-mm") if args.image_mm else None
        device = resolve_devices(args.devices)[0]
        _check_spot_budget(args)
        src = spot_source(lens, focus, args.source_m * MM_PER_M, field_deg=field, object_mm=obj, image_mm=im,
                          device=device)
        img = bokeh_spot(lens, focus, src, pixel_um=args.pixel_um, window_px=args.window_px, device=device,
                         time_budget_s=args.time_budget, **common)
        name = stem or "bokeh"
        extra = {}
        if field is None and obj is None and im is None and img.batch_xyz is not None and _obscured(lens):
            extra["annulus"] = _annulus(img)
        if field is None and obj is None and im is None and not moved:
            g = gaussian_blur(lens, focus, args.source_m * MM_PER_M, stop_radius_mm=stop_r)
            extra["gaussian_blur_diameter_mm"] = g.diameter_mm
            extra["paraxial_defocus_mm"] = g.defocus_mm
    summary = img.to_dict()
    summary.update(extra)
    if not args.no_files:
        from ..views.bokeh_files import write_bokeh_files
        try:
            paths = write_bokeh_files(img, args.out, name, args.exposure)
        except OSError as err:
            raise LensrtError(f"cannot write to {args.out}: {err.strerror}") from None
        summary["files"] = {k: str(v) for k, v in paths.items()}
    if args.json:
        print_json(summary)
        return 0
    emit(_report(summary, lens))
    return 0


def _report(d: dict, lens: Any) -> str:
    s, f = d["settings"], d["settings"]["focus"]
    dist = "inf" if f["distance_mm"] is not None and math.isinf(f["distance_mm"]) else (
        f"{f['distance_mm'] / 1000.0:.4g} m" if f["distance_mm"] is not None else "beyond infinity")
    lines = [f"{s['lens'] or lens.path}: bokeh of {d['n_sources']} point source{'s' if d['n_sources'] != 1 else ''} "
             f"({d['n_sources_on_sensor']} on the sensor)",
             f"focus {dist} (extension {f['extension_mm']:.4f} mm, sensor at z = {f['sensor_z_mm']:.4f} mm); "
             f"stop radius {s['stop_radius_mm']:.4g} mm, iris {s['iris']['blades']} blades "
             f"(rotation {s['iris']['rotation_deg']:g} deg, roundness {s['iris']['roundness']:g})",
             f"light {s['light']['spectrum']} (x, y = {s['light']['chromaticity_xy'][0]:.4f}, "
             f"{s['light']['chromaticity_xy'][1]:.4f}); {d['frame']['pixels'][0]} x {d['frame']['pixels'][1]} px "
             f"at {d['frame']['pitch_um']:.4g} um"]
    if d["n_sources"] == 1 and d["sources"][0].get("reached_sensor"):
        r = d["sources"][0]
        lines.append(f"source at {r['depth_mm'] / 1000.0:g} m, object point ({r['object_mm'][0]:.4g}, "
                     f"{r['object_mm'][1]:.4g}) mm: pupil transmission {r['transmission']:.4f} +- "
                     f"{r['transmission_stderr']:.2g}, centroid ({r['centroid_mm'][0]:.5f}, {r['centroid_mm'][1]:.5f}) +- "
                     f"{max(r['centroid_stderr_mm']):.1g} mm, RMS radius {r['rms_radius_mm'] * 1000:.5g} +- {r['rms_radius_stderr_mm'] * 1000:.2g} um")
        lines.append(f"luminous flux on the sensor {r['luminous_flux_lm']:.5g} +- "
                     f"{r['luminous_flux_stderr_lm']:.2g} lm; {r['rays']:.4g} rays, {r['seconds']:.3g} s of tracing"
                     + (f", {r['rounds']} rounds (stopped by {r['stop_reason']})" if "rounds" in r else ""))
        if "gaussian_blur_diameter_mm" in d:
            lines.append(f"Gaussian blur disc {d['gaussian_blur_diameter_mm'] * 1000:.5g} um (defocus "
                         f"{d['paraxial_defocus_mm']:+.4f} mm); 2 sqrt(2) x RMS radius "
                         f"{2 * math.sqrt(2) * r['rms_radius_mm'] * 1000:.5g} um")
        if "annulus" in d:
            a = d["annulus"]
            lines.append(f"ring (central obscuration): radii {a['inner_radius_mm']:.4f} +- "
                         f"{a['inner_radius_stderr_mm']:.2g} / {a['outer_radius_mm']:.4f} +- "
                         f"{a['outer_radius_stderr_mm']:.2g} mm, ratio {a['ratio']:.4f} +- {a['ratio_stderr']:.2g}")
    nz = d["noise"]
    noise = (f"{nz['rel_stderr_median']:.3g} median, {nz['rel_stderr_max']:.3g} worst source, RMS over a disc "
             f"{nz['rel_stderr_rms_max']:.3g} worst" if nz["rel_stderr_median"] is not None else "n/a")
    lines.append(f"{d['rays']:.4g} rays in {d['seconds']:.3g} s ({(d['rays_per_second'] or 0):.3g} rays/s); "
                 f"noise (per-pixel relative standard error of Y in the discs): {noise} ({nz['method']})")
    if "files" in d:
        lines.append("wrote " + ", ".join(d["files"].values()))
    return "\n".join(lines)
