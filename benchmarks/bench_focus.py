"""Best-focus moments on the device against the host path, in one process (issue 19: host time).

Usage (from the repository root)::

    PYTHONPATH=. python benchmarks/bench_focus.py --device cuda          # one H100
    PYTHONPATH=. python benchmarks/bench_focus.py --device cpu --repeat 1

Times :func:`lensrt.trace.focus.focus_moments_fields` on the jobs of the report's focus-breathing
round (the built-in lens's axial point at 9 focus distances, each on its own paraxial image plane,
128 x 128 grid, 8 x 8 sub-rays per boundary cell: ~1.3 million rays) and on the comparison's
polychromatic best focus (3 wavelengths, one plane), once with the grids made, traced and reduced
on the device (``on_device=True``, :class:`lensrt.trace.focus_grids.DeviceGrids`) and once on the
host (``on_device=False``: rays built in NumPy, traced by the store kernel, downloaded and reduced,
as before), nothing reused between calls. Prints wall, kernel seconds, launches and copies of each
(:mod:`lensrt.core.telemetry`) and the largest relative difference of the moments.
"""
from __future__ import annotations

import argparse
import math
import time


def jobs_of(lens):
    """(lens traced, breathing jobs), (lens, polychromatic jobs)."""
    from lensrt.analysis.raysets import object_field_point
    from lensrt.paraxial import first_order
    dists = [d * 1000.0 for d in (math.inf, 10.0, 5.0, 3.0, 2.0, 1.5, 1.0, 0.7, 0.5)]
    ats = [lens.replace(object_distance_mm=d) for d in dists]
    wl = lens.wavelengths.primary_nm
    breathing = [(object_field_point(a, 0.0), wl, first_order(a, wl).image_z_mm) for a in ats]
    z_par = first_order(lens, wl).image_z_mm
    poly = [(object_field_point(lens, 0.0), float(w), z_par) for w in lens.wavelengths.nm]
    return [("breathing, 9 distances", ats[0], breathing), ("best focus, 3 wavelengths", lens, poly)]


def main(argv: list[str] | None = None) -> int:
    from lensrt.core.telemetry import measure
    from lensrt.loading import load_lens
    from lensrt.trace.focus import focus_moments_fields
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("lens", nargs="?", default=None, help="lens file or library name (default: the built-in lens)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    lens = load_lens(args.lens)
    print("| case | path | wall s | kernel s | launches | copies |\n|---|---|---:|---:|---:|---:|")
    for name, traced, jobs in jobs_of(lens):
        got = {}
        for on in (True, False):
            focus_moments_fields(traced, jobs, device=args.device, on_device=on, reuse=False)  # compile, pack
            best = None
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                with measure() as rec:
                    got[on] = focus_moments_fields(traced, jobs, device=args.device, on_device=on, reuse=False)
                wall = time.perf_counter() - t0
                if best is None or wall < best[0]:
                    best = (wall, rec.kernel_s, rec.launches, rec.copies)
            print(f"| {name} | {'device' if on else 'host'} | {best[0]:.3f} | {best[1]:.3f} | {best[2]} | {best[3]} |")
        diff = max(abs(a - b) / max(abs(b), 1e-300) for x, y in zip(got[True], got[False])
                   for a, b in ((x.pp, y.pp), (x.pt, y.pt), (x.tt, y.tt)))
        print(f"|   largest relative difference of E[p.p], E[p.t], E[t.t]: {diff:.1e} | | | | | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
