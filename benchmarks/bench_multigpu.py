#!/usr/bin/env python
"""Scaling of one job from 1 to N devices: seconds, speed-up, efficiency, and a bit-identity check.

Examples
--------
On a machine with several GPUs: the large PSF map and the render, all three executors compared::

    python benchmarks/bench_multigpu.py --workload psf-map --size large,groups=36 --devices all \
        --executor thread,process,dask
    python benchmarks/bench_multigpu.py --workload render --size large,tiles=24 --devices all \
        --executor thread,process

On a CPU-only machine, a tiny job over 1 and 2 host threads or processes (what CI can run)::

    python benchmarks/bench_multigpu.py --devices cpu,cpu --size tiny --executor thread,process

Workloads come from :mod:`lensrt.parallel.workloads` (name -> factory of a
Job: ``psf-map``, ``render``, ``bokeh-map``, ``sweep``); this script adds
``mc-histogram``, the Monte Carlo Warp test workload of
tests/oracles/workload_mc_histogram.py. Register another with
``--workload-factory NAME=module:attribute``. ``--size PRESET,key=value``
changes one parameter of a preset, e.g. the number of work items
(``groups`` of the PSF map, ``tiles`` of the render): a multiple of every
device count (12, 24, 36 for 1..4) leaves no device idle at the end when the
items cost the same.

Each executor and device count runs a warm-up first (the executor starts its
worker processes, every device prepares the context and loads its Warp
module), then ``--repeat`` timed runs of the whole job; the table shows the
best. "speed-up" is against the same executor on the first device count;
"item bound" is the efficiency that equal items allow (18 items on 4 devices:
4.5 rounds of work take 5, so at most 0.90); "thread s / s" compares with the
thread executor on as many devices (the issue's "Dask within 10 % of the
in-process executor"); "identical" compares the reduced value with the first
run's, bit for bit.
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


EXECUTORS = ("thread", "process", "dask")


def _executor(kind: str, devices: list[str]):
    from lensrt.parallel import DaskExecutor, LocalExecutor, ProcessExecutor
    if kind == "dask":
        return DaskExecutor.local(len(devices), devices)
    return ProcessExecutor(devices) if kind == "process" else LocalExecutor(devices)


def _time_job(kind: str, devices: list[str], job, repeat: int) -> tuple[float, str]:
    """Best seconds of ``repeat`` runs of ``job`` after a warm-up, and the value's digest ("varies" if it moved)."""
    with _executor(kind, devices) as ex:
        ex.run(_warm_job(job, len(devices)))
        times, digest = [], None
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            res = ex.run(job)
            times.append(time.perf_counter() - t0)
            d = _digest(res.value)
            digest = d if digest is None else digest
            if d != digest:
                digest = "varies"
    return min(times), digest


def _item_bound(n_items: int, n_devices: int) -> float:
    """The best efficiency ``n_items`` equal items allow on ``n_devices``: the last round may be part-full."""
    return (n_items / n_devices) / -(-n_items // n_devices)


def _header(args, size: str, job, devices: list[str], kinds: list[str]) -> str:
    import platform
    import subprocess
    from lensrt.device import describe_device
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, timeout=10).stdout.strip() or "?"
    except (OSError, subprocess.SubprocessError):
        commit = "?"
    import warp
    return (f"workload {args.workload} ({size}): {len(job.items)} items; executor {', '.join(kinds)}; "
            f"devices {', '.join(describe_device(d) for d in devices)}\n"
            f"# {time.strftime('%Y-%m-%d %H:%M')}, lensrt {commit}, warp {warp.__version__}, "
            f"python {platform.python_version()}, {platform.node()}")


def main(argv: list[str] | None = None) -> int:
    import warp
    warp.config.log_level = warp.LOG_WARNING  # keep Warp's greeting out of the table
    from lensrt.parallel import resolve_devices
    from lensrt.parallel.workloads import WORKLOADS, get_workload, register_workload
    from lensrt.io.table import format_table

    register_workload("mc-histogram", "workload_mc_histogram:workload")
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workload", default="mc-histogram", help=f"one of {', '.join(sorted(WORKLOADS))}")
    p.add_argument("--workload-factory", action="append", default=[], metavar="NAME=MODULE:ATTR",
                   help="register another workload factory (size, seed) -> Job")
    p.add_argument("--size", default=None,
                   help="tiny, small, large, key=value pairs, or a preset with overrides (large,groups=36) "
                        "(default: large on CUDA, tiny on CPU)")
    p.add_argument("--devices", default="all", help="device list to scale over (default all: every GPU)")
    p.add_argument("--counts", default=None, help="device counts to run, e.g. 1,2,4 (default 1..N)")
    p.add_argument("--executor", default="thread", metavar="KIND[,KIND...]",
                   help="thread (one thread per device in this process; 'local' is the same), process (one "
                        "worker process per device), dask (a LocalCluster, one worker per device), or a "
                        "comma-separated list to compare them in one run")
    p.add_argument("--repeat", type=int, default=3, help="timed runs per device count (best is shown)")
    p.add_argument("--seed", type=int, default=2024)
    args = p.parse_args(argv)
    for spec in args.workload_factory:
        name, _, target = spec.partition("=")
        register_workload(name, target)
    kinds = ["thread" if k.strip() == "local" else k.strip() for k in args.executor.split(",") if k.strip()]
    if not kinds or any(k not in EXECUTORS for k in kinds):
        p.error(f"--executor takes {', '.join(EXECUTORS)} (or a comma-separated list of them)")

    devices = resolve_devices(args.devices)
    on_cuda = devices[0].startswith("cuda")
    size = args.size or ("large" if on_cuda else "tiny")
    job = get_workload(args.workload)(size, args.seed)
    counts = [int(c) for c in args.counts.split(",")] if args.counts else list(range(1, len(devices) + 1))
    if any(c < 1 or c > len(devices) for c in counts):
        p.error(f"--counts must lie within 1..{len(devices)}")

    print(_header(args, size, job, devices, kinds))
    rows, first_digest, thread_s = [], None, {}
    for kind in kinds:
        base_s = None
        for n in counts:
            best, digest = _time_job(kind, devices[:n], job, args.repeat)
            first_digest = digest if first_digest is None else first_digest
            if base_s is None:
                base_s = best * counts[0]  # normalise to one device if counts starts above 1
            if kind == "thread":
                thread_s[n] = best
            speedup = base_s / best
            vs_thread = f"{thread_s[n] / best:.3f}" if n in thread_s else "--"
            rows.append([kind, n, best, speedup, speedup / n, _item_bound(len(job.items), n), vs_thread,
                         len(job.items) / best, "yes" if digest == first_digest and digest != "varies" else "NO"])
            print(f"  {kind}, {n} device(s): {best:.3f} s", file=sys.stderr)
    print(format_table(rows, ["executor", "devices", "seconds", "speed-up", "efficiency", "item bound",
                              "thread s / s", "items/s", "identical"], digits=3))
    return 0


if __name__ == "__main__":
    sys.exit(main())
