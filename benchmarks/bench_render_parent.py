#!/usr/bin/env python
"""The parent's serial share of a tiled render: tiles written in place against tiles returned, per executor.

The tiled render (``render`` workload of ``benchmarks/bench_multigpu.py``) runs on several devices
with one parent that collects every tile. Whatever the parent does per tile is serial across devices
and, for the last round of tiles, comes after the last device has finished: at 4 GPUs it is what
separates the speed-up from N. This runs the same Job twice per executor -- tiles written into the
run's image in place (``in place``, the default of :func:`lensrt.render.jobs.render_tiles_job`) and
tiles that return their sums for the reduction to place (``returned``, the path before it) -- and
prints per tile: the parent's seconds receiving and folding results (process executor: the time in
its result handler, shared-memory unpacking included; thread executor: the reduction's ``add``), the
bytes that came back to the parent, the worker's seconds per tile, and the job's wall seconds; then
whether the two images are the same bits.

On a CPU the kernels are slow, so the default size is the large render's image (1920 px wide, 40
bands: the bytes of a large-render tile) with 1 path per pixel and 2 passes; the seconds of the
kernels say nothing about a GPU, the parent's seconds per tile do (they depend on the tile's bytes)::

    python benchmarks/bench_render_parent.py --devices cpu,cpu --executor thread,process
"""
from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


class _Timed:
    """A Reduction that times the wrapped one's ``add`` and counts the bytes of the results it gets."""

    def __init__(self, red) -> None:
        self.red, self.add_s, self.nbytes, self.count_s = red, 0.0, 0, 0.0

    def start(self):
        return self.red.start()

    def add(self, acc, index, result):
        t0 = time.perf_counter()
        self.nbytes += len(pickle.dumps(result, protocol=5))
        self.count_s += time.perf_counter() - t0  # not the parent's work: taken off its seconds below
        t0 = time.perf_counter()
        acc = self.red.add(acc, index, result)
        self.add_s += time.perf_counter() - t0
        return acc

    def finish(self, acc):
        return self.red.finish(acc)


def _run(kind: str, devices: str, job, repeat: int) -> list[tuple]:
    from lensrt.parallel import Job, LocalExecutor, ProcessExecutor
    import lensrt.parallel.process as proc
    collect = proc.ProcessExecutor._collect
    spent = {"s": 0.0}

    def timed_collect(self, *a, **k):
        t0 = time.perf_counter()
        out = collect(self, *a, **k)
        spent["s"] += time.perf_counter() - t0
        return out

    proc.ProcessExecutor._collect = timed_collect
    rows = []
    try:
        with (ProcessExecutor(devices) if kind == "process" else LocalExecutor(devices)) as ex:
            ex.run(job)  # warm-up: processes started, kernels loaded, context prepared on every device
            for _ in range(max(1, repeat)):
                red = _Timed(job.reduction)
                timed = Job(job.items, job.run, red, context=job.context, prepare=job.prepare, name=job.name)
                spent["s"] = 0.0
                t0 = time.perf_counter()
                res = ex.run(timed)
                wall = time.perf_counter() - t0
                n = len(job.items)
                parent = spent["s"] - red.count_s if kind == "process" else red.add_s
                rows.append((wall, parent / n, red.nbytes / n, sum(res.item_seconds) / n, res.value))
    finally:
        proc.ProcessExecutor._collect = collect
    return rows


def main(argv: list[str] | None = None) -> int:
    import numpy as np
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING
    from lensrt.render.jobs import render_tiles_job, render_workload

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="scene=still_life_mesh,width=1920,spp_per_pass=1,passes=2,tiles=8")
    p.add_argument("--devices", default="cpu,cpu")
    p.add_argument("--executor", default="thread,process")
    p.add_argument("--repeat", type=int, default=2)
    args = p.parse_args(argv)
    base = render_workload(args.size, 2024)
    setup = base.context
    passes, tiles = int(base.items[0].params[2]), len(base.items)
    print(f"render {args.size}: {tiles} tiles, image {setup.shape}, {setup.n_bands} bands, devices {args.devices}")
    print("executor  tiles     wall s  parent s/tile  bytes/tile  worker s/tile")
    images = {}
    for kind in [k.strip() for k in args.executor.split(",") if k.strip()]:
        for label, in_place in (("returned", False), ("in place", True)):
            job = render_tiles_job(setup, passes, tiles, in_place=in_place)
            rows = _run(kind, args.devices, job, args.repeat)
            for wall, parent, nbytes, worker, _ in rows:
                print(f"{kind:8s}  {label:8s}  {wall:6.3f}  {parent:13.4f}  {nbytes:10.0f}  {worker:13.3f}")
            images[(kind, label)] = rows[-1][4]
    first = next(iter(images.values()))
    same = all(np.array_equal(v.spec_sum, first.spec_sum) and np.array_equal(v.xyz_stderr, first.xyz_stderr)
               and v.pass_sum.region_means == first.pass_sum.region_means for v in images.values())
    print(f"every image the same bits: {'yes' if same else 'NO'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
