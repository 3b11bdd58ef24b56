"""Occlusion at a depth edge: ``lensrt simulate`` against lensrt's own path tracer on two planes.

Scene: a far plane (``--far-m``) filling the view and a near plane (``--near-m``) covering the left
half of it, its right edge on the optical axis -- so that an ideal pinhole at the entrance pupil
sees the edge on the picture's vertical centre line at every depth. Each plane is a uniform image
texture (8-bit PNG, read identically by both): one bright, one dark. Case ``sharp-front``: focus on
the near plane, dark foreground over a bright background (does the blurred background leak onto the
sharp foreground?). Case ``blurred-front``: focus on the far plane, bright foreground over a dark
background (how far does the blurred foreground spread?). ``lensrt render`` traces camera paths
through the real lens and both planes; ``lensrt simulate`` takes the pinhole picture and its depth
map (two layers). Both in lux (Y), as :mod:`acceptance_simulate`.

Measured on the profile across the edge (mean of Y over the middle half of the rows):

* halo width: the 10-90 % width of the edge (pixels), simulate and render;
* leak: the largest |simulate - render| over the profile, in units of the step (bright - dark) --
  over the sharp side only (``leak_sharp_side``, beyond the in-focus PSF's reach) and anywhere
  (``leak_max``); with the render's own noise of the profile beside it.

    python benchmarks/acceptance_occlusion.py [--pixels 96x72] [--sensor 12x9] [--spp 256] [--case both]
        [--near-m 0.7] [--far-m 5] (and the options of acceptance_simulate.py)
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

BRIGHT, DARK = 0.8, 0.05  # sRGB-encoded texture values of the two planes


def parser() -> argparse.ArgumentParser:
    """:func:`acceptance_simulate.parser` with this check's defaults and its planes and cases."""
    from acceptance_simulate import parser as base
    ap = base()
    ap.description = __doc__.splitlines()[0]
    ap.set_defaults(sensor="12x9", rays=1 << 15, grid="5x7", bands=4, out="occlusion_out")
    ap.add_argument("--near-m", type=float, default=0.7)
    ap.add_argument("--far-m", type=float, default=5.0)
    ap.add_argument("--case", default="both", choices=("both", "sharp-front", "blurred-front"))
    return ap


def width_10_90(profile: np.ndarray, centre: int, span: int = 20) -> float:
    """10-90 % width (pixels) of the step at ``centre`` (a pixel boundary): the distance between the first
    crossings of 10 % and 90 % of the way between plateaus taken 16 to ``span`` pixels either side (local, so
    that the frame's relative illumination does not enter)."""
    lo, hi = float(profile[centre - span:centre - 16].mean()), float(profile[centre + 16:centre + span].mean())
    t = (profile[centre - 16:centre + 16] - lo) / (hi - lo)  # rising from 0 to 1 either way
    x = np.arange(centre - 16, centre + 16, dtype=float) + 0.5 - centre  # distance from the edge

    def cross(level: float) -> float:
        k = int(np.argmax(t >= level))
        if k == 0:
            return float(x[0])
        return float(x[k - 1] + (level - t[k - 1]) / (t[k] - t[k - 1]) * (x[k] - x[k - 1]))
    return cross(0.9) - cross(0.1)


def _case(args, name: str, out: Path) -> dict:
    """Render and simulate one case; the edge measures as a dict (module docstring)."""
    from acceptance_simulate import plane_toml, scene_header
    from lensrt import load_lens
    from lensrt.cli import main as cli
    from lensrt.io.exr import read_exr
    from lensrt.io.png import write_png
    from lensrt.simulate.inputs import read_image_linear
    from lensrt.simulate.optics import make_camera, pinhole_focal_mm
    from lensrt.simulate.pipeline import SimulateOptions, simulate
    cols, rows = (int(v) for v in args.pixels.split("x"))
    near_v, far_v = (DARK, BRIGHT) if name == "sharp-front" else (BRIGHT, DARK)
    focus_m = args.near_m if name == "sharp-front" else args.far_m
    lens = load_lens("dgauss_50mm_f2")
    cam = make_camera(lens, (rows, cols), args.sensor, focus_m, None, args.device)
    f_pin = pinhole_focal_mm(cam)
    out.mkdir(parents=True, exist_ok=True)
    planes = []
    for label, val, d_m in (("near", near_v, args.near_m), ("far", far_v, args.far_m)):
        img_path = out / f"{label}.png"
        write_png(img_path, np.full((8, 8, 3), val), 8)
        scale = (d_m * 1000.0 + cam.z_ep_mm) / f_pin  # plane mm per sensor mm
        w_mm, h_mm = cols * cam.pitch_mm * scale, rows * cam.pitch_mm * scale
        # twice the frame: the lens sees beyond the pinhole's frame (distortion, the aperture's reach)
        planes.append((img_path, (w_mm / 1000.0 * (1.0 if label == "near" else 2.0), 2.0 * h_mm / 1000.0), d_m))
    (n_img, n_size, n_d), (f_img, f_size, f_d) = planes
    # the near plane's right edge on the axis (x = 0), the far one centred
    (out / "scene.toml").write_text(
        scene_header(cam.focus.extension_mm, args.sensor, (cols, rows), args.spp, None, "simulate_occlusion")
        + plane_toml("near", n_img, (-0.5 * n_size[0], 0.0, -n_d), n_size)
        + plane_toml("far", f_img, (0.0, 0.0, -f_d), f_size))
    t0 = time.perf_counter()
    assert cli(["render", str(out / "scene.toml"), "-o", str(out / "render"), "--device", args.device]) == 0
    t_render = time.perf_counter() - t0
    ch, _ = read_exr(out / "render.exr")
    ren = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float64)
    y_se = np.asarray(ch["Y_stderr"], dtype=np.float64)
    lin = {k: float(read_image_linear(out / f"{k}.png")[0, 0, 0]) for k in ("near", "far")}
    img = np.empty((rows, cols, 3), np.float32)
    depth = np.empty((rows, cols))
    img[:, :cols // 2], img[:, cols // 2:] = lin["near"], lin["far"]
    depth[:, :cols // 2], depth[:, cols // 2:] = args.near_m, args.far_m
    gr, gc = (int(v) for v in args.grid.split("x"))
    t0 = time.perf_counter()
    sim = simulate(img, lens, depth, SimulateOptions(sensor=args.sensor, focus_m=focus_m, bands=args.bands,
                                                     layers=2, grid=(gr, gc), rays=args.rays, device=args.device,
                                                     use_cache=False))
    t_sim = time.perf_counter() - t0
    lum = np.array([0.2126, 0.7152, 0.0722])
    ys = (sim.rgb.astype(np.float64) * sim.reference_gain_sr * 1000.0 / math.pi) @ lum
    yr = ren @ lum
    band = slice(rows // 4, rows - rows // 4)
    p_sim, p_ren = ys[band].mean(axis=0), yr[band].mean(axis=0)
    p_noise = np.sqrt((y_se[band] ** 2).mean(axis=0) / (band.stop - band.start))
    centre = cols // 2
    step = abs(float(p_ren[centre + 16:centre + 20].mean() - p_ren[centre - 20:centre - 16].mean()))
    d = (p_sim - p_ren) / step
    # the sharp side: the in-focus plane's side beyond 2 pixels from the edge (its PSF's reach)
    sharp = np.arange(cols) < centre - 2 if name == "sharp-front" else np.arange(cols) >= centre + 2
    np.savez(out / "profiles.npz", sim=p_sim, render=p_ren, noise=p_noise)
    return {"case": name, "focus_m": focus_m, "near_m": args.near_m, "far_m": args.far_m,
            "near_value": near_v, "far_value": far_v, "render_seconds": t_render, "simulate_seconds": t_sim,
            "halo_width_10_90_px": {"simulate": width_10_90(p_sim, centre), "render": width_10_90(p_ren, centre)},
            "leak_max": float(np.abs(d).max()), "leak_max_at_px_from_edge": float(np.argmax(np.abs(d)) + 0.5 - centre),
            "leak_sharp_side": float(np.abs(d[sharp]).max()),
            "render_noise_of_profile_max": float((p_noise / step).max()),
            "mean_ratio_far_side": float(p_sim[-5:].mean() / p_ren[-5:].mean()),
            "mean_ratio_near_side": float(p_sim[:5].mean() / p_ren[:5].mean()),
            "profile_diff": [round(float(v), 4) for v in d]}


def run(args: argparse.Namespace) -> list[dict]:
    cases = ("sharp-front", "blurred-front") if args.case == "both" else (args.case,)
    return [_case(args, c, Path(args.out) / c) for c in cases]


def main() -> None:
    print(json.dumps(run(parser().parse_args()), indent=1))


if __name__ == "__main__":
    main()
