#!/usr/bin/env python
"""Render speed: the trimesh still life through the 50 mm double Gauss, and what the render plan saves.

Examples
--------
The issue's target (one H100: 1920 x 1080, 64 spectral samples per pixel, under 1 s per image)::

    python benchmarks/bench_render.py --device cuda

A small image on the CPU (what the table in docs/benchmarks.md shows)::

    python benchmarks/bench_render.py --device cpu

Each case runs once to warm up (kernel compilation, BVH build, first allocations; its time is shown
as ``first run``) and then ``--repeat`` times; the table shows the best. ``seconds`` counts the
passes only -- tracing, accumulation and the per-pass statistics -- not the set-up (focus, exit-pupil
table, scene packing and BVH build; ``set-up s``). ``paths/s`` counts every path started, vignetted
ones included; ``paths/CPU s`` divides by the CPU time of all this process's threads (on a shared
machine it measures the code, ``paths/s`` the code and the neighbours). ``rel. err`` is the render's own error measure: the RMS over lit pixels of the
relative standard error of Y (batch means over passes).

The plan rows render variants of the same scene at the same size and samples: without the meshes
(no BVH), one wavelength instead of 40 bands, without the lights (no shadow rays), and a
point-source scene (night_street) splatted from the lights against camera paths.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def _case(name: str, scene, opts, repeat: int) -> dict:
    from lensrt.render.integrator import render
    t0 = time.perf_counter()
    first = render(scene, options=opts)
    first_wall = time.perf_counter() - t0
    best = None
    for _ in range(repeat):
        r = render(scene, options=opts)
        if best is None or r.seconds < best.seconds:
            best = r
    rel = best.history[-1].get("rel_error") if best.history else None
    img = best.regions.get("image")
    setup = best.setup_seconds.get("total_before_passes", 0.0)
    rows, cols = best.shape
    kernel = best.plan.variant.name if best.mode == best.plan.mode else best.mode.replace("_", " ")
    return {"case": name, "kernel": kernel, "mode": best.mode, "pixels": f"{cols} x {rows}",
            "spp": best.samples_per_pixel, "passes": best.passes, "bands": int(best.irradiance.shape[2]),
            "seconds": best.seconds, "paths_per_s": best.samples_per_second, "cpu_seconds": best.cpu_seconds,
            "paths_per_cpu_s": best.samples / best.cpu_seconds if best.cpu_seconds > 0 else float("nan"),
            "setup_s": setup, "first_run_wall_s": first_wall, "rel_error": rel,
            "image_Y_lux": None if img is None else [img.value, img.stderr], "device": best.device,
            "setup_detail": best.setup_seconds, "kernel_s": getattr(best, "kernel_seconds", None)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default=None, help="cpu or cuda[:N] (default: CUDA when present)")
    p.add_argument("--width", type=int, default=None, help="image width (default 1920 on CUDA, 240 on the CPU)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel (default 64 on CUDA, 16 on the CPU)")
    p.add_argument("--spp-per-pass", type=int, default=None, help="paths per pixel per pass (default spp / 8)")
    p.add_argument("--repeat", type=int, default=2, help="timed runs per case after the warm-up (best shown)")
    p.add_argument("--no-plan-rows", action="store_true", help="only the main case")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    import warp
    warp.config.log_level = warp.LOG_WARNING
    from lensrt.device import describe_device, resolve_device
    from lensrt.io.table import format_table
    from lensrt.render.setup import RenderOptions
    from lensrt.render.scene.load import load_scene
    from lensrt.render.scene.model import SpectralSettings

    dev = resolve_device(args.device)
    gpu = dev.startswith("cuda")
    width = args.width or (1920 if gpu else 240)
    spp = args.spp or (64 if gpu else 16)
    opts = RenderOptions(samples_per_pixel=spp, spp_per_pass=args.spp_per_pass, width=width, device=dev, seed=1)
    base = load_scene("still_life_mesh")
    # 16:9 at the asked width: the scene's sensor is 36 x 20.25 mm
    cases = [("still life: mesh, spectral, shadow rays (full plan)", base, opts)]
    if not args.no_plan_rows:
        cases += [
            ("  without the meshes (no BVH)", dataclasses.replace(base, meshes=()), opts),
            ("  one wavelength (550 nm) instead of 40 bands",
             dataclasses.replace(base, spectral=SpectralSettings("monochromatic", base.grid, 550.0, "auto")), opts),
            ("  without lights (uniform illumination only: no shadow rays)",
             dataclasses.replace(base, point_lights=(), sphere_lights=(),
                                 planes=tuple(pl for pl in base.planes if not pl.emissive)), opts),
        ]
        night = load_scene("night_street")
        nw = max(96, width // 4)
        nopts = dataclasses.replace(opts, width=nw)
        cases += [("night street (lights only): light splat", night, nopts),
                  ("night street: camera paths instead", night,
                   dataclasses.replace(nopts, window=(0, round(nw * 24 / 36), 0, nw)))]
    rows = []
    for name, scene, o in cases:
        sys.stderr.write(f"bench_render: {name.strip()} ...\n")
        rows.append(_case(name, scene, o, args.repeat))
    import os
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    head = (f"bench_render on {describe_device(dev)} ({os.cpu_count()} CPU cores, load average {load:.1f} at the end); "
            f"still_life_mesh {width} px wide, {spp} samples/pixel")
    if args.json:
        print(json.dumps({"title": head, "rows": rows}, indent=1, default=str))
        return 0
    print(head)
    table = [[r["case"], r["kernel"], r["pixels"], r["spp"], r["bands"], f"{r['seconds']:.3g}",
              f"{r['paths_per_s']:.3g}", f"{r['paths_per_cpu_s']:.3g}", f"{r['setup_s']:.3g}", f"{r['first_run_wall_s']:.3g}",
              "-" if r["rel_error"] is None else f"{r['rel_error']:.3g}"] for r in rows]
    print(format_table(table, ["case", "kernel", "pixels", "spp", "bands", "seconds", "paths/s", "paths/CPU s", "set-up s",
                               "first run s", "rel. err"]))
    splat = [r for r in rows if r["mode"] == "light_splat"]
    cam = [r for r in rows if r["case"].strip().startswith("night street: camera")]
    if splat and cam and splat[0]["rel_error"] and cam[0]["rel_error"]:
        a, b = splat[0], cam[0]
        # Monte Carlo error falls as 1/sqrt(time): the time each path needs for the other's error
        t_cam = b["seconds"] * (b["rel_error"] / a["rel_error"]) ** 2
        t_splat = a["seconds"] * (a["rel_error"] / b["rel_error"]) ** 2
        print(f"night street, equal error: light splat {a['seconds']:.3g} s at rel. err {a['rel_error']:.3g} "
              f"(GPU/kernel {a['kernel_s'] or float('nan'):.3g} s); camera paths need ~{t_cam:.3g} s for that error "
              f"({b['seconds']:.3g} s at {b['rel_error']:.3g}); at the camera paths' error the splat needs "
              f"~{t_splat:.3g} s: {'light splat' if t_cam > a['seconds'] else 'camera paths'} is faster by "
              f"{max(t_cam / a['seconds'], a['seconds'] / t_cam):.3g}x")
    main_row = rows[0]
    print(f"per image: {main_row['seconds']:.3g} s for {main_row['pixels']} px x {main_row['spp']} spp "
          f"({main_row['paths_per_s']:.3g} paths/s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
