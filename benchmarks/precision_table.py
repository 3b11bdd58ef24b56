"""float32 against float64: the largest differences of real rays on every library lens and stiff case.

Usage: ``python benchmarks/precision_table.py [--rays 4000] [--device cpu]``

For each lens: random rays over six field points (axis, 0.5, full field, and three
skew fields) and the pupil [-1.1, 1.1]^2, wavelengths across the lens's range, aimed
at the real stop; both precisions on the same rays. Reports, over the rays that
reach the image in both, the largest |float32 - float64| of the image intercept and
of the optical path length (mm) and of the direction cosines, for rays that meet no surface
beyond 80 deg incidence; then how many OK rays were grazing (steeper than that somewhere),
the largest image difference including them, and how many rays changed status (rays
within a few ulp of an aperture edge). The stiff cases (tests/trace_cases.py):
the pbrt fisheye at its full 155.9 deg field, the CODE V double Gauss opened to f/1 and
with its plane surfaces bent to |R| = 1e7 mm.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "oracles"))

from lensrt.io.table import format_table  # noqa: E402
from lensrt.trace import make_rays, trace  # noqa: E402
from trace_cases import all_cases  # noqa: E402

FIELDS = np.array([[0.0, 0.0], [0.0, 0.5], [0.0, -1.0], [0.3, 0.9], [-0.7, 0.7], [1.0, 0.0]])


def measure(lens, n: int, device: str, seed: int = 1) -> list:
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(FIELDS), n)
    px, py = rng.uniform(-1.1, 1.1, n), rng.uniform(-1.1, 1.1, n)
    wl = rng.uniform(min(lens.wavelengths.nm), max(lens.wavelengths.nm), n)
    rays = make_rays(lens, FIELDS[k, 0], FIELDS[k, 1], px, py, wl, aim="real", device=device)
    r64 = trace(lens, rays, "float64", device)
    r32 = trace(lens, rays, "float32", device)
    both = (r64.status == 0) & (r32.status == 0)
    ok = both & ~r64.grazing

    def worst(a: np.ndarray, b: np.ndarray, sel: np.ndarray) -> float:
        return float(np.max(np.abs(a[sel] - b[sel]))) if sel.any() else float("nan")

    return [int(ok.sum()), worst(r32.position_mm, r64.position_mm, ok), worst(r32.opl_mm, r64.opl_mm, ok),
            worst(r32.direction, r64.direction, ok), int((both & r64.grazing).sum()),
            worst(r32.position_mm, r64.position_mm, both), int((r64.status != r32.status).sum())]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=4000)
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args(argv)
    rows = []
    for name, lens in all_cases().items():
        rows.append([name] + measure(lens, args.rays, args.device))
    print(format_table([[r[0], r[1], f"{r[2]:.2e}", f"{r[3]:.2e}", f"{r[4]:.2e}", r[5], f"{r[6]:.2e}", r[7]]
                        for r in rows],
                       ["lens", "rays OK", "max |d image| mm", "max |d OPL| mm", "max |d LMN|",
                        "grazing rays", "incl. grazing mm", "status changed"],
                       title=f"float32 - float64, {args.rays} random rays per lens (real aiming)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
