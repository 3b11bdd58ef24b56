"""Fixed costs of a fresh lensrt process: colour-science's tables, and a specialised kernel's first trace.

Usage (from the repository root)::

    PYTHONPATH=. python benchmarks/bench_startup.py --device cuda
    PYTHONPATH=. python benchmarks/bench_startup.py --device cpu --repeat 5

Each case runs in new Python processes (one warm-up run first, which fills lensrt's colour-table files,
lensrt's specialised-kernel folder and Warp's kernel cache; then ``--repeat`` timed runs, median shown):

- ``import colour`` -- what a process paid for CIE tables before they were kept on disk;
- ``colour tables from disk`` -- :mod:`lensrt.colour` with the CMFs, D65, the sRGB matrices and 8-bit codes;
- ``specialised trace, lensrt folder`` / ``..., Warp's path`` -- the first float32 specialised store trace of
  the built-in lens (1,024 rays) after Warp is initialised and a generic trace has run, with
  ``LENSRT_KERNEL_CACHE`` on (module loaded from :mod:`lensrt.trace.kernel_cache`'s folder, no code
  generation) and off (Warp's content hash: its code generator runs over the module first).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

COLOUR = """
import time
t = time.perf_counter()
import colour
print(time.perf_counter() - t)
"""

TABLES = """
import time
import numpy
t = time.perf_counter()
from lensrt.colour import cie_illuminant, cie_xyz_cmfs, srgb_encode8, srgb_matrices
cie_xyz_cmfs(); cie_illuminant("D65"); srgb_matrices(); srgb_encode8([0.5])
print(time.perf_counter() - t)
"""

TRACE = """
import sys, time
import numpy as np
from lensrt.loading import load_lens
from lensrt.trace.api import make_rays, trace
lens = load_lens(None)
rays = make_rays(lens, 0.0, 1.0, np.linspace(-1, 1, 1024), 0.3)
trace(lens, rays, "float32", sys.argv[1], kernel="generic")
t = time.perf_counter()
trace(lens, rays, "float32", sys.argv[1], kernel="specialised")
print(time.perf_counter() - t)
"""


def run(code: str, device: str, env: dict, repeat: int) -> list[float]:
    """Seconds printed by ``code`` in ``repeat`` new processes (after one untimed warm-up process)."""
    times = []
    for i in range(repeat + 1):
        out = subprocess.run([sys.executable, "-c", code, device], env=env, capture_output=True, text=True,
                             check=True)
        if i > 0:
            times.append(float(out.stdout.strip().splitlines()[-1]))
    return times


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu", help="cpu, cuda or cuda:N")
    p.add_argument("--repeat", type=int, default=3, help="timed processes per case (after one warm-up)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    base = dict(os.environ)
    cases = [("import colour", COLOUR, base), ("colour tables from disk", TABLES, base),
             ("specialised trace, lensrt folder", TRACE, base | {"LENSRT_KERNEL_CACHE": "1"}),
             ("specialised trace, Warp's path", TRACE, base | {"LENSRT_KERNEL_CACHE": "0"})]
    rows = [{"case": name, "median_s": statistics.median(t), "runs_s": t}
            for name, code, env in cases for t in [run(code, args.device, env, args.repeat)]]
    if args.json:
        print(json.dumps({"device": args.device, "rows": rows}, indent=1))
        return 0
    print(f"fresh-process costs on {args.device} (median of {args.repeat} processes after a warm-up)")
    print("| case | median s | runs s |\n|---|---:|---|")
    for r in rows:
        print(f"| {r['case']} | {r['median_s']:.3f} | {', '.join(f'{v:.3f}' for v in r['runs_s'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
