"""Speed of ``lensrt simulate``: a picture with a depth map through the 50 mm f/2 double Gauss.

Runs the simulation twice -- cold (PSF grid and optics traced, then cached) and warm (from the
cache) -- and prints the wall and CPU seconds of each stage and the rate in megapixels per second
of the warm run (what a second picture with the same lens, focus, aperture and depth layers
costs). The issue's targets: a 12 MP image (the default, 4000 x 3000) with 8 depth layers in < 2 s
on one H100 and < 60 s on a 2-core CPU, excluding a cold PSF cache.

    python benchmarks/bench_simulate.py [--pixels 4000x3000] [--layers 8] [--bands 4] [--grid 5x7]
                                        [--device cpu|cuda] [--backend auto|host|warp] [--runs 2]
                                        [--cache-dir DIR] [--max-memory SIZE]

``--device cuda`` runs the blur with Warp tile FFTs on the GPU (and traces the PSFs there); a GPU
that Warp does not see is one error. ``--device cpu`` runs it with NumPy/SciPy (``--backend warp``:
the device kernels on the CPU, slow, for checking).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time

import numpy as np


def scene(rows: int, cols: int, layers: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A textured picture and a depth map of ``layers`` vertical slabs from 0.8 m to 20 m."""
    from scipy.ndimage import gaussian_filter
    rng = np.random.default_rng(seed)
    img = np.clip(gaussian_filter(rng.random((rows, cols, 3)), (1.5, 1.5, 0)) * 1.6 - 0.3, 0, 1).astype(np.float32)
    depth = np.empty((rows, cols))
    edges = np.linspace(0, cols, layers + 1).astype(int)
    for k, d in enumerate(np.geomspace(0.8, 20.0, layers)):
        depth[:, edges[k]:edges[k + 1]] = d
    return img, depth


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pixels", default="4000x3000")
    ap.add_argument("--layers", type=int, default=8)
    ap.add_argument("--bands", type=int, default=4)
    ap.add_argument("--grid", default="5x7")
    ap.add_argument("--rays", type=int, default=1 << 14)
    ap.add_argument("--sensor", default="24x18")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--backend", default="auto", choices=("auto", "host", "warp"))
    ap.add_argument("--runs", type=int, default=2, help="runs: the first is cold, the rest warm")
    ap.add_argument("--cache-dir", default=None, help="keep the PSF/optics cache here (default: a temporary one)")
    ap.add_argument("--max-memory", default=None, help="working-memory budget of the host blur (e.g. 2G): "
                                                       "beyond it, bands of rows")
    args = ap.parse_args()
    from lensrt import load_lens
    from lensrt.core.budget import parse_memory
    from lensrt.simulate.pipeline import SimulateOptions, simulate
    cols, rows = (int(v) for v in args.pixels.split("x"))
    gr, gc = (int(v) for v in args.grid.split("x"))
    img, depth = scene(rows, cols, args.layers)
    lens = load_lens("dgauss_50mm_f2")
    with tempfile.TemporaryDirectory() as tmp:
        cache = args.cache_dir or tmp
        opts = SimulateOptions(sensor=args.sensor, focus_m=2.0, bands=args.bands, layers=args.layers, grid=(gr, gc),
                               rays=args.rays, cache_dir=cache, device=args.device, backend=args.backend,
                               max_memory_bytes=parse_memory(args.max_memory) if args.max_memory else None)
        runs = []
        for k in range(max(args.runs, 2)):
            t0, c0 = time.perf_counter(), time.process_time()
            sim = simulate(img, lens, depth, opts)
            runs.append({"run": "warm" if k or sim.psf_grid.cached else "cold",
                         "wall_s": round(time.perf_counter() - t0, 3),
                         "cpu_s": round(time.process_time() - c0, 3),
                         **{f"{name}_s": round(v, 3) for name, v in sim.seconds.items()}})
            print(json.dumps(runs[-1]), flush=True)
    mp = rows * cols / 1e6
    best = min(runs[1:], key=lambda r: r["wall_s"])
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    out = {"machine": platform.processor() or platform.machine(), "cores": os.cpu_count(), "load_average_1min": load,
           "device": args.device, "where": sim.notes[0], "pixels": [cols, rows],
           "megapixels": mp, "layers": len(sim.layers), "bands": args.bands, "grid": [gr, gc],
           "rays_per_psf": args.rays, "psf_px": [int(p.shape[-1]) for p in sim.psf_grid.psf], "runs": runs,
           "warm_best_wall_s": best["wall_s"], "warm_megapixels_per_s": mp / best["wall_s"],
           "warm_convolution_megapixels_per_s": mp / best["convolution_s"]}
    if args.device.startswith("cuda"):
        import warp as wp
        out["gpu"] = wp.get_device(args.device).name
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
