"""``lensrt render [SCENE]``: render a scene through its lens; ``--plan`` shows what a render would do."""
from __future__ import annotations

import argparse
import math

from ..errors import LensrtError
from ._common import emit, print_json
from ._limits import add_max_memory_argument, memory_limit, parse_seed

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("render", help="render a scene through the lens (--plan: show the render plan)")
    p.add_argument("scene", nargs="?", default=None, metavar="SCENE",
                   help="scene file (.toml) or built-in scene name; default: the built-in default scene")
    p.add_argument("--plan", action="store_true", help="print the scene and the render plan, render nothing")
    p.add_argument("--list", action="store_true", help="list the built-in scenes")
    p.add_argument("--lens", metavar="FILE", help="use this lens instead of the scene's")
    p.add_argument("--preview", metavar="OUT.png",
                   help="write a quick pinhole view of the scene (no lens: layout and colours only)")
    p.add_argument("-o", "--output", metavar="PREFIX",
                   help="output prefix: PREFIX.exr (spectral irradiance), PREFIX.png (preview), PREFIX.json, and "
                        "with a sensor preset PREFIX_raw.exr and PREFIX_camera.png (default: the scene's name)")
    p.add_argument("--width", type=int, default=None, metavar="PX",
                   help="image width in pixels (default: the scene's; --preview: 360); rows keep the aspect ratio")
    p.add_argument("--spp", type=int, default=None,
                   help="samples (paths) per pixel (default: the scene's; --preview: 16)")
    p.add_argument("--spp-per-pass", type=int, default=None, metavar="N",
                   help="paths per pixel in each pass (default: spp / 8); passes give the standard errors")
    p.add_argument("--time-budget", type=float, default=None, metavar="S",
                   help="stop after the pass that reaches S seconds")
    p.add_argument("--target-error", type=float, default=None, metavar="REL",
                   help="stop when the RMS relative standard error of Y over lit pixels reaches REL (e.g. 0.02)")
    p.add_argument("--seed", type=parse_seed, default=None, help="random seed, 0..2^63-1 (default: the scene's)")
    p.add_argument("--focus", choices=("best", "paraxial"), default="best",
                   help="best: least RMS spot on axis (default); paraxial: the paraxial image plane")
    p.add_argument("--band-nm", type=float, default=10.0, metavar="NM",
                   help="width of the output spectral bands (default 10 nm)")
    p.add_argument("--window", default=None, metavar="R0,R1,C0,C1",
                   help="render only these sensor pixels (rows R0..R1-1, columns C0..C1-1)")
    p.add_argument("--device", default=None, help="cpu, cuda, cuda:N (default: CUDA when present)")
    p.add_argument("--json", action="store_true", help="one JSON object (with --plan, --list or a render)")
    from .bokeh import add_tilt_shift_arguments
    add_tilt_shift_arguments(p, "tilt-shift camera (the whole lens moved in front of the fixed sensor, after "
                                "focusing; overrides the scene's [camera] lens_tilt_deg, lens_swing_deg, "
                                "lens_shift_mm; docs/guide/reflex.md)")
    add_max_memory_argument(p)
    from ._parallel import add_parallel_arguments
    add_parallel_arguments(p)
    p.set_defaults(func=cmd_render)


def _tilt_shift(args: argparse.Namespace, scene):
    """``scene`` with --lens-tilt-deg / --lens-swing-deg / --lens-shift-mm put into its camera block."""
    from dataclasses import replace
    from .bokeh import parse_pair
    cam = scene.camera
    changes = {}
    for opt, key in (("lens_tilt_deg", "lens_tilt_rad"), ("lens_swing_deg", "lens_swing_rad")):
        v = getattr(args, opt, None)
        if v is not None:
            if not (math.isfinite(v) and abs(v) < 45.0):
                raise LensrtError(f"--{opt.replace('_', '-')} {v:g} must be a finite angle below 45 deg",
                                  hint="tilt-shift lenses tilt and swing by a few degrees (about 8 to 15 at most)")
            changes[key] = math.radians(v)
    if getattr(args, "lens_shift_mm", None) is not None:
        changes["lens_shift_mm"] = parse_pair(args.lens_shift_mm, "--lens-shift-mm", True)
    return replace(scene, camera=replace(cam, **changes)) if changes else scene


def _load_lens_or_note(scene, override: str | None):
    """The scene's lens, or ``None`` and the reason when it cannot be loaded (the plan still prints)."""
    from ..loading import load_lens
    try:
        return load_lens(override if override is not None else scene.camera.lens_source), None
    except LensrtError as err:
        return None, str(err)


def cmd_render(args: argparse.Namespace) -> int:
    from ..render.scene.load import builtin_scenes, load_scene
    if args.list:
        rows = []
        for path in builtin_scenes():
            s = load_scene(path)
            rows.append({"name": s.name, "file": str(path), "description": s.description})
        if args.json:
            print_json({"scenes": rows})
        else:
            width = max(len(r["name"]) for r in rows)
            for r in rows:
                emit(f"{r['name']:<{width}}  {r['description']}")
        return 0
    scene = _tilt_shift(args, load_scene(args.scene))
    if args.preview:
        return _preview(args, scene)
    from ._render_run import options_from_args
    options_from_args(args)  # the option ranges first (one error line each)
    lens, note = _load_lens_or_note(scene, args.lens)
    if lens is None:
        raise LensrtError(f"cannot load the scene's lens: {note}")
    from ..render.footprint import check_render
    checked = check_render(scene, lens, width=args.width, band_width_nm=args.band_nm, focus=args.focus,
                           limit_bytes=memory_limit(args))
    if args.plan:
        return _plan(args, checked, lens)
    from ._render_run import run
    return int(run(args, scene, lens) or 0)


def _plan(args: argparse.Namespace, checked, lens) -> int:
    """``--plan``: the plan of the checked scene, the camera and the memory estimate; renders nothing."""
    from ..core.budget import format_bytes
    from ..render.plan import plan_render
    scene, cam = checked.scene, checked.camera
    plan = plan_render(scene, lens)
    focus = "infinity" if cam.focus_distance_mm == float("inf") else f"{cam.focus_distance_mm / 1000.0:.4g} m"
    if args.json:
        print_json({"scene": scene.name, "plan": plan.to_dict(), "lens_note": None,
                    "camera": {"f_number": cam.f_number, "focus_distance_mm": cam.focus_distance_mm,
                               "sensor_z_mm": cam.sensor_z_mm, "lens_tilt_rad": cam.tilt_rad,
                               "lens_swing_rad": cam.swing_rad, "lens_shift_mm": list(cam.shift_mm)},
                    "memory": {"estimate_bytes": checked.memory.bytes, "detail": checked.memory.detail}})
        return 0
    emit(scene.summary())
    emit("")
    emit(plan.describe())
    moved = (f"; lens tilted {math.degrees(cam.tilt_rad):g} deg, swung {math.degrees(cam.swing_rad):g} deg, shifted "
             f"({cam.shift_mm[0]:g}, {cam.shift_mm[1]:g}) mm" if cam.is_tilt_shift else "")
    emit(f"  camera       f/{cam.f_number:.3g}, focus {focus}, sensor at z = {cam.sensor_z_mm:.4f} mm{moved}")
    emit(f"  memory       about {format_bytes(checked.memory.bytes)} ({checked.memory.detail})")
    return 0


def _preview(args: argparse.Namespace, scene) -> int:
    """Pinhole preview -> 8-bit sRGB PNG, exposed so that the 99th-percentile luminance is white."""
    import numpy as np
    from PIL import Image
    from ..io.paths import output_file
    from ..render.preview import preview_pinhole
    from ..colour import srgb_encode, xyz_to_linear_srgb
    width = 360 if args.width is None else args.width
    spp = 16 if args.spp is None else args.spp
    if width < 1 or width > 8192 or spp < 2:
        raise LensrtError("--width must be 1-8192 and --spp at least 2")
    est = preview_pinhole(scene, width, samples_per_pixel=spp, seed=scene.render.seed, device=args.device)
    xyz = est.value
    white = float(np.percentile(xyz[..., 1], 99)) or 1.0
    rgb = srgb_encode(xyz_to_linear_srgb(xyz / white))
    try:
        Image.fromarray((rgb * 255.0 + 0.5).astype(np.uint8)).save(output_file(args.preview))
    except (OSError, ValueError) as err:
        raise LensrtError(f"cannot write {args.preview!r}: {err}") from None
    emit(f"{args.preview}: pinhole view of {scene.name!r}, {xyz.shape[1]} x {xyz.shape[0]} px, "
         f"{est.samples:.3g} rays in {est.seconds:.3g} s; white = {white:.4g} cd/m^2 (99th percentile)")
    return 0
