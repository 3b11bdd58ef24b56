#!/usr/bin/env python
"""Host share of the tiled render's work items: what runs under the interpreter lock, per item and in the parent.

For the ``render`` workload of ``benchmarks/bench_multigpu.py`` (a Job of row-band tiles, each running
all its passes) on one device, this prints per item: wall seconds, seconds inside kernel launches,
host seconds (the rest: argument packing, NumPy, copies), and the number of device-to-host copies
(``wp.array.numpy`` calls and copies into the image in place: on a GPU each one waits for the device);
and for the parent: seconds in the reduction's ``add`` (placing tiles, all of them and the last one)
and ``finish`` (what no device overlaps at the end of the job).

On the CPU a launch runs the kernel before it returns, so "inside launches" is kernel time and the
host seconds are what a GPU run would spend on the host per item (on a faster core); the copies are
what would make each GPU wait. Example (the numbers in docs/how-to/several-gpus-and-dask.md)::

    python benchmarks/bench_render_items.py --size scene=still_life_mesh,width=240,spp_per_pass=1,passes=32,tiles=4
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


class _TimedReduction:
    """A Reduction that times the wrapped one's ``add`` and ``finish``."""

    def __init__(self, red) -> None:
        self.red, self.add_s, self.finish_s = red, [], 0.0

    def start(self):
        return self.red.start()

    def add(self, acc, index, result):
        t0 = time.perf_counter()
        acc = self.red.add(acc, index, result)
        self.add_s.append(time.perf_counter() - t0)
        return acc

    def finish(self, acc):
        t0 = time.perf_counter()
        value = self.red.finish(acc)
        self.finish_s = time.perf_counter() - t0
        return value


def main(argv: list[str] | None = None) -> int:
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING
    import lensrt.core.telemetry as tel
    import lensrt.render.jobs as jobs
    from lensrt.parallel import Job, LocalExecutor
    from lensrt.render import pupil_table

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="scene=still_life_mesh,width=240,spp_per_pass=1,passes=32,tiles=4")
    p.add_argument("--device", default="cpu")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)

    pupil_table._cpu_workers = lambda device, n: 1     # one launch per kernel call: its time is the kernel's
    counts = {"launch_s": 0.0, "launches": 0, "copies": 0}
    launch = tel.launch

    def timed_launch(*a, **k):
        t0 = time.perf_counter()
        launch(*a, **k)
        counts["launch_s"] += time.perf_counter() - t0
        counts["launches"] += 1

    replay = tel.replay

    def timed_replay(*a, **k):  # a launch recorded once per tile and replayed pass by pass
        t0 = time.perf_counter()
        replay(*a, **k)
        counts["launch_s"] += time.perf_counter() - t0
        counts["launches"] += 1

    for mod in (jobs, pupil_table):
        mod.launch = timed_launch
    pupil_table.replay = timed_replay
    numpy_of = wp.array.numpy

    def counted_numpy(self):
        counts["copies"] += 1
        return numpy_of(self)

    wp.array.numpy = counted_numpy
    copy_to_host = jobs._copy_to_host

    def counted_copy(dest, src):  # a tile's sums copied from the device straight into the image
        counts["copies"] += 1
        return copy_to_host(dest, src)

    jobs._copy_to_host = counted_copy
    base = jobs.render_workload(args.size, 2024)
    print(f"render {args.size}: {len(base.items)} items, image {base.context.shape}, {base.context.n_bands} bands, "
          f"device {args.device}")
    ex = LocalExecutor(args.device)
    ex.run(base)  # warm-up: kernels compiled and loaded, context prepared
    rows = []
    for _ in range(max(1, args.repeat)):
        red = _TimedReduction(base.reduction)
        job = Job(base.items, base.run, red, context=base.context, prepare=base.prepare, name=base.name)
        for k in counts:
            counts[k] = 0
        t0 = time.perf_counter()
        res = ex.run(job)
        wall = time.perf_counter() - t0
        n = len(job.items)
        items_s = sum(res.item_seconds)
        rows.append((wall, items_s / n, counts["launch_s"] / n, (items_s - counts["launch_s"]) / n,
                     counts["copies"] / n, counts["launches"] / n, sum(red.add_s), red.add_s[-1], red.finish_s))
    print("run s  item s  kernel s/item  host s/item  copies/item  launches/item  parent add s  last add s  finish s")
    for r in rows:
        print(f"{r[0]:5.3f}  {r[1]:6.3f}  {r[2]:13.3f}  {r[3]:11.4f}  {r[4]:11.1f}  {r[5]:13.1f}  {r[6]:12.4f}  "
              f"{r[7]:10.4f}  {r[8]:8.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
