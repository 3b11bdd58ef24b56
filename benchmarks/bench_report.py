"""Where the time of ``lensrt report`` goes: per section wall, kernel seconds, launches, copies, busy fraction.

Usage (from the repository root)::

    PYTHONPATH=. python benchmarks/bench_report.py --device cpu --quality draft
    PYTHONPATH=. python benchmarks/bench_report.py --device cuda               # the issue's case (normal)
    PYTHONPATH=. python benchmarks/bench_report.py --device cuda --json > report_bench.json
    PYTHONPATH=. python benchmarks/bench_report.py --device cpu --ray-fraction 0.015625 --no-warmup  # launch plan

It runs :func:`lensrt.report.build_report` on a lens (default: the built-in 50 mm f/2 double Gauss, as
``lensrt report`` does) into a temporary folder, after a warm-up run that compiles the Warp kernels
(``--no-warmup`` to time a cold cache; the warm-up also fills the analyses' in-process caches -- pupil
outlines, focus moments and the like -- so the measured run launches fewer kernels than ``lensrt report`` in a
fresh process: count launches with ``--no-warmup``), and prints the :mod:`lensrt.core.telemetry` record of each
section: ``wall s``, ``kernel s`` (CUDA events on a GPU; on the CPU the wall time of the launch calls,
summed over the cores a launch runs on), kernel ``launches``, host<->device ``copies`` (lensrt's own
NumPy uploads and ``.numpy()`` downloads) and ``busy`` = kernel s / wall s. A last line says how many figure
and file jobs figure worker processes ran and how long the report waited for them at its end.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile


def run_report(lens_name: str | None, device: str, quality: str, skip: list[str], ray_fraction: float = 1.0):
    """Build the report once into a temporary folder; returns the Report."""
    from lensrt.loading import load_lens
    from lensrt.report import ReportOptions, build_report
    lens = load_lens(lens_name)
    with tempfile.TemporaryDirectory() as tmp:
        options = ReportOptions(quality=quality, device=device, ray_fraction=ray_fraction)
        return build_report(lens, tmp, options, skip=skip, quiet=True)


def rows_of(report) -> list[dict]:
    """One row per section that ran, then the total."""
    rows = [dict(section=s.key, ok=s.ok, **s.telemetry) for s in report.sections if s.telemetry]
    rows.append(dict(section="total", ok=not report.failed, **report.telemetry))
    for r in rows:
        r["busy"] = r["kernel_s"] / r["wall_s"] if r["wall_s"] > 0 else 0.0
    return rows


def table(rows: list[dict]) -> str:
    """A markdown table of the rows."""
    out = ["| section | wall s | kernel s | launches | copies | busy |", "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        name = r["section"] + ("" if r["ok"] else " (failed)")
        out.append(f"| {name} | {r['wall_s']:.2f} | {r['kernel_s']:.3f} | {r['launches']} | {r['copies']} | "
                   f"{100 * r['busy']:.1f} % |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    from lensrt.report.options import QUALITIES
    from lensrt.report.run import section_keys
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("lens", nargs="?", default=None, help="lens file or library name (default: the built-in lens)")
    p.add_argument("--device", default="cpu", help="cpu, cuda or cuda:N")
    p.add_argument("--quality", choices=list(QUALITIES), default="normal")
    p.add_argument("--skip", action="append", default=[], choices=section_keys())
    p.add_argument("--no-warmup", action="store_true", help="time the first run (kernel compilation included)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.add_argument("--ray-fraction", type=float, default=1.0,
                   help="every Monte Carlo ray count of the preset times this (ReportOptions.ray_fraction)")
    args = p.parse_args(argv)
    if not args.no_warmup:
        run_report(args.lens, args.device, args.quality, args.skip, args.ray_fraction)
    report = run_report(args.lens, args.device, args.quality, args.skip, args.ray_fraction)
    rows = rows_of(report)
    if args.json:
        print(json.dumps({"device": report.device_name, "quality": args.quality, "rows": rows}, indent=1))
        return 0
    fraction = f" x {args.ray_fraction:g} rays" if args.ray_fraction != 1.0 else ""
    print(f"lensrt report {report.lens_name}, quality {args.quality}{fraction}, on {report.device_name} "
          f"({platform.processor() or platform.machine()}, python {platform.python_version()})")
    print(table(rows))
    figs = report.summary.get("figure_telemetry")
    if figs:
        print(f"figures and files: {figs['jobs']} jobs, {figs['jobs_in_workers']} by {figs['workers']} worker "
              f"processes ({figs['worker_s']:.2f} s there), {figs['caller_s']:.2f} s run in the report's process; "
              f"the report waited {figs['wait_s']:.2f} s for them at its end (LENSRT_FIGURE_WORKERS)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
