"""Where the stream kernel's time goes: the pieces one at a time (a GPU micro-benchmark).

Usage (from the repository root)::

    python benchmarks/bench_kernel_parts.py --device cuda --rays 2**30 [--check]
    python benchmarks/bench_kernel_parts.py --aot 90     # compile every module it needs for sm_90
                                                         # into Warp's kernel cache (no GPU needed)

On the 50 mm double Gauss with a 7-blade iris (as ``bench_trace.py``), each row
changes one thing against a reference run (specialised kernel, float32, full
field, 400-700 nm, Sobol', histogram): the generic kernel; the precision; the
field; three lines (index table) instead of the dispersion formula; other
samplers; no histogram; a circular stop; no apertures at all ("bare": no clip,
table indices, R2 points, no histogram -- the trace loop alone); threads per
launch; a register cap. ``--check`` first compares the kernels on the device
(specialised vs generic float64 store to 1e-10 mm, float32 vs float64, Sobol'
points against the CPU's, bit-identical repeats and launch splits).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lensrt.device import describe_device, resolve_device, warp  # noqa: E402
from lensrt.io.table import format_table  # noqa: E402
from lensrt.prescription.model import Iris  # noqa: E402
from lensrt.trace import specialised  # noqa: E402
from lensrt.trace.kernels import get_kernels, module_names  # noqa: E402
from lensrt.trace.pack import pack_lens  # noqa: E402
from lensrt.trace.kernels.generic import sample_unit_square  # noqa: E402
from lensrt.trace.sampling import SAMPLERS, spectrum_continuous  # noqa: E402
from lensrt.trace.specialised import StreamOptions, Tuning, stream_kernel  # noqa: E402
from lensrt.trace.stream import GPU_THREADS, Grid, stream, stream_source  # noqa: E402
from lensrt.trace.variants import shape_and_constants  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_trace import bench_lens  # noqa: E402

REF = dict(precision="float32", hy=1.0, spectral=True, kernel="specialised", sampler="sobol", histogram=True,
           iris="7", clip=True, threads=None, tuning=None)


def cases() -> list[tuple[str, dict]]:
    c = [("reference (spec f32 full field 400-700)", {})]
    c += [("generic kernel", dict(kernel="generic")),
          ("on axis", dict(hy=0.0)),
          ("3 lines (index table)", dict(spectral=False)),
          ("sampler random", dict(sampler="random")),
          ("sampler r2", dict(sampler="r2")),
          ("sampler stratified", dict(sampler="stratified")),
          ("no histogram", dict(histogram=False)),
          ("circular stop", dict(iris="0")),
          ("bare: no clip, table, r2, no hist", dict(clip=False, spectral=False, sampler="r2", histogram=False)),
          ("threads 2^17", dict(threads=1 << 17)),
          ("threads 2^19", dict(threads=1 << 19)),
          ("threads 2^20", dict(threads=1 << 20)),
          ("max registers 80", dict(tuning=Tuning(80))),
          ("max registers 64", dict(tuning=Tuning(64))),
          ("float64", dict(precision="float64")),
          ("float64 generic", dict(precision="float64", kernel="generic")),
          ("float64 on axis", dict(precision="float64", hy=0.0)),
          ("float64 3 lines", dict(precision="float64", spectral=False)),
          ("float64 max registers 128", dict(precision="float64", tuning=Tuning(128))),
          ("float64 max registers 96", dict(precision="float64", tuning=Tuning(96))),
          ("float64 threads 2^20", dict(precision="float64", threads=1 << 20)),
          ("float64 bare", dict(precision="float64", clip=False, spectral=False, sampler="r2", histogram=False))]
    return [(label, {**REF, **kw}) for label, kw in c]


def lens_for(cfg: dict):
    lens = bench_lens()
    if cfg["iris"] == "0":
        lens = lens.replace(iris=Iris(blades=0))
    return lens


def run_case(cfg: dict, rays: int, device: str, sources: dict) -> tuple[float, float, dict]:
    lens = lens_for(cfg)
    key = (cfg["iris"], cfg["hy"])
    if key not in sources:
        sources[key] = stream_source(lens, 0.0, cfg["hy"], device=device)
    spec = spectrum_continuous([400.0, 700.0], [1.0]) if cfg["spectral"] else None
    prec = cfg["precision"]
    saved = specialised.GPU_TUNING[prec]
    if cfg["tuning"] is not None:
        specialised.GPU_TUNING[prec] = cfg["tuning"]
    try:
        T = None if cfg["threads"] is None else max(1, cfg["threads"] // 32)
        res = stream(lens, [sources[key]], Grid(256, 256, 0.002), int(rays), spectrum=spec, sampler=cfg["sampler"],
                     seed=1, precision=prec, device=device, kernel=cfg["kernel"], histogram=cfg["histogram"],
                     clip=cfg["clip"], threads_per_batch=T)
    finally:
        specialised.GPU_TUNING[prec] = saved
    return res.seconds, res.rays_total / res.seconds, res.extra


def modules_for(cfg: dict) -> list[str]:
    """The Warp modules a case loads on a GPU (for ahead-of-time compilation)."""
    prec = cfg["precision"]
    get_kernels(prec)
    get_kernels("float64")
    names = module_names(prec) + module_names("float64")
    if cfg["kernel"] == "specialised":
        lens = lens_for(cfg)
        packed = pack_lens(lens, prec, "cpu")
        shape, _ = shape_and_constants(packed, cfg["clip"])
        tuning = cfg["tuning"] or specialised.GPU_TUNING[prec]
        opts = StreamOptions(SAMPLERS.index(cfg["sampler"]), not cfg["spectral"], False, cfg["histogram"])
        names.append(stream_kernel(prec, shape, opts, tuning).module)
    return names


def aot(arch: int, names: list[str]) -> None:
    wp = warp()
    t0 = time.perf_counter()
    for name in dict.fromkeys(names):
        wp.compile_aot_module(name, arch=arch, use_ptx=False)
    print(f"compiled {len(set(names))} modules for sm_{arch} into {wp.config.kernel_cache_dir} "
          f"in {time.perf_counter() - t0:.1f} s")


def check(device: str) -> list[str]:
    """Device-side checks (see the module docstring); returns lines to print."""
    from lensrt.trace import RayBatch, trace
    out = []
    rng = np.random.default_rng(4)
    lens = bench_lens()
    src = stream_source(lens, 0.0, 0.8, device=device)
    b = src.box
    n = 1 << 16
    pts = b.points(rng.uniform(b.a0, b.a1, n), rng.uniform(b.b0, b.b1, n))
    rays = RayBatch(pts, np.broadcast_to(np.asarray(src.field.direction), pts.shape), rng.uniform(400, 700, n))
    g64 = trace(lens, rays, "float64", device, kernel="generic")
    s64 = trace(lens, rays, "float64", device, kernel="specialised")
    s32 = trace(lens, rays, "float32", device, kernel="specialised")
    ok = g64.ok
    out.append(f"store float64 specialised vs generic: statuses equal {np.array_equal(g64.status, s64.status)}, "
               f"max |dpos| {np.abs(g64.position_mm[ok] - s64.position_mm[ok]).max():.2e} mm")
    ok32 = ok & s32.ok & ~g64.grazing
    out.append(f"store float32 specialised vs float64: max |dpos| "
               f"{np.abs(g64.position_mm[ok32] - s32.position_mm[ok32]).max():.2e} mm")
    ref = Path(__file__).resolve().parent.parent / ".perf_ref"
    for prec in ("float32", "float64"):
        f = ref / f"sobol_{prec}.npy"
        if f.exists():
            u = sample_unit_square("sobol", 4096, seed=7, precision=prec, device=device)
            out.append(f"sobol {prec} on {device} == CPU points: {np.array_equal(u, np.load(f))}")
    spec = spectrum_continuous([400.0, 700.0], [1.0])
    kw = dict(spectrum=spec, seed=3, precision="float32", device=device, kernel="specialised")
    a = stream(lens, [src], Grid(64, 64, 0.004), 1 << 24, **kw)
    b2 = stream(lens, [src], Grid(64, 64, 0.004), 1 << 24, **kw)
    c = stream(lens, [src], Grid(64, 64, 0.004), 1 << 24, rays_per_launch=1 << 21, **kw)
    g = stream(lens, [src], Grid(64, 64, 0.004), 1 << 24, **{**kw, "kernel": "generic"})
    out.append(f"stream repeat bit-identical: {np.array_equal(a.histogram, b2.histogram) and np.array_equal(a.batch_stats, b2.batch_stats)}; "
               f"other launch split: histogram and counts equal {np.array_equal(a.histogram, c.histogram) and np.array_equal(a.batch_counts, c.batch_counts)}")
    out.append(f"stream specialised vs generic: counts equal {np.array_equal(a.batch_counts, g.batch_counts)}, "
               f"histogram sum rel diff {abs(a.histogram.sum() / g.histogram.sum() - 1):.1e}, "
               f"rms radius {a.rms_radius()[0]:.6e} vs {g.rms_radius()[0]:.6e} mm")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--rays", default="2**30", help="rays per case (Python expression)")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--aot", type=int, default=None, help="only compile every module for this CUDA arch")
    ap.add_argument("--only", default=None, help="comma-separated case numbers")
    args = ap.parse_args(argv)
    todo = cases()
    if args.only:
        keep = {int(v) for v in args.only.split(",")}
        todo = [c for i, c in enumerate(todo) if i in keep]
    if args.aot is not None:
        names = [m for _, cfg in todo for m in modules_for(cfg)]
        if args.check or not args.only:  # the store kernels the checks use
            from lensrt.trace.specialised import store_kernel
            for prec in ("float32", "float64"):
                shape, _ = shape_and_constants(pack_lens(bench_lens(), prec, "cpu"), True)
                names.append(store_kernel(prec, shape, specialised.GPU_TUNING[prec]).module)
        aot(args.aot, names)
        return 0
    wp = warp()
    device = resolve_device(args.device)
    rays = int(eval(args.rays, {}))  # noqa: S307 - a command-line number such as 2**30
    print(f"device: {describe_device(device)}; Warp {wp.config.version}; rays per case {rays:.3e}", flush=True)
    if args.check:
        for line in check(device):
            print(line, flush=True)
    rows = []
    sources: dict = {}
    for label, cfg in todo:
        run_case(cfg, 1 << 16, device, sources)  # warm-up: module load, pupil box
        sec, rps, extra = run_case(cfg, rays, device, sources)
        rows.append([label, cfg["precision"], extra["kernel"], extra["threads_per_batch"] * 32, f"{sec:.4f}",
                     f"{rps:.3e}"])
        print(" | ".join(str(v) for v in rows[-1]), flush=True)
    print()
    print(format_table(rows, ["case", "precision", "kernel", "threads", "seconds", "rays/s"],
                       title=f"stream kernel pieces on {describe_device(device)} ({rays:.2e} rays per case)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
