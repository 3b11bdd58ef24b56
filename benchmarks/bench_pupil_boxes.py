"""Pupil boxes of a bokeh map's 450 sources: the host grid pass against the one-launch device pass.

Usage (from the repository root)::

    python benchmarks/bench_pupil_boxes.py --device cuda

Times :func:`lensrt.trace.pupil_boxes.pupil_boxes` (coarse 128^2 and fine 64^2 grids, three
wavelengths, 450 object points at 1, 2 and 4 m before the 50 mm f/2 double Gauss) with
``on_device=False`` (rays built in NumPy, traced by the store kernel, results downloaded) and
``on_device=True`` (:mod:`lensrt.trace.kernels.boxes`), the best of ``--repeat`` runs each after
a warm-up, and prints the largest difference between the two passes' boxes and footprints.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lensrt.loading import load_lens  # noqa: E402
from lensrt.trace.pupil_boxes import pupil_boxes  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--sources", type=int, default=450)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    lens = load_lens("dgauss_50mm_f2")
    rng = np.random.default_rng(1)
    S = args.sources
    obj = np.stack([rng.uniform(-600, 600, S), rng.uniform(-400, 400, S),
                    rng.choice([-1000.0, -2000.0, -4000.0], S)], axis=1)
    out = {}
    for on in (False, True):
        best = np.inf
        for _ in range(args.repeat + 1):  # the first run warms up (kernel compilation)
            t0 = time.perf_counter()
            out[on] = pupil_boxes(lens, obj, [450.0, 550.0, 650.0], plane_z_mm=lens.image_z_mm, device=args.device,
                                  footprint=True, on_device=on)
            best = min(best, time.perf_counter() - t0) if _ else best
        print(f"{'device' if on else 'host'} pass: {best:.4f} s for {S} sources ({args.device})")
    (bh, fh), (bd, fd) = out[False], out[True]
    d = max(max(abs(x.a0 - y.a0), abs(x.a1 - y.a1), abs(x.b0 - y.b0), abs(x.b1 - y.b1)) for x, y in zip(bh, bd))
    ok = ~np.isnan(fh)
    print(f"largest box difference {d:.3g} mm, footprint {np.max(np.abs(fh[ok] - fd[ok])):.3g} mm, "
          f"same unlit sources: {np.array_equal(np.isnan(fh), np.isnan(fd))}")


if __name__ == "__main__":
    main()
