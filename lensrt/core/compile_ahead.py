"""Compile Warp modules before their first launch, several side by side, in background threads.

Warp compiles a module (its unit of compilation and caching) the first time one of its kernels
is launched, on the launching thread, one module after another. :func:`start` loads a list of
modules on a device in a pool of worker threads instead. A load is Warp's Python code generation
(serialised by Warp's codegen lock and the GIL: the short part) followed by the native compiler --
NVRTC for CUDA, LLVM/Clang for the CPU -- called through ``ctypes.CDLL``, which releases the GIL,
so the compiles of several modules run on several cores at once while the caller goes on with
its own work. Warp builds each module in a folder of its own (process and thread id) and moves
the result into its kernel cache, so concurrent loads are safe; its own ``wp.force_load`` offers
a thread pool too (``max_workers``), but blocks until every module is loaded.

:func:`wait_for` -- called by :func:`lensrt.core.telemetry.launch` before every launch -- makes a
launch whose module is still loading wait for that load instead of compiling the module a second
time on its own thread; without a preload, the first launch of a module loads it under a lock, so
that the slices of one launch on several CPU threads compile it once, not once per thread. A module
still queued in the pool when a launch needs it (fewer threads than modules) is loaded by that launch at
once, not after the modules queued before it. A load that fails is recorded (:attr:`ModuleLoad.error`)
and otherwise forgotten: the kernel then compiles on its first launch exactly as without preloading, and
raises there whatever it raises. Preloading a module that is loaded, or already being loaded, is a no-op.
"""
from __future__ import annotations

import os
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Sequence

__all__ = ["ModuleLoad", "Preload", "start", "wait_for", "pending", "default_workers", "MAX_WORKERS"]

#: most compiling threads by default: a default report's plan on a GPU is 9 modules, so on a 16-core host
#: (the H100's) every one starts at once, leaving cores to the report's thread and its figure workers
MAX_WORKERS = 12
_LOCK = threading.RLock()
#: loads not finished yet: (id of the Warp module, device alias) -> (future, its ModuleLoad, its loader or None)
_PENDING: dict[tuple[int, str], tuple[Future, "ModuleLoad", Any]] = {}
#: one lock per (module, device) for the first load on use (wait_for)
_FIRST_LOAD: dict[tuple[int, str], threading.Lock] = {}


@dataclass
class ModuleLoad:
    """One module's load in a :class:`Preload`.

    name : str
        Warp module name.
    device : str
        Device alias (``cpu``, ``cuda:0``).
    seconds : float
        Wall time of the load in its worker thread (code generation, compilation when the kernel cache
        does not hold it, loading), s; 0 until it ends.
    waited_s : float
        Time launches on other threads spent waiting for this load, s.
    error : str or None
        Why the load failed (the kernel then compiles on its first launch).
    skipped : bool
        The module was loaded already, or another preload was loading it.
    """

    name: str
    device: str
    seconds: float = 0.0
    waited_s: float = 0.0
    error: str | None = None
    skipped: bool = False


class Preload:
    """Module loads running in background threads (:func:`start`)."""

    def __init__(self, loads: list[ModuleLoad], futures: list[Future | None], pool: ThreadPoolExecutor | None,
                 started: float):
        self.loads = loads
        self._futures = futures
        self._pool = pool
        self._t0 = started

    @property
    def done(self) -> bool:
        """True when every load has ended."""
        return all(f is None or f.done() for f in self._futures)

    def wait(self) -> list[ModuleLoad]:
        """Wait for every load to end (failures included; nothing raises); returns :attr:`loads`."""
        for f in self._futures:
            if f is not None:
                try:
                    f.result()
                except BaseException:  # noqa: BLE001 - recorded in the ModuleLoad by _load
                    pass
        return self.loads

    def cancel(self) -> None:
        """Drop the loads that have not started (those running finish in the background)."""
        for f in self._futures:
            if f is not None:
                f.cancel()

    @property
    def wall_s(self) -> float:
        """Seconds from :func:`start` to now or to the end of the last load."""
        return time.perf_counter() - self._t0


def default_workers() -> int:
    """Worker threads of a preload: ``LENSRT_COMPILE_WORKERS``, else the cores this process may use less one
    (the caller's own thread goes on), at least 1, at most :data:`MAX_WORKERS`. Each compiling thread builds
    Warp's precompiled header for itself (a per-thread folder), so threads beyond the idle cores only add
    work."""
    raw = os.environ.get("LENSRT_COMPILE_WORKERS", "")
    if raw.strip():
        try:
            return max(1, int(raw))
        except ValueError:
            from ..errors import LensrtError
            raise LensrtError(f"LENSRT_COMPILE_WORKERS={raw!r} is not a whole number",
                              hint="set it to e.g. 4, or unset it") from None
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(MAX_WORKERS, cores - 1))


def _device_key(wp: Any, device: Any) -> str:
    return wp.get_device(device).alias


def _load(wp: Any, module: Any, device: str, rec: ModuleLoad, loader: Any = None) -> None:
    """Load ``module`` on ``device`` (as its first launch would: Warp's ``force_load``, or ``loader(device)``),
    timing it."""
    t0 = time.perf_counter()
    try:
        if loader is not None:
            loader(device)
        else:
            wp.force_load(device=device, modules=[module], max_workers=0)
    except BaseException as err:  # noqa: BLE001 - a failed preload only means compile-on-use
        rec.error = f"{type(err).__name__}: {err}"
    finally:
        rec.seconds = time.perf_counter() - t0


def start(modules: Sequence[Any], device: Any, workers: int | None = None,
          loaders: dict[Any, Any] | None = None) -> Preload:
    """Load ``modules`` (Warp ``Module`` objects, in the order they are needed) on ``device`` in
    ``workers`` background threads (default :func:`default_workers`); returns at once.

    ``loaders`` maps a module to a callable ``loader(device)`` that loads it the way its own code does
    (e.g. a block size of its launches, or lensrt's keyed cache of specialised kernels) instead of
    Warp's ``force_load`` with the module's default block size."""
    import warp as wp
    dev = _device_key(wp, device)
    context = wp.get_device(dev).context
    t0 = time.perf_counter()
    modules = list(dict.fromkeys(modules))
    pool = ThreadPoolExecutor(max_workers=max(1, min(len(modules), workers or default_workers())),
                              thread_name_prefix="lensrt-compile")
    loads, futures = [], []
    with _LOCK:
        for m in modules:
            rec = ModuleLoad(m.name, dev)
            loads.append(rec)
            key = (id(m), dev)
            if key in _PENDING or _loaded(m, context):
                rec.skipped = True
                futures.append(None)
                continue
            loader = (loaders or {}).get(m)
            fut = pool.submit(_load, wp, m, dev, rec, loader)
            _PENDING[key] = (fut, rec, loader)
            fut.add_done_callback(lambda f, key=key: _forget(key))
            futures.append(fut)
    pool.shutdown(wait=False)
    return Preload(loads, futures, pool, t0)


def _forget(key: tuple[int, str]) -> None:
    with _LOCK:
        _PENDING.pop(key, None)


def pending() -> list[str]:
    """Names of the modules being loaded now (``name@device``)."""
    with _LOCK:
        return [f"{rec.name}@{rec.device}" for _, rec, _ in _PENDING.values()]


def _loaded(module: Any, context: Any) -> bool:
    return any(ctx == context for ctx, _ in list(module.execs))


def wait_for(kernel: Any, device: Any = None, block_dim: int | None = None) -> None:
    """Make sure ``kernel``'s module is loaded on ``device`` before a launch, compiling it once.

    If a preload is loading the module, wait for it; if the preload has it still queued behind other modules
    (fewer compiling threads than modules), take it over: load it here, now (with the preload's loader).
    Otherwise the first caller loads it (Warp's ``force_load``, as the launch would) while other threads
    launching kernels of the same module wait, so that the slices of one launch on several CPU threads do
    not each compile it. A load that fails is left to the launch, which compiles (and raises) as it would
    have. Loaded modules cost a look-up. A launch with its own ``block_dim`` (a module variant of its own)
    only waits for a preload.
    """
    module = getattr(kernel, "module", None)
    if module is None:
        return
    import warp as wp
    dev = wp.get_device(device)
    if not _PENDING and _loaded(module, dev.context):
        return
    key = (id(module), dev.alias)
    with _LOCK:
        hit = _PENDING.get(key)
        lock = _FIRST_LOAD.setdefault(key, threading.Lock())
        # a load still queued behind others (fewer threads than modules) is taken over by this launch
        mine = hit is not None and hit[0].cancel()
        if mine:
            _PENDING.pop(key, None)
    if hit is not None:
        fut, rec, loader = hit
        t0 = time.perf_counter()
        if mine:
            with lock:  # as a first load on use: other threads launching this module wait for it
                if loader is not None or not _loaded(module, dev.context):
                    _load(wp, module, dev.alias, rec, loader)
        else:
            try:
                fut.result()
            except BaseException:  # noqa: BLE001 - cancelled: the launch compiles the module itself
                pass
        dt = time.perf_counter() - t0
        with _LOCK:
            rec.waited_s += dt
        return
    if block_dim is not None:
        return
    with lock:
        if not _loaded(module, dev.context):
            try:
                wp.force_load(device=dev, modules=[module], max_workers=0)
            except Exception:  # noqa: BLE001 - the launch itself compiles and raises what it raises
                pass
