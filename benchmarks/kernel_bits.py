"""Kernel outputs to a file, and two such files compared bit for bit (a refactoring guard, not a test).

Usage (from the repository root; run it on the commit before and after a change of kernel code)::

    python benchmarks/kernel_bits.py record before.npz --device cuda:0
    git checkout <other commit>
    python benchmarks/kernel_bits.py record after.npz --device cuda:0
    python benchmarks/kernel_bits.py compare before.npz after.npz

It records the generic store kernel (three lenses: an asphere, a 5-blade rounded iris with an
obstruction, a wide-aperture asphere lens; both precisions; once with per-surface records),
the specialised store kernel, the generic and specialised stream kernels (the four samplers,
discrete and tabulated spectra, channel tables, batch histograms), the samplers alone and a
small render. ``compare`` lists every array whose bits differ. Both commits must run on the
same device: CPU and CUDA results differ in the last bits.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "oracles"), str(ROOT / "tests")]

PARTS = ("samp", "store", "stream", "spec", "render")


def _rays(n: int, seed: int):
    from lensrt.trace.api import RayBatch
    rng = np.random.default_rng(seed)
    o = np.c_[rng.normal(0, 8, (n, 2)), np.full(n, -20.0)]
    d = np.c_[rng.normal(0, 0.15, (n, 2)), np.ones(n)]
    return RayBatch(o, d, rng.uniform(400, 800, n))


def _lenses() -> list:
    from lensrt.prescription.model import Iris
    from trace_cases import asphere_lens, library_lens
    iris = Iris(blades=5, rotation_rad=0.3, roundness=0.4, obstruction_ratio=0.2)
    return [asphere_lens(), library_lens("dgauss_50mm_f2").replace(iris=iris), library_lens("nikkor_28mm_f1.4_asph")]


def _samplers(out: dict, device: str) -> None:
    try:
        from lensrt.trace.kernels.generic import sample_unit_square
    except ImportError:  # before the kernels package
        from lensrt.trace.sampling import sample_unit_square
    from lensrt.trace.sampling import SAMPLERS
    for s in SAMPLERS:
        for p in ("float32", "float64"):
            out[f"samp_{s}_{p}"] = sample_unit_square(s, 300, seed=5, precision=p, device=device)


def _store(out: dict, key: str, lens, p: str, device: str, kernel: str, seed: int, record: bool = False) -> None:
    from lensrt.trace.api import trace
    res = trace(lens, _rays(3000, seed), p, device, kernel=kernel, record=record)
    out[key] = np.c_[res.position_mm, res.direction, res.opl_mm, res.min_cos_incidence, res.status, res.surface]
    if record:
        out[key + "_rec"] = res.records


def _stream_configs(kernel: str, li: int) -> list[dict]:
    from lensrt.trace.sampling import spectrum_continuous
    from lensrt.trace.stream import Channels
    cfgs = [dict(sampler="sobol", spectrum=spectrum_continuous([420.0, 680.0], [1.0])),
            dict(sampler="stratified"),
            dict(sampler="r2", channels=Channels(np.array([[0.2, 1.0, 0.5], [1.0, 0.3, 0.1]]), 400.0, 150.0),
                 spectrum=spectrum_continuous([420.0, 560.0, 680.0], [1.0, 2.0])),
            dict(sampler="random", batch_histograms=True)]
    if kernel == "specialised":
        return cfgs[li - 1::2] if li else cfgs[:1]
    return cfgs


def _streams(out: dict, lens, li: int, p: str, device: str, kernel: str) -> None:
    from lensrt.trace.stream import Grid, stream, stream_source
    src = stream_source(lens, 0.0, 0.8, device=device)
    for ci, cfg in enumerate(_stream_configs(kernel, li)):
        res = stream(lens, [src], Grid(24, 20, 0.01), 1 << 13, seed=3, batches=4, precision=p, device=device,
                     kernel=kernel, **cfg)
        key = f"stream_{kernel}_{p}_{li}_{ci}"
        out[key + "_h"], out[key + "_s"], out[key + "_c"] = res.histogram, res.batch_stats, res.batch_counts
        if res.batch_histograms is not None:
            out[key + "_bh"] = res.batch_histograms


def _render(out: dict, device: str) -> None:
    from lensrt.render.integrator import RenderOptions, render
    from lensrt.render.scene import load_scene
    r = render(load_scene("default"), options=RenderOptions(width=32, samples_per_pixel=4, spp_per_pass=2,
                                                             device=device))
    out["render_irr"], out["render_xyz"] = r.irradiance, r.xyz


def record(path: str, device: str, parts: set[str]) -> None:
    out: dict = {}
    if "samp" in parts:
        _samplers(out, device)
    for p in ("float64", "float32"):
        for li, lens in enumerate(_lenses()):
            if "store" in parts:
                _store(out, f"store_{p}_{li}", lens, p, device, "generic", li, record=li == 0)
            if "spec" in parts and li > 0:
                _store(out, f"sstore_{p}_{li}", lens, p, device, "specialised", li)
            if "stream" in parts:
                _streams(out, lens, li, p, device, "generic")
            if "spec" in parts and not (li == 0 and p == "float32"):
                _streams(out, lens, li, p, device, "specialised")
    if "render" in parts:
        _render(out, device)
    np.savez(path, **out)
    print(f"{path}: {len(out)} arrays")


def compare(a_path: str, b_path: str) -> int:
    a, b = np.load(a_path), np.load(b_path)
    bad = [k for k in a.files if k not in b.files or a[k].shape != b[k].shape or a[k].tobytes() != b[k].tobytes()]
    for k in bad:
        print("differs:", k)
    print(f"{len(a.files)} arrays, {len(bad)} differ" + ("" if bad else ": bit-identical"))
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("path")
    r.add_argument("--device", default="cpu")
    r.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated subset of {','.join(PARTS)}")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = ap.parse_args()
    if args.cmd == "record":
        record(args.path, args.device, set(args.parts.split(",")))
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    raise SystemExit(main())
