"""Scaling out: run a job's independent work items on every GPU of a machine or on a Dask cluster.

Where this sits in the pipeline
-------------------------------
``lensrt.parallel`` is a utility layer beside :mod:`lensrt.device` and
:mod:`lensrt.stats`, underneath the stages: it imports no stage. A stage that
has embarrassingly parallel work (the PSF map over field points and
wavelengths, bokeh maps over depths, render tiles or sample passes, a sweep over
lens variants) describes it as a :class:`Job` -- items, a ``run`` function and
a ``reduce`` -- and the caller (the CLI through
``lensrt.commands._parallel.executor_from_args``, or a user script) picks an
executor:

* :class:`LocalExecutor` -- one host thread per Warp device of this machine
  (all GPUs, or the CPU), each with its own CUDA stream;
* :class:`ProcessExecutor` -- one worker process per device of this machine
  (``spawn``; no interpreter lock shared between devices; a killed process's
  item re-runs on a new one);
* :class:`DaskExecutor` -- a Dask distributed cluster: a LocalCluster of worker
  processes on loopback, or a real one at ``tcp://host:8786`` (imported lazily;
  ``pip install 'lensrt[dist]'``).

The contract a stage implements (see :mod:`lensrt.parallel.work`)::

    items   = make_items(params_list, job_seed)          # WorkItem(index, params, job_seed)
    prepare(context, device) -> prepared                   # optional; once per process and device
    run(item, prepared, device) -> result                  # module-level, pure, returns host data
    reduce(results_in_index_order) -> value                # or a Reduction(start, add, finish)
    job = Job(items, run, reduce, context=lens_or_scene, prepare=prepare, name="psf-map")
    value = executor.run(job).value

Rules for ``prepare`` and ``run``: they are module-level functions of an
importable module (Dask pickles them by reference); they pass ``device=device``
to every Warp allocation and launch (Warp's default device is process-wide, so
threads must not rely on it); ``prepare``'s result is read-only (threads on the
same device share it -- allocate per-item scratch inside ``run``); ``run``
returns host data (NumPy arrays, numbers), never device arrays; its random
numbers come from ``item.seed`` / ``item.rng()`` only. A Monte Carlo item
returns its sample count (and per-batch sums where a standard error is wanted)
so that the reduction can build a :class:`lensrt.stats.Estimate`.

Determinism
-----------
Each item's random stream comes from (job seed, item index) only
(``item.seed`` for ``wp.rand_init(item.seed, sample_index)``, ``item.rng()``
on the host), and results are reduced on the host in item-index order. So the
value is bit-identical whatever the number of devices, threads or workers and
whatever order items finish in -- provided each item's own computation is
deterministic on its device. Integer atomics (histogram counts) are; float
``atomic_add`` on a GPU is not (the order of additions changes from run to
run), nor is any reduction inside an item that depends on thread scheduling.
CPU and CUDA runs agree within float tolerance, not bit for bit.
"""
from __future__ import annotations

from .context import cache_stats, clear_cache, content_hash
from .local import LocalExecutor, resolve_devices
from .process import ProcessExecutor
from .work import (ItemOutcome, Job, JobResult, ListReduction, OrderedFold, Reduction, WorkItem,
                   item_seed_sequence, make_items)

__all__ = ["WorkItem", "Job", "JobResult", "Reduction", "ListReduction", "OrderedFold", "ItemOutcome",
           "make_items", "item_seed_sequence", "LocalExecutor", "ProcessExecutor", "DaskExecutor", "resolve_devices",
           "content_hash", "cache_stats", "clear_cache", "distributed_available"]


def __getattr__(name: str):
    # the Dask executor is imported on first use, so lensrt runs without Dask installed
    if name in ("DaskExecutor", "distributed_available"):
        from . import cluster
        return getattr(cluster, name)
    raise AttributeError(f"module 'lensrt.parallel' has no attribute {name!r}")
