"""``--devices``, ``--executor``, ``--workers``, ``--scheduler``: one set of options for every command that runs a job.

A command adds them with :func:`add_parallel_arguments` and runs its job with
the executor :func:`executor_from_args` builds::

    add_parallel_arguments(p)
    ...
    with executor_from_args(args) as ex:
        result = ex.run(job, progress=progress_printer(args))

* no ``--workers``/``--scheduler``: this process, one thread per device of
  ``--devices`` (:class:`~lensrt.parallel.LocalExecutor`);
* ``--executor process``: one worker process per device of ``--devices``
  (:class:`~lensrt.parallel.ProcessExecutor`: no interpreter lock shared
  between devices);
* ``--workers N``: a Dask LocalCluster of N processes on 127.0.0.1, spread
  over ``--devices``;
* ``--scheduler ADDRESS``: a running Dask cluster; ``--devices`` is resolved
  on each worker.
"""
from __future__ import annotations

import argparse
import sys
from typing import Any, Callable

from ..errors import LensrtError

__all__ = ["add_parallel_arguments", "executor_from_args", "progress_printer", "run_summary_line"]


def add_parallel_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``parallel execution`` option group to ``parser``."""
    g = parser.add_argument_group("parallel execution")
    g.add_argument("--devices", default=None, metavar="LIST",
                   help="Warp devices: auto (default: the first GPU, else the CPU), all (every GPU Warp sees), "
                        "cpu, cuda, cuda:N, or a comma-separated list (cpu,cpu = two CPU threads)")
    g.add_argument("--executor", choices=("thread", "process"), default="thread",
                   help="how this machine's --devices are driven: thread (default: one host thread per device in "
                        "this process) or process (one worker process per device: no shared interpreter lock; "
                        "a crashed process's item re-runs on a new one)")
    g.add_argument("--workers", type=int, default=0, metavar="N",
                   help="run on N local worker processes (a Dask LocalCluster on 127.0.0.1, spread over "
                        "--devices); 0 (default): this machine's --devices, driven as --executor says")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask cluster at ADDRESS (e.g. tcp://host:8786); its workers need lensrt "
                        "installed, and for GPU work `--resources GPU=1`")


def executor_from_args(args: argparse.Namespace, uses_device: bool = True) -> Any:
    """The executor the options ask for (a context manager: close it when done).

    ``uses_device=False`` (a host-only job, e.g. the paraxial sweep) ignores
    ``--devices`` and never starts Warp.
    """
    workers = getattr(args, "workers", 0) or 0
    scheduler = getattr(args, "scheduler", None)
    devices = getattr(args, "devices", None) if uses_device else "cpu"
    if workers < 0:
        raise LensrtError(f"--workers {workers} must be 0 (this process) or a positive count")
    if scheduler and workers:
        raise LensrtError("--workers starts a local cluster and --scheduler names a running one: give one of them")
    kind = getattr(args, "executor", None) or "thread"
    if kind == "process":
        if scheduler or workers:
            raise LensrtError("--executor process starts its own worker processes (one per device of --devices); "
                              "--workers/--scheduler run on Dask instead: give one of them")
        from ..parallel.process import ProcessExecutor
        return ProcessExecutor(devices)
    if scheduler:
        from ..parallel.cluster import DaskExecutor
        return DaskExecutor(scheduler, devices=devices)
    if workers:
        from ..parallel.cluster import DaskExecutor
        return DaskExecutor.local(workers, devices=devices)
    from ..parallel.local import LocalExecutor
    return LocalExecutor(devices)


def progress_printer(args: argparse.Namespace | None = None, label: str = "items") -> Callable[[int, int], None] | None:
    """A progress callback that draws a ``done/total`` bar on stderr when stderr is a terminal (else None);
    see :mod:`lensrt.views.progress`."""
    if not sys.stderr.isatty():
        return None
    from ..views.progress import ProgressBar
    return ProgressBar(label)


def run_summary_line(result: Any) -> str:
    """One line on how a job ran: items, seconds, executor."""
    n = result.n_items
    return f"{n} item{'' if n == 1 else 's'} in {result.seconds:.3g} s on {result.executor}"
