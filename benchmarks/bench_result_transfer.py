#!/usr/bin/env python
"""What a large item result costs to come back: the thread executor against one worker process.

Each of ``--items`` host-only items returns the arrays of one tile of the large render (1920 x 45
pixels x 40 bands of float64 sums and an XYZ moment: 29.7 MB by default); the job is run on one
host thread, on one worker process (``ProcessExecutor("cpu")``) and, with Dask installed, on a
LocalCluster of one worker; the best of ``--repeat`` runs is printed per item. The difference is
the transfer: through shared memory since lensrt.parallel.shm, through the worker's pipe (or the
Dask worker's socket) before. Example::

    python benchmarks/bench_result_transfer.py --items 12 --mb 29.7
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def run(item, context, device: str) -> dict:
    """A tile-like result of ``item.params`` float64 values plus an XYZ moment of 1/40 of that size."""
    n = int(item.params)
    return {"spec": np.full(n, float(item.index)), "xyz1": np.ones((n // 40, 3))}


def reduce(results: list) -> float:
    return float(sum(r["spec"][0] for r in results))


def main(argv: list[str] | None = None) -> int:
    from lensrt.parallel import Job, LocalExecutor, ProcessExecutor, make_items
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--items", type=int, default=12)
    p.add_argument("--mb", type=float, default=29.7, help="size of one result in MB (1e6 bytes)")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    n = int(args.mb * 1e6 / 8 / (1 + 3 / 40))
    job = Job(make_items([n] * args.items), run, reduce, uses_device=False, name="result-transfer")
    from lensrt.parallel import distributed_available
    kinds = [("thread", lambda: LocalExecutor("cpu")), ("process", lambda: ProcessExecutor("cpu"))]
    if distributed_available():
        from lensrt.parallel import DaskExecutor
        kinds.append(("dask", lambda: DaskExecutor.local(1, "cpu")))
    for name, make in kinds:
        with make() as ex:
            ex.run(job)
            best = min(_timed(ex, job) for _ in range(max(1, args.repeat)))
        print(f"{name:8s} {args.items} items x {args.mb:g} MB: best {best:.3f} s, {best / args.items * 1e3:.0f} ms/item")
    return 0


def _timed(ex, job) -> float:
    t0 = time.perf_counter()
    ex.run(job)
    return time.perf_counter() - t0


if __name__ == "__main__":
    sys.exit(main())
