"""CPU seconds of each report section, split into kernels, figures and the rest (host work).

Usage (from the repository root; single-threaded BLAS, or the process CPU time counts OpenBLAS's spinning
helper threads)::

    OPENBLAS_NUM_THREADS=1 LENSRT_FIGURE_WORKERS=0 PYTHONPATH=. python benchmarks/bench_report_host_cpu.py OUT_DIR
    OPENBLAS_NUM_THREADS=1 LENSRT_FIGURE_WORKERS=0 PYTHONPATH=. python benchmarks/bench_report_host_cpu.py OUT_DIR \\
        --ray-fraction 0.015625 --skip bokeh

Builds the report of the default lens on the CPU into ``OUT_DIR`` and prints one JSON object, per section:
``section_cpu`` (process CPU seconds while the section ran, all threads), ``kernel_cpu`` (thread CPU seconds
of its kernel launches), ``host_cpu`` (the difference), ``figures_cpu`` (thread CPU seconds of
``save_figure``), ``host_no_fig``, ``wall`` and ``launches``. CPU seconds rather than wall time because a
shared machine's load moves wall times by tens of per cent; compare trees by running them alternately.
"""
from __future__ import annotations

import argparse
import collections
import json
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out_dir")
    p.add_argument("--ray-fraction", type=float, default=0.015625)
    p.add_argument("--skip", action="append", default=[])
    args = p.parse_args(argv)
    acc: dict = collections.defaultdict(float)
    cur = {"key": None}
    lock = threading.Lock()
    # wrapped before the modules that import them by name are loaded
    import lensrt.core.telemetry as tel
    launch0 = tel.launch

    def launch(*a, **k):
        t = time.thread_time()
        try:
            return launch0(*a, **k)
        finally:
            with lock:
                acc[(cur["key"], "kernel")] += time.thread_time() - t
    tel.launch = launch
    import lensrt.views.plots.figure as fig
    save0 = fig.save_figure

    def save_figure(*a, **k):
        t = time.thread_time()
        try:
            return save0(*a, **k)
        finally:
            with lock:
                acc[(cur["key"], "figures")] += time.thread_time() - t
    fig.save_figure = save_figure
    import lensrt.report.run as run
    function0 = run._function

    def timed(spec):
        f = function0(spec)

        def g(ctx, sec):
            cur["key"] = sec.key
            c = time.process_time()
            try:
                return f(ctx, sec)
            finally:
                acc[(sec.key, "section")] += time.process_time() - c
        return g
    run._function = timed
    from lensrt.loading import load_lens
    from lensrt.report import ReportOptions, build_report
    rep = build_report(load_lens(None), args.out_dir, ReportOptions(device="cpu", ray_fraction=args.ray_fraction),
                       skip=args.skip, quiet=True)
    rows = {}
    for s in rep.sections:
        if not s.telemetry:
            continue
        k = s.key
        sec, ker, figs = acc[(k, "section")], acc[(k, "kernel")], acc[(k, "figures")]
        rows[k] = {"section_cpu": sec, "kernel_cpu": ker, "host_cpu": sec - ker, "figures_cpu": figs,
                   "host_no_fig": sec - ker - figs, "wall": s.telemetry["wall_s"], "launches": s.telemetry["launches"]}
    print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
