"""Host time of ``lensrt report`` per section: wall seconds and CPU seconds of the report's own process.

Usage (from the repository root; the tree on PYTHONPATH is the one measured)::

    LENSRT_FIGURE_WORKERS=2 PYTHONPATH=. python benchmarks/bench_report_host.py --device cpu --ray-fraction 0.015625
    LENSRT_FIGURE_WORKERS=2 PYTHONPATH=. python benchmarks/bench_report_host.py --device cuda --out /tmp/r

CPU seconds (``time.process_time`` of the report's process, every thread of it, not the figure worker
processes) are what the report's process itself spent: on a machine that other jobs share they move less
than wall seconds, and on a GPU host they are the host time that a section puts on the report's path.
The last lines: the whole report, the time before the first section and after the last one (preparing,
waiting for figure workers, writing report.json and index.html), and the figure workers' record
(``report.json`` summary ``figure_telemetry``) where the tree has one. ``--out`` keeps the report folder
(for ``compare_report_files.py``).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("lens", nargs="?", default=None)
    p.add_argument("--device", default="cpu")
    p.add_argument("--quality", default="normal")
    p.add_argument("--ray-fraction", type=float, default=1.0)
    p.add_argument("--out", default=None, help="report folder to keep (default: a temporary one)")
    args = p.parse_args(argv)
    import lensrt.report.run as run
    from lensrt.loading import load_lens
    from lensrt.report import ReportOptions, build_report
    times: dict[str, tuple[float, float]] = {}
    plain = run._function

    def timed(spec):
        fn = plain(spec)

        def section(ctx, sec):
            w0, c0 = time.perf_counter(), time.process_time()
            try:
                fn(ctx, sec)
            finally:
                times[sec.key] = (time.perf_counter() - w0, time.process_time() - c0)
        return section
    run._function = timed
    lens = load_lens(args.lens)
    with tempfile.TemporaryDirectory() as tmp:
        w0, c0 = time.perf_counter(), time.process_time()
        report = build_report(lens, args.out or tmp, ReportOptions(quality=args.quality, device=args.device,
                                                                   ray_fraction=args.ray_fraction), quiet=True)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    print(f"lensrt report, quality {args.quality} x {args.ray_fraction:g} rays, {report.device_name}")
    print("| section | wall s | CPU s (report process) |\n|---|---:|---:|")
    for key, (w, c) in times.items():
        print(f"| {key} | {w:.2f} | {c:.2f} |")
    sw, sc = sum(w for w, _ in times.values()), sum(c for _, c in times.values())
    print(f"| outside the sections | {wall - sw:.2f} | {cpu - sc:.2f} |")
    print(f"| total | {wall:.2f} | {cpu:.2f} |")
    figs = report.summary.get("figure_telemetry")
    if figs:
        print(f"figure workers: {figs}")
    return 1 if report.failed else 0


if __name__ == "__main__":
    sys.exit(main())
