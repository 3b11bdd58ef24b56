"""Every device of one machine, one worker process each: no shared GIL between devices.

:class:`ProcessExecutor` starts one worker process per entry of its device list
(``spawn`` start method: a fresh interpreter, no inherited CUDA state), keeps
them for its whole life (so each process prepares a context once and reuses it
job after job) and hands a job's items out one at a time from one queue in the
parent: a worker that finishes gets the next item, so a fast device takes more
of them and the tail is one item long (no item is queued behind a running one,
where a long item would hold it hostage); the parent hands a worker its next
item as soon as the result's message is in, before it unpacks and folds it.
Results come back as host data -- large arrays through shared memory
(:mod:`lensrt.parallel.shm`: one copy in, one copy out, instead of a pickle
through the pipe), small ones through the worker's pipe -- and are folded in
item-index order
(:class:`~lensrt.parallel.work.OrderedFold`), so the value is bit-identical to
the one-thread :class:`~lensrt.parallel.local.LocalExecutor` run.

Why processes beside threads: in the thread executor the host share of every
item (set-up, analysis, NumPy) runs under the one interpreter lock, so with
several GPUs the host work of all of them is serial. Here each device has an
interpreter of its own. The price: each worker starts Python, lensrt and Warp
(seconds, once per executor), the context is pickled once per worker, and
each result is copied twice (into shared memory and out of it).

Faults: when a worker process dies (killed, out of memory, a driver fault), the
item it was running goes back to the front of the queue and a new process is
started on the same device; the fold keys results by index, so nothing is
counted twice and the value is unchanged. An item that kills ``max_failures``
processes stops the job with a :class:`~lensrt.errors.LensrtError` naming it.
An exception raised by ``run`` stops the job (items already running finish
first) and is re-raised in the caller.

``run``/``prepare`` follow the rules of :mod:`lensrt.parallel` (module-level,
importable: the worker imports them by name; context and results picklable).
"""
from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import time
from collections import deque
from multiprocessing.connection import wait
from typing import Any, Sequence

from ..errors import LensrtError
from .context import content_hash, drop_context, execute_item, store_context, stored_context
from .local import Progress, device_scope, resolve_devices
from .shm import Attached, SegmentPool, pack, unpack
from .work import Job, JobResult, OrderedFold, finish_result

__all__ = ["ProcessExecutor", "worker_main"]

#: deaths of worker processes one item may cause before the job stops (as Dask's allowed-failures)
MAX_FAILURES = 3
#: contexts (lenses, scenes) a worker process keeps for later jobs; the oldest is dropped first
MAX_CONTEXTS = 4
#: seconds the first worker processes may take to start (Python, lensrt, Warp)
START_TIMEOUT_S = 300.0


def _pickle(obj: Any) -> bytes:
    try:
        return pickle.dumps(obj, protocol=5)
    except Exception:  # noqa: BLE001 - lambdas and local classes
        import cloudpickle
        return cloudpickle.dumps(obj, protocol=5)


def worker_main(conn: Any, device: str) -> None:
    """Body of a worker process: receive contexts and items on ``conn``, send back outcomes.

    Messages in: ``("context", hash, pickled context)``, ``("drop", hash)``, ``("item", run, prepare,
    hash, item, uses_device)``, ``("stop",)``. Out: ``("ready", pid)`` once started, then per item
    ``("done", ItemOutcome)`` or ``("error", index, exception)``.
    """
    from ..device import warp
    warp()  # Warp initialised quietly before any job module imports it
    conn.send(("ready", os.getpid()))
    pool = SegmentPool()
    try:
        _serve(conn, device, pool)
    finally:
        pool.close()


def _serve(conn: Any, device: str, pool: SegmentPool) -> None:
    """The message loop of :func:`worker_main`."""
    unreadable: dict[str, BaseException] = {}  # contexts that did not unpickle here, by hash
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError, KeyboardInterrupt):
            return  # the parent is gone
        except Exception as err:  # noqa: BLE001 - an item message whose functions do not import here
            conn.send(("error", -1, LensrtError(f"a worker process cannot load the job: {err!r}",
                                                hint="run and prepare must be module-level functions of a "
                                                     "module the worker can import")))
            continue
        if msg[0] == "stop":
            return
        if msg[0] == "drop":
            drop_context(msg[1])
            unreadable.pop(msg[1], None)
            continue
        if msg[0] == "context":
            try:
                store_context(msg[1], pickle.loads(msg[2]))
            except Exception as err:  # noqa: BLE001 - reported with the first item that needs it
                unreadable[msg[1]] = err
            continue
        _, run, prepare, ctx_hash, item, uses_device = msg
        dev = device if uses_device else "cpu"
        try:
            if ctx_hash in unreadable:
                raise LensrtError(f"a worker process cannot load the job's context: {unreadable[ctx_hash]!r}",
                                  hint="its classes must come from modules the worker can import")
            with device_scope(dev, own_stream=False):
                out = ("done", pack(execute_item(run, prepare, stored_context(ctx_hash), ctx_hash, item, dev), pool=pool))
        except BaseException as err:  # noqa: BLE001 - handed to the parent, which re-raises it
            out = ("error", item.index, err)
        try:
            conn.send(out)
        except Exception as err:  # noqa: BLE001 - an unpicklable result or exception
            conn.send(("error", item.index, RuntimeError(f"item {item.index}: its result cannot be sent back "
                                                         f"from the worker process: {err!r}")))


class _Worker:
    """One worker process on one device, its pipe, the contexts it holds and its item in flight."""

    def __init__(self, ctx: Any, device: str, slot: int) -> None:
        self.device, self.slot = device, slot
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=worker_main, args=(child, device), name=f"lensrt-{device}-{slot}",
                                   daemon=True)
        self.process.start()
        child.close()
        self.contexts: list[str] = []  # held by the process, oldest first
        self.items: deque = deque()      # in flight, in the order sent: the first is running
        self.attached = Attached()       # the parent's mappings of the worker's result segments

    def send_item(self, job: Job, ctx_hash: str, blob: bytes, index: int) -> None:
        try:
            msg = pickle.dumps(("item", job.run, job.prepare, ctx_hash, job.items[index], job.uses_device),
                               protocol=5)
        except Exception as err:  # noqa: BLE001 - a lambda or a local function
            raise LensrtError(f"job {job.name!r} cannot be sent to a worker process: {err}",
                              hint="run and prepare must be module-level functions of an importable module, "
                                   "the items' params picklable") from None
        self.items.append(index)  # in flight from now: if the process is dead, its sentinel says so and it re-runs
        try:
            if ctx_hash in self.contexts:
                self.contexts.remove(ctx_hash)
            else:
                self.conn.send_bytes(blob)
                while len(self.contexts) >= MAX_CONTEXTS:
                    self.conn.send(("drop", self.contexts.pop(0)))
            self.contexts.append(ctx_hash)
            self.conn.send_bytes(msg)
        except (BrokenPipeError, ConnectionResetError):
            pass

    def stop(self, timeout_s: float = 5.0) -> None:
        if timeout_s > 0:
            try:
                self.conn.send(("stop",))
            except (OSError, ValueError):
                pass
        self.process.join(timeout_s)
        killed = self.process.is_alive()
        if killed:
            self.process.kill()
            self.process.join()
        self.attached.close(unlink=killed)  # a worker that stops in time unlinks its own segments
        self.conn.close()


class ProcessExecutor:
    """Runs jobs on the devices of this machine, one worker process per device entry.

    Parameters
    ----------
    devices : str or sequence of str, optional
        A device specification for :func:`~lensrt.parallel.local.resolve_devices`
        (default ``"auto"``); ``"cpu,cpu"`` is two processes on the CPU.
    max_failures : int, optional
        Worker deaths one item may cause before the job stops (default 3).

    Notes
    -----
    The processes start at the first :meth:`run` and live until :meth:`close`
    (use the executor as a context manager). Host-only jobs run on the same
    processes, on the CPU.
    """

    def __init__(self, devices: str | Sequence[str] | None = None, *, max_failures: int = MAX_FAILURES) -> None:
        self._spec = devices
        self._devices: list[str] | None = None
        self._workers: list[_Worker] = []
        self._ctx = mp.get_context("spawn")
        self.max_failures = int(max_failures)
        #: worker processes started in all (replacements of dead ones included)
        self.started = 0

    @property
    def devices(self) -> list[str]:
        if self._devices is None:
            self._devices = resolve_devices(self._spec)
            cuda = [d for d in self._devices if d.startswith("cuda")]
            if len(set(cuda)) != len(cuda):
                raise LensrtError(f"device list {', '.join(self._devices)} names a GPU twice",
                                  hint="one worker process per GPU: list each cuda:N once (cpu may repeat)")
        return self._devices

    def describe(self) -> str:
        return f"processes ({', '.join(self.devices)})"

    def _start(self, slot: int) -> _Worker:
        self.started += 1
        return _Worker(self._ctx, self.devices[slot], slot)

    def _ensure_workers(self) -> None:
        """Start one process per device and wait until each has said it is ready (replacements of dead
        processes are not waited for: their ready message comes before their first result)."""
        if self._workers:
            return
        self._workers = [self._start(k) for k in range(len(self.devices))]
        deadline = time.monotonic() + START_TIMEOUT_S
        for w in self._workers:
            ready = wait([w.conn, w.process.sentinel], timeout=max(0.0, deadline - time.monotonic()))
            try:
                msg = w.conn.recv() if w.conn in ready else None
            except (EOFError, OSError):
                msg = None
            if msg is None or msg[0] != "ready":
                self.close(kill=True)
                raise LensrtError(
                    f"the worker process for {w.device} did not start (exit code {w.process.exitcode})",
                    hint="a script that runs a ProcessExecutor needs its code under `if __name__ == "
                         "'__main__':` (worker processes import the main module); otherwise run with "
                         "--executor thread to see the error")

    def run(self, job: Job, progress: Progress | None = None) -> JobResult:
        """Run every item of ``job`` and reduce in item order; see :class:`~lensrt.parallel.JobResult`."""
        started = time.perf_counter()
        self._ensure_workers()
        ctx_hash = content_hash(job.context)
        blob = _pickle(("context", ctx_hash, _pickle(job.context)))
        fold = OrderedFold(job.reduction, len(job.items))
        todo = deque(job.schedule_order())
        try:
            error = self._loop(job, ctx_hash, blob, fold, todo, progress)
        except BaseException:
            self.close(kill=True)  # items may still be in flight: these processes cannot serve another job
            raise
        if error is not None:
            raise error
        return finish_result(fold, job, started, self.describe(), self.devices,
                             workers=sorted(set(fold.item_workers)), processes_started=self.started)

    def _loop(self, job: Job, ctx_hash: str, blob: bytes, fold: OrderedFold, todo: deque,
              progress: Progress | None) -> BaseException | None:
        """Hand out items and collect outcomes until none is left or in flight; returns the first error."""
        deaths: dict[int, int] = {}
        error: BaseException | None = None
        while True:
            if error is None:
                for w in list(self._workers):
                    if not w.items and todo:
                        if not w.process.is_alive():  # died between items: nothing to re-run
                            w.conn.close()
                            w.attached.close(unlink=True)
                            w = self._workers[w.slot] = self._start(w.slot)
                        w.send_item(job, ctx_hash, blob, todo.popleft())
            busy = [w for w in self._workers if w.items]
            if not busy:
                break
            ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
            for w in busy:
                if w.conn in ready or w.process.sentinel in ready:
                    error = self._collect(w, job, ctx_hash, blob, fold, todo, deaths, error)
            if progress:
                progress(fold.received, len(job.items))
        return error

    def _collect(self, w: _Worker, job: Job, ctx_hash: str, blob: bytes, fold: OrderedFold, todo: deque,
                 deaths: dict[int, int], error: BaseException | None) -> BaseException | None:
        """Take what worker ``w`` sent (or its death); returns the job's error so far."""
        try:
            msg = w.conn.recv() if w.conn.poll() else None
        except (EOFError, OSError):
            msg = None
        if msg is not None and msg[0] == "ready":
            return error  # a replacement process has started; its item is still running
        if msg is not None:
            if w.items:
                w.items.popleft()  # the worker answers its items in the order they were sent
            if msg[0] == "done":
                if error is None and todo:  # the next item first: the worker runs it while this one unpacks
                    w.send_item(job, ctx_hash, blob, todo.popleft())
                fold.add(unpack(msg[1], w.attached))
                return error
            return error or msg[2]
        if w.process.is_alive():
            return error  # woken by a sentinel race; nothing to read yet
        # the process died mid-item: its items go back to the front of the queue, a new process takes the slot
        index = w.items[0]
        todo.extendleft(reversed(list(w.items)[1:]))
        w.items.clear()
        deaths[index] = deaths.get(index, 0) + 1
        w.conn.close()
        w.attached.close(unlink=True)  # the dead worker's segments (any it never announced: the resource tracker)
        self._workers[w.slot] = self._start(w.slot)
        if deaths[index] >= self.max_failures:
            return error or LensrtError(
                f"item {index} of job {job.name!r} killed {deaths[index]} worker processes "
                f"(exit code {w.process.exitcode})",
                hint="it crashes its process (out of memory? a driver fault?); run it with the thread executor "
                     "to see why")
        todo.appendleft(index)
        return error

    def close(self, kill: bool = False) -> None:
        """Stop the worker processes (``kill``: at once, without letting them finish an item)."""
        for w in self._workers:
            w.stop(0.0 if kill else 5.0)
        self._workers = []

    def __enter__(self) -> "ProcessExecutor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass
