#!/usr/bin/env python
"""Scaling of one job from 1 to N devices: seconds, speed-up, efficiency, and a bit-identity check.

Examples
--------
On a 4-GPU machine (the PSF map and the render plug in as workloads once they exist)::

    python benchmarks/bench_multigpu.py --devices all --size large
    python benchmarks/bench_multigpu.py --devices all --size large --executor dask

On a CPU-only machine, a tiny job over 1 and 2 host threads (what CI can run)::

    python benchmarks/bench_multigpu.py --devices cpu,cpu --size tiny

Workloads come from :mod:`lensrt.parallel.workloads` (name -> factory of a
Job); this script adds ``mc-histogram``, the Monte Carlo Warp test workload of
tests/workload_mc_histogram.py, which stands in for a PSF map until the real one
lands. Register another with ``--workload-factory NAME=module:attribute``.

Each device count runs a warm-up first (every device prepares the context and
loads its Warp module), then ``--repeat`` timed runs of the whole job; the
table shows the best. "identical" compares the reduced value with the
one-device value, bit for bit.
"""
from __future__ import annotations

import argparse
import hashlib
import pickle
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "oracles"))  # the test workload; Dask's spawned workers inherit sys.path


def _digest(value: object) -> str:
    if callable(getattr(value, "digest", None)):  # values that carry timings hash their content themselves
        return value.digest()
    return hashlib.sha256(pickle.dumps(value, protocol=5)).hexdigest()[:16]


def _warm_job(job, n_devices: int):
    """The first 2 items per device of ``job``: enough that every device prepares the context and loads
    its Warp module (items are handed out dynamically; ``--repeat`` absorbs a device that got none)."""
    from lensrt.parallel import Job
    return Job(job.items[: max(1, min(len(job.items), 2 * n_devices))], job.run, job.reduce, context=job.context,
               prepare=job.prepare, name=job.name + "-warmup", uses_device=job.uses_device)


def main(argv: list[str] | None = None) -> int:
    import warp
    warp.config.log_level = warp.LOG_WARNING  # keep Warp's greeting out of the table
    from lensrt.parallel import DaskExecutor, LocalExecutor, resolve_devices
    from lensrt.parallel.workloads import WORKLOADS, get_workload, register_workload
    from lensrt.io.table import format_table

    register_workload("mc-histogram", "workload_mc_histogram:workload")
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workload", default="mc-histogram", help=f"one of {', '.join(sorted(WORKLOADS))}")
    p.add_argument("--workload-factory", action="append", default=[], metavar="NAME=MODULE:ATTR",
                   help="register another workload factory (size, seed) -> Job")
    p.add_argument("--size", default=None,
                   help="tiny, small, large, or key=value pairs (default: large on CUDA, tiny on CPU)")
    p.add_argument("--devices", default="all", help="device list to scale over (default all: every GPU)")
    p.add_argument("--counts", default=None, help="device counts to run, e.g. 1,2,4 (default 1..N)")
    p.add_argument("--executor", choices=("local", "dask"), default="local",
                   help="local: one thread per device in this process; dask: a LocalCluster, one worker per device")
    p.add_argument("--repeat", type=int, default=3, help="timed runs per device count (best is shown)")
    p.add_argument("--seed", type=int, default=2024)
    args = p.parse_args(argv)
    for spec in args.workload_factory:
        name, _, target = spec.partition("=")
        register_workload(name, target)

    devices = resolve_devices(args.devices)
    on_cuda = devices[0].startswith("cuda")
    size = args.size or ("large" if on_cuda else "tiny")
    job = get_workload(args.workload)(size, args.seed)
    counts = [int(c) for c in args.counts.split(",")] if args.counts else list(range(1, len(devices) + 1))
    if any(c < 1 or c > len(devices) for c in counts):
        p.error(f"--counts must lie within 1..{len(devices)}")

    from lensrt.device import describe_device
    print(f"workload {args.workload} ({size}): {len(job.items)} items; executor {args.executor}; "
          f"devices {', '.join(describe_device(d) for d in devices)}")
    rows, base_s, base_digest = [], None, None
    for n in counts:
        devs = devices[:n]
        ex = DaskExecutor.local(n, devs) if args.executor == "dask" else LocalExecutor(devs)
        with ex:
            ex.run(_warm_job(job, n))
            times, digest = [], None
            for _ in range(max(1, args.repeat)):
                t0 = time.perf_counter()
                res = ex.run(job)
                times.append(time.perf_counter() - t0)
                d = _digest(res.value)
                digest = d if digest is None else digest
                if d != digest:
                    digest = "varies"
        best = min(times)
        if base_s is None:
            base_s, base_digest = best * counts[0], digest  # normalise to one device if counts starts above 1
        speedup = base_s / best
        rows.append([n, best, speedup, speedup / n, len(job.items) / best,
                     "yes" if digest == base_digest and digest != "varies" else "NO"])
        print(f"  {n} device(s): {best:.3f} s", file=sys.stderr)
    print(format_table(rows, ["devices", "seconds", "speed-up", "efficiency", "items/s", "identical"], digits=3))
    return 0


if __name__ == "__main__":
    sys.exit(main())
