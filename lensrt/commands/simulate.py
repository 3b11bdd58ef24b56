"""``lensrt simulate``: a photograph (and its depth map) through a real lens onto the sensor -- blur per
field, depth and wavelength, distortion, lateral colour, relative illumination; optionally the sensor and
raw conversion."""
from __future__ import annotations

import argparse
import math

from ._common import emit, print_json

__all__ = ["register", "cmd_simulate"]


def _grid(text: str) -> tuple[int, int]:
    """``RxC`` -> (rows, cols), at least 2 x 2 nodes (an argparse type: a bad value is argparse's usage error)."""
    from ..analysis.fields import parse_grid
    from ..errors import LensrtError
    try:
        rows, cols = parse_grid(text)
    except LensrtError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    if rows < 2 or cols < 2:
        raise argparse.ArgumentTypeError(f"a PSF grid of {text} nodes: use at least 2x2 (corners included)")
    return rows, cols


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="image simulation: a picture (and its depth map) through the real lens",
                       description="Simulate the image a real lens forms of IMAGE, the scene as an ideal pinhole "
                                   "sees it over the sensor: spectral (Mallett-Yuksel 2019) wavelength bands, "
                                   "spatially varying real PSFs per band and depth (cached), distortion and "
                                   "lateral colour from the real chief ray, relative illumination, depth layers "
                                   "composited back to front; optionally a sensor preset and raw conversion.")
    p.add_argument("image", metavar="IMAGE", help="PNG/JPEG/TIFF (sRGB), EXR or .npy (linear RGB)")
    p.add_argument("--depth", metavar="DEPTH", help="depth map in metres: EXR (Z), .npy, or 16-bit PNG with "
                                                    "--depth-scale-m")
    p.add_argument("--depth-scale-m", type=float, default=None, metavar="S", help="metres per PNG/TIFF code value")
    p.add_argument("--lens", "-l", default=None, metavar="L", help="lens file or library name (default: the built-in)")
    p.add_argument("--focus-m", type=float, default=None, metavar="S",
                   help="focus distance in m (default: the depth map's median, else infinity)")
    p.add_argument("--f-number", type=float, default=None, metavar="N", help="stop down to f/N")
    p.add_argument("--sensor", default="full-frame", metavar="FORMAT", help="sensor format the image spans "
                                                                              "(full-frame, aps-c, ..., WxH mm)")
    p.add_argument("--encoding", choices=["auto", "srgb", "linear"], default="auto", help="input encoding")
    p.add_argument("--bands", type=int, default=4, help="wavelength bands, one PSF each (default 4)")
    p.add_argument("--layers", type=int, default=8, help="depth layers at most (default 8)")
    p.add_argument("--grid", type=_grid, default=(5, 7), metavar="RxC", help="PSF nodes over the frame (default 5x7)")
    p.add_argument("--rays", type=float, default=32768, help="Monte Carlo rays per PSF (default 32768)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cache-dir", default=None, help="PSF cache (default $LENSRT_CACHE/simulate or "
                                                     "~/.cache/lensrt/simulate)")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the PSF cache")
    p.add_argument("--max-memory", metavar="SIZE", default=None,
                   help="working memory of the blur (e.g. 4G; default 60%% of the machine's): a larger picture "
                        "is blurred in bands of rows, the same result")
    p.add_argument("--sensor-preset", default=None, metavar="P", help="expose a sensor preset and develop it")
    p.add_argument("--iso", type=float, default=None, metavar="I")
    p.add_argument("--exposure-s", type=float, default=None, metavar="T",
                   help="exposure time (default: metered on 18 %% grey)")
    p.add_argument("--white-cd-m2", type=float, default=100.0, help="luminance of the input's white (default 100)")
    p.add_argument("--no-noise", action="store_true", help="sensor without noise")
    p.add_argument("--device", default=None, help="cpu, cuda or cuda:N")
    p.add_argument("-o", "--output", default=None, metavar="PREFIX", help="output prefix (default: IMAGE's stem "
                                                                          "+ _sim)")
    p.add_argument("--json", action="store_true", help="print the sidecar as one JSON object")
    p.set_defaults(func=cmd_simulate)


def _check(args: argparse.Namespace) -> None:
    from ..errors import LensrtError
    for name in ("bands", "layers"):
        if getattr(args, name) < 1:
            raise LensrtError(f"--{name} must be at least 1")
    if not (math.isfinite(args.rays) and args.rays >= 512):
        raise LensrtError(f"--rays {args.rays:g}: use 512 or more")
    if args.white_cd_m2 <= 0 or not math.isfinite(args.white_cd_m2):
        raise LensrtError("--white-cd-m2 must be a positive number")
    if args.sensor_preset is None and (args.iso is not None or args.exposure_s is not None):
        raise LensrtError("--iso and --exposure-s need --sensor-preset")


def cmd_simulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from ..loading import load_lens
    from ..simulate.inputs import read_depth_m, read_image_linear
    from ..simulate.outputs import write_outputs
    from ..simulate.pipeline import SimulateOptions, simulate
    from ._limits import memory_limit
    _check(args)
    if args.sensor_preset is not None:
        from ..sensor import get_preset
        get_preset(args.sensor_preset)  # an unknown preset fails before the work
    image = read_image_linear(args.image, args.encoding)
    depth = read_depth_m(args.depth, image.shape[:2], args.depth_scale_m) if args.depth else None
    focus_m = args.focus_m if args.focus_m is not None else (float(np.median(depth)) if depth is not None else math.inf)
    lens = load_lens(args.lens)
    opts = SimulateOptions(sensor=args.sensor, focus_m=focus_m, f_number=args.f_number, bands=args.bands,
                           layers=args.layers, grid=args.grid, rays=int(args.rays), seed=args.seed,
                           cache_dir=args.cache_dir, use_cache=not args.no_cache, device=args.device,
                           max_memory_bytes=memory_limit(args))
    sim = simulate(image, lens, depth, opts)
    prefix = args.output or str(Path(args.image).with_suffix("")) + "_sim"
    files = write_outputs(sim, prefix, preset=args.sensor_preset, iso=args.iso, exposure_s=args.exposure_s,
                          white_cd_m2=args.white_cd_m2, seed=args.seed, noise=not args.no_noise)
    if args.json:
        data = sim.to_dict()
        data["files"] = files
        print_json(data)
        return 0
    err = sim.errors()
    emit(f"{lens.name}: {image.shape[1]} x {image.shape[0]} px on {args.sensor}, focus {focus_m:g} m, "
         f"{len(sim.layers)} layer(s), {sim.bands.count} bands, {len(sim.psf_grid.node_rows)}x"
         f"{len(sim.psf_grid.node_cols)} PSF nodes ({'cache' if sim.psf_grid.cached else 'traced'}) in "
         f"{sim.seconds['total']:.2f} s")
    emit(f"errors: PSF Monte Carlo {err['psf_monte_carlo']['rel_stderr_rms_lit']:.2g} RMS relative (Y); "
         f"interpolation TV {err['interpolation']['tv_max']} (Monte Carlo floor included); "
         f"relative illumination +- {err['relative_illumination_stderr_max']:.2g}")
    emit("wrote " + ", ".join(files.values()))
    return 0
