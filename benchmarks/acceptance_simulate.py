"""Acceptance check of ``lensrt simulate`` against lensrt's own path tracer on one textured plane.

The same texture is (a) the image of a [[plane]] (texture = "image") 2 m in front of the lens,
sized so that an ideal pinhole at the paraxial entrance pupil sees each texture pixel as one sensor
pixel, reaching a margin beyond the frame (so that the lens's barrel distortion finds texture there),
lit by 1000 lx of D65 (uniform illumination), rendered by ``lensrt render`` (camera paths
through the real lens), and (b) the frame's crop of it as the input of ``lensrt simulate`` (white = the luminance of a
reflectance-1 Lambertian plane under 1000 lx, 1000/pi cd/m^2). Both use unit focusing with the
same extension, the same sensor, the same Mallett-Yuksel spectra under D65. The script prints the
per-pixel relative difference of Y (RMS over the frame, the corners, and with the render's own
noise taken out in quadrature) and writes both images.

    python benchmarks/acceptance_simulate.py [--pixels 96x72] [--spp 256] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np


def texture(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    """A smooth colourful test image in [0, 1] (sRGB-encoded): low-pass noise, gradients, soft bars."""
    from scipy.ndimage import gaussian_filter
    rng = np.random.default_rng(seed)
    noise = gaussian_filter(rng.random((rows, cols, 3)), (3, 3, 0))
    noise = (noise - noise.min()) / (np.ptp(noise) + 1e-12)
    r, c = np.mgrid[0:rows, 0:cols]
    bars = 0.5 + 0.5 * np.sin(2 * np.pi * c / 16.0)[..., None] * np.array([0.6, 0.2, -0.4])
    img = 0.15 + 0.7 * (0.5 * noise + 0.3 * bars + 0.2 * (r / rows)[..., None])
    return np.clip(img, 0.02, 0.98)


def scene_header(extension_mm: float, sensor: str, pixels: tuple[int, int], spp: int, f_number: float | None,
                 name: str = "simulate_acceptance") -> str:
    """The scene's sections before its planes: the lens focused by ``extension_mm``, sensor, render, light."""
    fn = f"f_number = {f_number}\n" if f_number else ""
    return f"""[scene]
name = "{name}"
units = "m"

[camera]
lens = "dgauss_50mm_f2"
focus_extension_mm = {float(extension_mm)!r}
{fn}exposure_s = 0.01

[sensor]
format = "{sensor}"
pixels = [{pixels[0]}, {pixels[1]}]

[render]
samples_per_pixel = {spp}
seed = 1

[illumination]
spectrum = "D65"
illuminance_lux = 1000
"""


def plane_toml(name: str, image: Path, center_m: tuple[float, float, float], size_m: tuple[float, float]) -> str:
    """One [[plane]] with an image texture."""
    return f"""
[[plane]]
name = "{name}"
center = [{float(center_m[0])!r}, {float(center_m[1])!r}, {float(center_m[2])!r}]
size = [{float(size_m[0])!r}, {float(size_m[1])!r}]
texture = "image"
image = "{image.name}"
"""


def scene_toml(image: Path, size_m: tuple[float, float], depth_m: float, extension_mm: float, sensor: str,
               pixels: tuple[int, int], spp: int, f_number: float | None) -> str:
    return (scene_header(extension_mm, sensor, pixels, spp, f_number)
            + plane_toml("texture", image, (0.0, 0.0, -float(depth_m)), size_m))


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pixels", default="96x72")
    ap.add_argument("--sensor", default="24x18")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--depth-m", type=float, default=2.0)
    ap.add_argument("--focus-m", type=float, default=1.5)
    ap.add_argument("--rays", type=int, default=1 << 16)
    ap.add_argument("--grid", default="7x9")
    ap.add_argument("--bands", type=int, default=6)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="acceptance_out")
    return ap


def run(args: argparse.Namespace) -> dict:
    """Render, simulate and compare (module docstring); the comparison as a dict."""
    from lensrt import load_lens
    from lensrt.cli import main as cli
    from lensrt.io.exr import read_exr
    from lensrt.io.png import write_png
    from lensrt.simulate.optics import make_camera, pinhole_focal_mm
    from lensrt.simulate.pipeline import SimulateOptions, simulate
    cols, rows = (int(v) for v in args.pixels.split("x"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    # the plane reaches m pixels beyond the frame on every side (the real lens's distortion shows some of it);
    # 8-bit, because the render's texture reader (Pillow) reads 16-bit colour PNGs as 8 bits
    m = max(4, cols // 10)
    tex = texture(rows + 2 * m, cols + 2 * m)
    write_png(out / "texture.png", tex, 8)
    lens = load_lens("dgauss_50mm_f2")
    cam = make_camera(lens, (rows, cols), args.sensor, args.focus_m, None, args.device)
    f_pin = pinhole_focal_mm(cam)
    d_mm = args.depth_m * 1000.0
    scale = (d_mm + cam.z_ep_mm) / f_pin  # plane mm per sensor mm
    size_m = ((cols + 2 * m) * cam.pitch_mm * scale / 1000.0, (rows + 2 * m) * cam.pitch_mm * scale / 1000.0)
    (out / "scene.toml").write_text(scene_toml(out / "texture.png", size_m, args.depth_m, cam.focus.extension_mm,
                                               args.sensor, (cols, rows), args.spp, None))
    t0 = time.perf_counter()
    rc = cli(["render", str(out / "scene.toml"), "-o", str(out / "render"), "--device", args.device])
    t_render = time.perf_counter() - t0
    assert rc == 0
    ch, _ = read_exr(out / "render.exr")
    ren = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float64)
    y_se = np.asarray(ch["Y_stderr"], dtype=np.float64)
    from lensrt.simulate.inputs import read_image_linear
    img = np.ascontiguousarray(read_image_linear(out / "texture.png")[m:m + rows, m:m + cols])
    gr, gc = (int(v) for v in args.grid.split("x"))
    t0 = time.perf_counter()
    sim = simulate(img, lens, np.full((rows, cols), args.depth_m), SimulateOptions(
        sensor=args.sensor, focus_m=args.focus_m, bands=args.bands, layers=1, grid=(gr, gc), rays=args.rays,
        device=args.device, use_cache=False))
    t_sim = time.perf_counter() - t0
    white_cd_m2 = 1000.0 / math.pi
    simabs = sim.rgb.astype(np.float64) * sim.reference_gain_sr * white_cd_m2  # lux (Y) scale
    write_png(out / "sim.png", np.clip(simabs / np.percentile(ren, 99.5), 0, 1) ** (1 / 2.2), 8)
    lum = np.array([0.2126, 0.7152, 0.0722])
    ys, yr = simabs @ lum, ren @ lum
    rel = (ys - yr) / yr
    noise = y_se / yr
    corner = np.zeros_like(rel, dtype=bool)
    k = max(2, rows // 8)
    corner[:k, :k] = corner[:k, -k:] = corner[-k:, :k] = corner[-k:, -k:] = True
    res = {"pixels": [cols, rows], "sensor": args.sensor, "spp": args.spp, "depth_m": args.depth_m,
           "focus_m": args.focus_m, "rays_per_psf": args.rays, "grid": [gr, gc], "bands": args.bands,
           "render_seconds": t_render, "simulate_seconds": t_sim,
           "mean_ratio_sim_over_render": float(np.mean(ys) / np.mean(yr)),
           "rel_rms": float(np.sqrt(np.mean(rel ** 2))), "rel_mean": float(np.mean(rel)),
           "render_noise_rel_rms": float(np.sqrt(np.mean(noise ** 2))),
           "rel_rms_beyond_noise": float(math.sqrt(max(np.mean(rel ** 2) - np.mean(noise ** 2), 0.0))),
           "corners_rel_rms": float(np.sqrt(np.mean(rel[corner] ** 2))),
           "corners_noise_rel_rms": float(np.sqrt(np.mean(noise[corner] ** 2))),
           "per_channel_rel_rms": [float(np.sqrt(np.mean(((simabs[..., i] - ren[..., i]) / ren[..., i]) ** 2)))
                                   for i in range(3)]}
    np.save(out / "rel_diff.npy", rel)
    return res


def main() -> None:
    print(json.dumps(run(parser().parse_args()), indent=1))


if __name__ == "__main__":
    main()
