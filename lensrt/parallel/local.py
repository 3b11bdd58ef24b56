"""Every device of one machine: one host thread per Warp device, each with its own stream.

:class:`LocalExecutor` hands a job's items out dynamically (a shared queue,
costly items first) to one host thread per entry of its device list. Each
thread runs inside :func:`device_scope`: on CUDA, the device's context made
current for that thread and a ``wp.Stream`` of its own as the device's current
stream, so kernel launches and copies of different GPUs overlap (Warp's
launches are asynchronous and its native calls release the GIL). Results come
back to the calling thread and are folded in item-index order, so the reduced
value is bit-identical to a one-device run whenever each item's computation is
deterministic (see the package docstring for what breaks that).

Why not ``wp.ScopedDevice`` in the threads: in Warp (1.19) the *default
device* it sets is one process-wide variable, so threads entering and leaving
it race and can leave the default changed. :func:`device_scope` does the
thread-safe part of it (``device.context_guard``, a per-thread CUDA context
push) and sets the stream of its own device only. Hence the rule for ``run``
and ``prepare``: pass ``device=device`` to every Warp allocation and launch,
never rely on the default device.

On a machine without CUDA the same code runs on ``"cpu"``; a device list with
``"cpu"`` repeated (``"cpu,cpu"``) runs that many host threads on the CPU.
"""
from __future__ import annotations

import queue
import threading
import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Sequence

from ..errors import LensrtError
from .context import content_hash, execute_item
from .work import ItemOutcome, Job, JobResult, OrderedFold, finish_result

__all__ = ["LocalExecutor", "resolve_devices", "device_scope", "Progress"]

#: progress callback: (items done, items total)
Progress = Callable[[int, int], None]


def resolve_devices(spec: str | Sequence[str] | None = None) -> list[str]:
    """Warp device names for a device specification.

    ``None``/``"auto"``: ``["cuda:0"]`` when Warp sees a GPU, else ``["cpu"]``;
    ``"all"``: every CUDA device Warp sees (``["cpu"]`` when it sees none);
    ``"cpu"``, ``"cuda"`` (= ``cuda:0``), ``"cuda:N"``; or a comma-separated
    list / sequence of those (repeats allowed: ``"cpu,cpu"`` is two CPU threads).
    Asking for a CUDA device that is not there is an error, never a silent switch.
    """
    if spec is None:
        spec = "auto"
    parts = [p.strip() for p in spec.split(",")] if isinstance(spec, str) else [str(p).strip() for p in spec]
    parts = [p for p in parts if p]
    if not parts:
        raise LensrtError("empty device list", hint="use cpu, cuda, cuda:N, all, or a comma-separated list")
    if all(p == "cpu" for p in parts):
        return parts  # no need to start Warp to know that
    from ..device import resolve_device, warp
    out: list[str] = []
    for p in parts:
        if p == "all":
            cuda = [str(d) for d in warp().get_cuda_devices()]
            out.extend(cuda if cuda else ["cpu"])
        else:
            out.append(resolve_device(p))
    return out


@contextmanager
def device_scope(device: str, own_stream: bool = True) -> Iterator[None]:
    """Thread-safe device scope: on CUDA, push the device's context for this thread and, with
    ``own_stream``, make a new ``wp.Stream`` the device's current stream until the scope ends.

    A no-op on the CPU. The device's previous stream waits for the new one on exit.
    """
    from ..device import warp
    wp = warp()
    dev = wp.get_device(device)
    if not dev.is_cuda:
        yield
        return
    with dev.context_guard:
        saved = dev.stream
        if own_stream:
            dev.set_stream(wp.Stream(dev), sync=True)
        try:
            yield
        finally:
            if own_stream:
                dev.set_stream(saved, sync=True)


def _device_thread(job: Job, ctx_hash: str, device: str, todo: "queue.SimpleQueue[int]",
                   results: "queue.SimpleQueue[Any]", stop: threading.Event) -> None:
    """Body of one device thread: pull item indices until the queue is empty or ``stop`` is set."""
    try:
        with device_scope(device):
            while not stop.is_set():
                try:
                    i = todo.get_nowait()
                except queue.Empty:
                    break
                results.put(execute_item(job.run, job.prepare, job.context, ctx_hash, job.items[i], device))
    except BaseException as err:  # noqa: BLE001 - handed to the calling thread, which re-raises it
        results.put(err)
    finally:
        results.put(None)  # this thread is done


class LocalExecutor:
    """Runs jobs on the devices of this machine, one host thread per device entry.

    Parameters
    ----------
    devices : str or sequence of str, optional
        A device specification for :func:`resolve_devices` (default ``"auto"``).

    Notes
    -----
    A host-only job (``job.uses_device`` False) runs in the calling thread and
    never initialises Warp.
    """

    def __init__(self, devices: str | Sequence[str] | None = None) -> None:
        self._spec = devices
        self._devices: list[str] | None = None

    @property
    def devices(self) -> list[str]:
        if self._devices is None:
            self._devices = resolve_devices(self._spec)
        return self._devices

    def describe(self) -> str:
        return f"local ({', '.join(self.devices)})"

    def run(self, job: Job, progress: Progress | None = None) -> JobResult:
        """Run every item of ``job`` and reduce in item order; see :class:`JobResult`."""
        started = time.perf_counter()
        ctx_hash = content_hash(job.context)
        fold = OrderedFold(job.reduction, len(job.items))
        n = len(job.items)
        if not job.uses_device:
            for i in job.schedule_order():
                fold.add(execute_item(job.run, job.prepare, job.context, ctx_hash, job.items[i], "cpu"))
                if progress:
                    progress(fold.received, n)
            return finish_result(fold, job, started, "local (host)", ["cpu"])
        devices = self.devices
        cuda = [d for d in devices if d.startswith("cuda")]
        if len(set(cuda)) != len(cuda):
            raise LensrtError(f"device list {', '.join(devices)} names a GPU twice",
                              hint="one host thread per GPU: list each cuda:N once (cpu may repeat)")
        todo: "queue.SimpleQueue[int]" = queue.SimpleQueue()
        for i in job.schedule_order():
            todo.put(i)
        results: "queue.SimpleQueue[Any]" = queue.SimpleQueue()
        stop = threading.Event()
        threads = [threading.Thread(target=_device_thread, args=(job, ctx_hash, d, todo, results, stop),
                                    name=f"lensrt-{d}-{k}", daemon=True) for k, d in enumerate(devices)]
        for t in threads:
            t.start()
        error: BaseException | None = None
        running = len(threads)
        try:
            while running:
                msg = results.get()
                if msg is None:
                    running -= 1
                elif isinstance(msg, ItemOutcome):
                    fold.add(msg)
                    if progress:
                        progress(fold.received, n)
                elif error is None:
                    error = msg
                    stop.set()
        except BaseException:
            stop.set()
            raise
        finally:
            for t in threads:
                t.join()
        if error is not None:
            raise error
        return finish_result(fold, job, started, self.describe(), devices)

    def close(self) -> None:
        """Nothing to release (symmetry with the Dask executor)."""

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
