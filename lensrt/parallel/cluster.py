"""Many machines: the same jobs on a Dask distributed cluster (imported lazily: ``pip install 'lensrt[dist]'``).

:class:`DaskExecutor` connects to a scheduler (``tcp://host:8786``) or starts
a ``LocalCluster`` of worker processes on loopback. For each job it

1. ships the context once per worker: a worker plugin holding the context is
   registered under the context's content hash, so every worker -- and every
   worker that joins or is restarted later -- receives it exactly once and keeps
   it in a process-level store; tasks carry only the 64-character hash;
2. submits one task per item (costly items first; host-only jobs of many cheap
   items in chunks) with ``resources={"GPU": 1}`` when the job runs on CUDA,
   so a worker started with ``--resources GPU=1`` runs one GPU task at a time;
3. streams results back with ``as_completed`` and folds them in item-index
   order (:class:`~lensrt.parallel.work.OrderedFold`), so the value does not
   depend on which worker finished first. On a ``LocalCluster`` (workers on
   this machine) a result's large arrays come through shared memory
   (:mod:`lensrt.parallel.shm`): the task returns the segment's name, not
   hundreds of MB through the local socket.

Fault handling is Dask's: when a worker process dies, the scheduler reschedules
the tasks it was running or held results of on the remaining (or restarted)
workers, up to ``distributed.scheduler.allowed-failures`` (3) deaths per task.
A task's result is the item's whole result -- nothing is accumulated on a
worker -- and the fold keys results by item index, so a rerun item can never be
counted twice.

Which device a task uses on its worker: the device the executor assigned to
that worker (a ``LocalCluster`` spreads its workers round-robin over the
requested devices), else the worker's ``LENSRT_DEVICE`` environment variable,
else the job's device specification resolved on the worker (``"auto"``: its
first GPU, or its CPU).
"""
from __future__ import annotations

import os
import time
import uuid
from typing import Any, Sequence

from ..errors import LensrtError
from .context import assigned_worker_device, content_hash, execute_item, stored_context
from .local import Progress, device_scope, resolve_devices
from .shm import pack, unpack
from .work import ItemOutcome, Job, JobResult, OrderedFold, WorkItem, finish_result

__all__ = ["DaskExecutor", "distributed_available", "worker_device"]

#: the Dask resource name lensrt requests per GPU task
GPU_RESOURCE = "GPU"
#: contexts (lenses, scenes) an executor keeps on its workers for later jobs
MAX_SHIPPED_CONTEXTS = 4
#: seconds a LocalCluster's workers may take to start (each imports lensrt and Warp)
LOCAL_START_TIMEOUT_S = 120.0


def distributed_available() -> bool:
    """True when ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise LensrtError("--workers and --scheduler need Dask distributed, which is not installed",
                          hint="pip install 'lensrt[dist]' (or pip install 'dask[distributed]')") from None
    return distributed


def worker_device(spec: str | None) -> str:
    """The Warp device a task uses in this worker process (see the module docstring)."""
    assigned = assigned_worker_device()
    if assigned is not None:
        return assigned
    env = os.environ.get("LENSRT_DEVICE")
    if env:
        return resolve_devices(env)[0]
    if spec in (None, "", "all"):
        spec = "auto"
    return resolve_devices(spec)[0]


def _run_task(items: tuple[WorkItem, ...], *, run: Any, prepare: Any, context_hash: str,
              device_spec: str | None, uses_device: bool, shared_memory: bool = False) -> list[Any]:
    """The Dask task of a chunk of items: fetch the shipped context, pick the device, run each item.
    ``shared_memory`` (the client is on this machine): large results go through shared memory."""
    context = stored_context(context_hash)
    if not uses_device:
        out = [execute_item(run, prepare, context, context_hash, it, "cpu") for it in items]
    else:
        device = worker_device(device_spec)
        with device_scope(device, own_stream=False):
            out = [execute_item(run, prepare, context, context_hash, it, device) for it in items]
    return [pack(o) for o in out] if shared_memory else out


def _wants_cuda(spec: str | Sequence[str] | None) -> bool:
    if spec is None:
        return False
    parts = spec.split(",") if isinstance(spec, str) else list(spec)
    return any(p.strip().startswith("cuda") or p.strip() == "all" for p in parts)


class DaskExecutor:
    """Runs jobs on a Dask distributed cluster.

    Parameters
    ----------
    address : str, optional
        Scheduler address (``tcp://host:8786``) of a running cluster.
    n_workers : int, optional
        Without ``address``: start a ``LocalCluster`` of this many worker
        processes on 127.0.0.1 (one thread each), closed by :meth:`close`.
    devices : str or sequence, optional
        Device specification (see :func:`~lensrt.parallel.local.resolve_devices`).
        Local cluster: resolved here and spread round-robin over the workers;
        remote cluster: resolved on each worker (default ``"auto"``).
    client : distributed.Client, optional
        Use this client (not closed by :meth:`close`).
    gpu_tasks : bool, optional
        Request ``resources={"GPU": 1}`` per task of a device job. Default:
        when the devices name CUDA, or (remote, ``"auto"``) when some worker
        advertises a GPU resource.
    chunk_size : int, optional
        Items per Dask task (see :meth:`_chunk` for the default). A chunk is
        retried as a whole; the fold drops indices it already has.
    """

    def __init__(self, address: str | None = None, *, n_workers: int | None = None,
                 devices: str | Sequence[str] | None = None, client: Any = None,
                 gpu_tasks: bool | None = None, chunk_size: int | None = None) -> None:
        distributed = _import_distributed()
        self._own_client = client is None
        self._cluster = None
        self._spec = devices
        self._shipped: list[str] = []
        if client is not None:
            self.client = client
            self._local_devices: list[str] | None = None
        elif address is not None:
            try:
                self.client = distributed.Client(address, timeout="20s")
            except (OSError, TimeoutError) as err:
                raise LensrtError(f"cannot reach the Dask scheduler at {address}: {err}",
                                  hint="start one with `dask scheduler` and workers with "
                                       "`dask worker ADDRESS --nthreads 1 --resources GPU=1`") from None
            self._local_devices = None
        else:
            n = 1 if n_workers is None else int(n_workers)
            if n < 1:
                raise LensrtError(f"--workers {n} must be at least 1")
            self._local_devices = resolve_devices(devices)
            cuda = any(d.startswith("cuda") for d in self._local_devices)
            self._cluster = distributed.LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=":0", resources={GPU_RESOURCE: 1} if cuda else None)
            self.client = distributed.Client(self._cluster)
            # every worker registered (with its GPU resource) before the first job asks the scheduler for them
            try:
                self.client.wait_for_workers(n, timeout=LOCAL_START_TIMEOUT_S)
            except TimeoutError:
                self.close()
                raise LensrtError(f"the {n} local Dask worker(s) did not start within {LOCAL_START_TIMEOUT_S:g} s",
                                  hint="see the workers' log lines above; --executor process runs without Dask")
            from ._dask_plugins import DevicePlugin
            self.client.register_plugin(DevicePlugin(self._local_devices), name="lensrt-devices")
        self._gpu_tasks = gpu_tasks
        self._chunk_size = chunk_size

    @classmethod
    def local(cls, n_workers: int, devices: str | Sequence[str] | None = None) -> "DaskExecutor":
        """A ``LocalCluster`` of ``n_workers`` processes on loopback."""
        return cls(n_workers=n_workers, devices=devices)

    @property
    def address(self) -> str:
        return str(self.client.scheduler.address)

    @property
    def devices(self) -> list[str]:
        if self._local_devices is not None:
            return list(self._local_devices)
        return [str(self._spec or "auto")]

    def n_workers(self) -> int:
        return len(self.client.scheduler_info().get("workers", {}))

    def describe(self) -> str:
        kind = "local cluster" if self._cluster is not None else f"cluster {self.address}"
        return f"dask {kind}, {self.n_workers()} worker(s), devices {', '.join(self.devices)}"

    def _task_resources(self, job: Job) -> dict | None:
        if not job.uses_device:
            return None
        gpu = self._gpu_tasks
        workers = self.client.scheduler_info().get("workers", {})
        advertised = sum(float(w.get("resources", {}).get(GPU_RESOURCE, 0)) for w in workers.values())
        if gpu is None:
            if self._local_devices is not None:
                gpu = any(d.startswith("cuda") for d in self._local_devices)
            else:
                gpu = _wants_cuda(self._spec) or (self._spec in (None, "auto") and advertised > 0)
        if not gpu:
            return None
        if advertised <= 0:
            raise LensrtError(f"the job asks for GPUs but no worker of {self.address} advertises a "
                              f"'{GPU_RESOURCE}' resource",
                              hint="start workers with `dask worker ADDRESS --nthreads 1 --resources GPU=1` "
                                   "(one per GPU), or run with --devices cpu")
        return {GPU_RESOURCE: 1}

    def run(self, job: Job, progress: Progress | None = None) -> JobResult:
        """Run every item of ``job`` on the cluster; results reduced in item order."""
        distributed = _import_distributed()
        started = time.perf_counter()
        ctx_hash = content_hash(job.context)
        resources = self._task_resources(job)
        self._ship(ctx_hash, job.context)
        token = uuid.uuid4().hex[:12]
        spec = None if self._local_devices is not None else (self._spec if isinstance(self._spec, str)
                                                              else ",".join(self._spec or ()) or None)
        fold = OrderedFold(job.reduction, len(job.items))  # before any task runs: a reduction may make
        # arrays that the items write into (lensrt.parallel.shm.SharedArrays)
        order = job.schedule_order()
        k = self._chunk(job)
        chunks = [tuple(job.items[i] for i in order[j:j + k]) for j in range(0, len(order), k)]
        futures = self.client.map(
            _run_task, chunks, run=job.run, prepare=job.prepare, context_hash=ctx_hash, device_spec=spec,
            uses_device=job.uses_device, shared_memory=self._cluster is not None, key=[f"lensrt-{job.name}-{token}-{c[0].index}" for c in chunks],
            resources=resources, pure=False)
        pending = {f.key: f for f in futures}
        del futures
        stream = distributed.as_completed(list(pending.values()), with_results=True)
        n = len(job.items)
        try:
            for fut, outcomes in stream:
                # drop our reference at once: a result already here is never recomputed when its
                # worker dies later, and the fold ignores any second delivery of an index anyway
                pending.pop(fut.key, None)
                for outcome in outcomes:
                    fold.add(unpack(outcome))
                if progress:
                    progress(fold.received, n)
        except RuntimeError as err:
            if "deserializ" not in str(err):
                raise
            raise LensrtError(f"the scheduler of {self.address} cannot read job {job.name!r}: {err}".rstrip(),
                              hint="the scheduler and every worker need the client's environment: lensrt (the "
                                   "same version) and the modules of the job's functions importable") from None
        except distributed.KilledWorker as err:
            raise LensrtError(f"an item of job {job.name!r} killed {err.allowed_failures + 1} workers in a row "
                              f"({err.task})", hint="it crashes its worker (out of memory? a driver fault?); "
                                                    "run it alone with --workers 0 to see why") from None
        finally:
            for f in pending.values():
                f.cancel()
            pending.clear()
        return finish_result(fold, job, started, self.describe(), self.devices,
                             workers=sorted(set(fold.item_workers)))

    def _chunk(self, job: Job) -> int:
        """Items per task: as given, else 1 for device jobs (each item is heavy) and, for host-only
        jobs, enough to make about 8 tasks per worker (Dask costs about a millisecond per task)."""
        if self._chunk_size is not None:
            return max(1, int(self._chunk_size))
        if job.uses_device:
            return 1
        return max(1, len(job.items) // (8 * max(1, self.n_workers())))

    def _ship(self, ctx_hash: str, context: Any) -> None:
        """Register the context's worker plugin once per executor (kept until :meth:`close`)."""
        name = f"lensrt-context-{ctx_hash[:16]}"
        if name in self._shipped:
            return
        from ._dask_plugins import ContextPlugin
        try:
            self.client.register_plugin(ContextPlugin(ctx_hash, context), name=name)
        except Exception as err:  # noqa: BLE001 - the scheduler relays a worker's error as text
            raise LensrtError(f"cannot ship the job context to the workers of {self.address}: {err}",
                              hint="every worker needs lensrt (the same version) and the modules of the "
                                   "job's functions and context importable") from None
        self._shipped.append(name)
        while len(self._shipped) > MAX_SHIPPED_CONTEXTS:
            self._unship(self._shipped.pop(0))

    def _unship(self, name: str) -> None:
        try:
            self.client.unregister_worker_plugin(name)
        except Exception:  # noqa: BLE001 - a closing cluster: the contexts die with its workers
            pass

    def close(self) -> None:
        """Drop the shipped contexts from a remote cluster and close the client and the local cluster,
        where this executor opened them (a client passed in is left as it is)."""
        if self._own_client and self._cluster is None:
            for name in self._shipped:
                self._unship(name)
        self._shipped = []
        if self._own_client:
            self.client.close()
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __enter__(self) -> "DaskExecutor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
