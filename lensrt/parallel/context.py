"""The job context on a worker: content-hashed, prepared once per (process, device), then reused.

A job's context (a lens, a scene) is identified by the SHA-256 of its pickle.
In every process that runs items, ``prepare(context, device)`` runs once per
(context hash, prepare function, device) and its result is kept in a small
per-process cache, so a PSF map of 81 field points packs the lens into device
arrays once per GPU, not 81 times. :func:`execute_item` is the one function
every executor calls to run an item.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import socket
import threading
import time
from collections import OrderedDict
from typing import Any, Callable

from .work import ItemOutcome, WorkItem

__all__ = ["assign_worker_device", "assigned_worker_device", "content_hash", "prepared_context", "execute_item", "cache_stats", "clear_cache", "CACHE_SIZE",
           "store_context", "stored_context", "drop_context"]

#: prepared contexts kept per process (the oldest is dropped first)
CACHE_SIZE = 8

_LOCK = threading.Lock()
_CACHE: "OrderedDict[tuple, Any]" = OrderedDict()
_KEY_LOCKS: dict[tuple, threading.Lock] = {}
_STATS = {"prepare_calls": 0, "hits": 0, "items": 0, "contexts_received": 0}
#: contexts shipped to this process by a cluster executor, by content hash
_CONTEXTS: dict[str, Any] = {}


def content_hash(obj: Any) -> str:
    """Hex SHA-256 of ``obj``'s pickle (cloudpickle when the plain pickle cannot do it)."""
    try:
        data = pickle.dumps(obj, protocol=5)
    except Exception:  # noqa: BLE001 - lambdas and local classes
        import cloudpickle
        data = cloudpickle.dumps(obj, protocol=5)
    return hashlib.sha256(data).hexdigest()


def _qualname(fn: Callable | None) -> str:
    if fn is None:
        return ""
    return f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', repr(fn))}"


def prepared_context(context: Any, context_hash: str, prepare: Callable[[Any, str], Any] | None,
                     device: str) -> Any:
    """``prepare(context, device)``, computed once per process for this (hash, prepare, device).

    Thread-safe: two device threads asking for the same key wait for one
    ``prepare`` call; different keys prepare concurrently.
    """
    if prepare is None:
        return context
    key = (context_hash, _qualname(prepare), device)
    with _LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            _STATS["hits"] += 1
            return _CACHE[key]
        klock = _KEY_LOCKS.setdefault(key, threading.Lock())
    with klock:
        with _LOCK:
            if key in _CACHE:
                _STATS["hits"] += 1
                return _CACHE[key]
        value = prepare(context, device)
        with _LOCK:
            _STATS["prepare_calls"] += 1
            _CACHE[key] = value
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
            _KEY_LOCKS.pop(key, None)
    return value


def store_context(context_hash: str, context: Any) -> None:
    """Keep a shipped context in this process under its content hash (a worker plugin calls this)."""
    with _LOCK:
        _CONTEXTS[context_hash] = context
        _STATS["contexts_received"] += 1


def stored_context(context_hash: str) -> Any:
    """The context stored under ``context_hash`` in this process."""
    with _LOCK:
        try:
            return _CONTEXTS[context_hash]
        except KeyError:
            raise RuntimeError(f"job context {context_hash[:12]} was never shipped to this worker "
                               f"(pid {os.getpid()})") from None


def drop_context(context_hash: str) -> None:
    """Forget a shipped context and everything prepared from it in this process."""
    with _LOCK:
        _CONTEXTS.pop(context_hash, None)
        for key in [k for k in _CACHE if k[0] == context_hash]:
            del _CACHE[key]


def cache_stats() -> dict:
    """This process's counters: ``prepare_calls``, cache ``hits``, ``items`` run, ``contexts_received``,
    ``cached`` (prepared entries held), ``contexts`` (shipped contexts held), ``pid``."""
    with _LOCK:
        return {**_STATS, "cached": len(_CACHE), "contexts": len(_CONTEXTS), "pid": os.getpid()}


def clear_cache() -> None:
    """Drop every prepared context and reset the counters (tests, or to free device memory)."""
    with _LOCK:
        _CACHE.clear()
        _CONTEXTS.clear()
        for k in _STATS:
            _STATS[k] = 0


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def execute_item(run: Callable[[WorkItem, Any, str], Any], prepare: Callable[[Any, str], Any] | None,
                 context: Any, context_hash: str, item: WorkItem, device: str) -> ItemOutcome:
    """Run one item on ``device`` in this process (the context prepared once per process and device)."""
    prepared = prepared_context(context, context_hash, prepare, device)
    t0 = time.perf_counter()
    result = run(item, prepared, device)
    seconds = time.perf_counter() - t0
    with _LOCK:
        _STATS["items"] += 1
    return ItemOutcome(item.index, result, seconds, device, _worker_name())


#: the device a Dask worker plugin assigned to this worker process (None: not assigned)
_assigned_device: str | None = None


def assign_worker_device(device: str | None) -> None:
    """Record the device this worker process uses (set by the Dask device plugin at worker start)."""
    global _assigned_device
    _assigned_device = device


def assigned_worker_device() -> str | None:
    """The device assigned to this worker process, or None."""
    return _assigned_device
