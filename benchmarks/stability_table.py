"""float32 against float64 per library lens and per stiff case: the table in docs/validation/stability.md.

Usage: ``python benchmarks/stability_table.py [--rays 4000] [--device cpu] [--random 40] [--markdown]``

For each case the same rays go through both precisions (store kernel). Over the rays that reach
the image in both, the image-plane difference |(x, y)_32 - (x, y)_64| (mm) is summarised as its
maximum and 99th percentile over the rays *not* flagged grazing (an angle of incidence or
refraction beyond 80 deg somewhere), then the maximum including the grazing rays, the
fraction of OK rays flagged grazing, and how many rays changed status between the precisions.
"max / bound" is the largest ratio, over the non-grazing rays, of the difference to the general
per-ray bound 2e-4 mm + 2e-6 L / (N' c) (``tests/stability_cases.f32_ray_bound_mm``: L the optical
path, N' the final z direction cosine, c the smallest cosine of incidence or refraction along the
ray) that ``tests/test_stability_random.py`` asserts.

Cases:

* every library lens: random rays over six field points (axis, 0.5, full, three skew) and the
  pupil [-1.1, 1.1]^2, wavelengths across the lens's range, aimed at the real stop, clipped
  (what ``benchmarks/precision_table.py`` traces, with percentiles added);
* the fisheye's chief rays from 0 to 110 deg (real aiming; unclipped, where the pbrt table's
  front element would stop them beyond ~75 deg) and a pupil fan at 85 deg;
* the 50 mm f/1.4, 28 mm f/1.4 and Petzval f/1.4 opened to f/0.95 (apertures recomputed);
* the double Gauss with an object 1e9 mm away and at 1:1;
* single surfaces: |R| = 1e4 and 1e9 mm, a nearly concentric meniscus, a hemisphere
  (sd = |R|) with TIR beyond h = R/n;
* random prescriptions (``tests/stability_cases.random_lens_numpy``, seed 1): the worst of N lenses.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "oracles"))

from lensrt.io.table import format_table  # noqa: E402
from lensrt.prescription.materials import ConstantIndex  # noqa: E402
from lensrt.prescription.model import Surface  # noqa: E402
from lensrt.trace import RayBatch, make_rays, trace  # noqa: E402
from stability_cases import (collimated, f32_ray_bound_mm, library, opened_lens, random_lens_numpy,  # noqa: E402
                             random_rays, system)

FIELDS = np.array([[0.0, 0.0], [0.0, 0.5], [0.0, -1.0], [0.3, 0.9], [-0.7, 0.7], [1.0, 0.0]])
LIBRARY_NAMES = sorted(p.stem for p in (ROOT / "lens_prescriptions").glob("*.toml"))


def library_rays(lens, n: int, device: str, seed: int = 1, aim: str = "real") -> RayBatch:
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(FIELDS), n)
    px, py = rng.uniform(-1.1, 1.1, n), rng.uniform(-1.1, 1.1, n)
    wl = rng.uniform(min(lens.wavelengths.nm), max(lens.wavelengths.nm), n)
    return make_rays(lens, FIELDS[k, 0], FIELDS[k, 1], px, py, wl, aim=aim, device=device)


def compare(lens, rays: RayBatch, device: str, clip: bool = True) -> dict:
    """The summary of one case (see the module docstring)."""
    r64 = trace(lens, rays, "float64", device, clip=clip)
    r32 = trace(lens, rays, "float32", device, clip=clip)
    both = r64.ok & r32.ok
    steady = both & ~r64.grazing
    d = np.hypot(*(r32.position_mm[:, :2] - r64.position_mm[:, :2]).T)

    def stat(sel: np.ndarray, fn) -> float:
        return float(fn(d[sel])) if sel.any() else float("nan")

    ratio = d / f32_ray_bound_mm(r64.opl_mm, r64.direction[:, 2], r64.min_cos_incidence)
    return {"rays": len(rays), "ok": int(both.sum()), "max": stat(steady, np.max),
            "bound": float(np.max(ratio[steady])) if steady.any() else float("nan"),
            "p99": stat(steady, lambda v: np.percentile(v, 99.0)), "max_all": stat(both, np.max),
            "grazing": float((both & r64.grazing).sum() / max(both.sum(), 1)),
            "changed": int((r64.status != r32.status).sum())}


def cases(n: int, device: str, n_random: int):
    """(name, lens, rays, clip) for every case."""
    for name in LIBRARY_NAMES:
        lens = library(name)
        yield f"library: {name}", lens, library_rays(lens, n, device), True
    fish = library("fisheye_10mm_f4")
    full = math.degrees(fish.fields.max_radial)
    angles = np.linspace(0.0, 110.0, 221)
    yield "fisheye chief rays 0-110 deg (unclipped)", fish, make_rays(fish, 0.0, angles / full, 0.0, 0.0, aim="real",
                                                                      device=device), False
    py = np.linspace(-1.0, 1.0, 201)
    yield "fisheye pupil fan at 85 deg (unclipped)", fish, make_rays(fish, 0.0, 85.0 / full, 0.0, py, aim="real",
                                                                     device=device), False
    for name in ("nikkor_50mm_f1.4", "nikkor_28mm_f1.4_asph", "petzval_51mm_f1.4"):
        lens = opened_lens(name, 0.95)
        yield f"{name} opened to f/0.95", lens, library_rays(lens, n, device), True
    dg = library("dgauss_50mm_f2")
    yield "dgauss_50mm_f2, object at 1e9 mm", dg.replace(object_distance_mm=1e9), \
        library_rays(dg.replace(object_distance_mm=1e9), n, device), True
    from lensrt.paraxial import first_order
    fo = first_order(dg)
    macro = dg.replace(object_distance_mm=-fo.front_focal_z_mm + fo.efl_mm)
    yield "dgauss_50mm_f2 at 1:1", macro, library_rays(macro, n, device), True
    glass = ConstantIndex(1.5)
    rng = np.random.default_rng(2)
    for radius in (1e4, 1e9):
        lens = system(Surface(curvature_per_mm=1.0 / radius, thickness_mm=5.0, material=glass, is_stop=True,
                              semi_diameter_mm=25.0), Surface(thickness_mm=50.0, semi_diameter_mm=30.0))
        o, d = collimated(rng.uniform(-20.0, 20.0, n), -1.0, math.radians(10.0))
        yield f"plane-parallel window, front |R| = {radius:g} mm", lens, RayBatch(o, d, 587.5618), True
    men = system(Surface(curvature_per_mm=1 / 20.0, thickness_mm=3.0, material=ConstantIndex(1.6), is_stop=True,
                         semi_diameter_mm=15.0),
                 Surface(curvature_per_mm=1 / (17.0 + 1e-6), thickness_mm=40.0, semi_diameter_mm=13.0))
    a = np.radians(rng.uniform(-30.0, 30.0, n))
    o = np.column_stack([np.zeros(n), rng.uniform(-8.0, 8.0, n), np.full(n, -5.0)])
    yield "meniscus concentric to 1e-6 mm", men, RayBatch(o, np.column_stack([np.zeros(n), np.sin(a), np.cos(a)]),
                                                         587.5618), True
    hemi = system(Surface(thickness_mm=10.0, material=glass, is_stop=True, semi_diameter_mm=10.0),
                  Surface(curvature_per_mm=-0.1, thickness_mm=20.0, semi_diameter_mm=10.0))
    o, d = collimated(np.sqrt(rng.uniform(0.0, 100.0, n)))
    yield "hemisphere, sd = |R| (TIR beyond R/n)", hemi, RayBatch(o, d, 587.5618), True
    rng = np.random.default_rng(1)
    for k in range(n_random):
        lens = random_lens_numpy(rng)
        if lens is not None:
            yield f"random lens {k}", lens, random_rays(lens, n // 2, n // 8, seed=k), True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=4000)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--random", type=int, default=40, help="random lenses (the worst one is shown)")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table (for docs/validation/stability.md)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows, random_rows = [], []
    for name, lens, rays, clip in cases(args.rays, args.device, args.random):
        r = compare(lens, rays, args.device, clip)
        (random_rows if name.startswith("random") else rows).append((name, r))
    if random_rows:
        worst = max(random_rows, key=lambda nr: nr[1]["max"] if math.isfinite(nr[1]["max"]) else -1.0)
        n_ok = sum(r["ok"] for _, r in random_rows)
        agg = dict(worst[1])
        agg.update(ok=n_ok, bound=max(r["bound"] for _, r in random_rows if math.isfinite(r["bound"])), grazing=sum(r["grazing"] * r["ok"] for _, r in random_rows) / max(n_ok, 1),
                   changed=sum(r["changed"] for _, r in random_rows),
                   max_all=max(r["max_all"] for _, r in random_rows if math.isfinite(r["max_all"])))
        rows.append((f"{len(random_rows)} random lenses (worst: {worst[0]})", agg))
    head = ["case", "rays OK", "max |d| mm", "p99 |d| mm", "max / bound", "max incl. grazing", "grazing %",
            "status changed"]

    def fmt(v: float) -> str:
        return "-" if not math.isfinite(v) else f"{v:.2e}"

    table = [[n, r["ok"], fmt(r["max"]), fmt(r["p99"]), f"{r['bound']:.2f}", fmt(r["max_all"]),
              f"{100.0 * r['grazing']:.2f}", r["changed"]] for n, r in rows]
    if args.markdown:
        def cell(v: object) -> str:
            return str(v).replace("|", "\\|")

        print("| " + " | ".join(cell(h) for h in head) + " |")
        print("|" + "---|" * len(head))
        for row in table:
            print("| " + " | ".join(cell(v) for v in row) + " |")
    else:
        print(format_table(table, head, title=f"float32 - float64 on the image plane ({args.rays} rays per case, "
                                              f"{args.device})"))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
