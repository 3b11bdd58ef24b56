"""The report's figure and file jobs replayed on a faster timeline: how long the end waits for the workers.

Usage (from the repository root; the tree on PYTHONPATH is the one measured)::

    PYTHONPATH=. python benchmarks/bench_figure_end.py --device cpu --ray-fraction 0.015625 \\
        --timeline-s 3.3 --workers 2 3 4

It runs the report once with a stand-in renderer that keeps every job (its pickled call, file, kind,
section and the second it was submitted, counted from the report's start) instead of running it. Then,
for each worker count, it replays the jobs into :func:`lensrt.views.plots.figure.deferred_figures` -- the
workers start at 0 as in the report, each job is submitted at its second scaled so that the last
submission falls at ``--timeline-s`` (3.3 s: the sections of the report on one H100) -- and prints how
long :meth:`FigureRenderer.wait` waited after the last submission and what it waited for. On a GPU host,
run it with ``--device cuda`` and no scaling (``--timeline-s 0`` keeps the measured seconds).
The files are written into a temporary folder (``--out`` keeps it).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time


def _capture(lens, out, options):
    """The report's jobs: (seconds since the start, section, pickled call, path, kind)."""
    import lensrt.views.plots.figure as F
    from lensrt.report import build_report

    class Keep:
        owner = ""

        def __init__(self):
            self.jobs = []
            self.t0 = time.perf_counter()

        def submit(self, job, path, kind="figure"):
            self.jobs.append((time.perf_counter() - self.t0, self.owner, job, path, kind))

    keep = Keep()
    plain = F._renderer
    F._renderer = lambda: keep  # every plot, file writer and figure of the report hands its job over
    try:
        import lensrt.report.run as run
        key_of = {spec: key for key, _, _, spec in run.SECTIONS}
        plain_fn = run._function

        def tagged(spec):  # the jobs a section submits are its own, as in the report
            keep.owner = key_of[spec]
            return plain_fn(spec)
        run._function = tagged
        import os
        os.environ["LENSRT_FIGURE_WORKERS"] = "0"
        build_report(lens, out, options, quiet=True)
    finally:
        F._renderer = plain
    return keep.jobs


def _replay(jobs, workers: int, timeline_s: float) -> dict:
    from lensrt.views.plots.figure import deferred_figures
    last = max(t for t, *_ in jobs)
    scale = timeline_s / last if timeline_s > 0 else 1.0
    t0 = time.perf_counter()
    with deferred_figures(workers) as r:
        for t, owner, job, path, kind in jobs:
            delay = t * scale - (time.perf_counter() - t0)
            if delay > 0:
                time.sleep(delay)
            r.owner = owner
            r.submit(job, path, kind)
        t_last = time.perf_counter() - t0
        errors = [e for _, _, e in r.wait() if e is not None]
    stats = r.stats()
    stats["after_last_submission_s"] = time.perf_counter() - t0 - t_last
    stats["errors"] = [str(e) for e in errors]
    return stats


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("lens", nargs="?", default=None)
    p.add_argument("--device", default="cpu")
    p.add_argument("--quality", default="normal")
    p.add_argument("--ray-fraction", type=float, default=1.0)
    p.add_argument("--timeline-s", type=float, default=3.3, help="last submission at this second (0: as measured)")
    p.add_argument("--workers", type=int, nargs="+", default=[2, 3])
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    from lensrt.loading import load_lens
    from lensrt.report import ReportOptions
    lens = load_lens(args.lens)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or tmp
        jobs = _capture(lens, out, ReportOptions(quality=args.quality, device=args.device,
                                                 ray_fraction=args.ray_fraction))
        print(f"{len(jobs)} jobs, last submitted at {max(t for t, *_ in jobs):.2f} s of the report "
              f"(replayed at {args.timeline_s:g} s)")
        print("| workers | run | wait at the end s | after the last submission s | worker s | stolen | waited for |")
        print("|---:|---:|---:|---:|---:|---:|---|")
        for n in args.workers:
            for k in range(args.repeat):
                s = _replay(jobs, n, args.timeline_s)
                late = ", ".join(f"{name} {t:.2f}" for name, t in s.get("waited_for_s", [])) or \
                    ", ".join(s["waited_for"])
                print(f"| {n} | {k + 1} | {s['wait_s']:.2f} | {s['after_last_submission_s']:.2f} | "
                      f"{s['worker_s']:.2f} | {s['stolen']} | {late} |")
                if s["errors"]:
                    print("errors:", s["errors"])
                    return 1
        slow = sorted(s["slowest"], key=lambda x: -x[2])
        print("slowest jobs (last run):", ", ".join(f"{n} {t:.2f} s" for n, _, t in slow))
    return 0


if __name__ == "__main__":
    sys.exit(main())
