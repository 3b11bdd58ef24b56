"""Results kept per key in a process: a bounded dict in front of a computation.

Used where a report asks for the same immutable result many times (paraxial systems, first-order data).
"""
from __future__ import annotations

from typing import Any, Callable

__all__ = ["kept"]


def kept(store: dict, key: Any, compute: Callable[[], Any], limit: int) -> Any:
    """``store[key]``, else ``compute()`` kept there (the store is emptied when it holds ``limit`` entries).

    A key that cannot be hashed is computed each time; an exception of ``compute`` is raised and nothing is
    kept. One look-up per call, so another thread emptying the store meanwhile does no harm.
    """
    try:
        hit = store.get(key)
    except TypeError:
        return compute()
    if hit is not None:
        return hit
    value = compute()
    if len(store) >= limit:
        store.clear()
    store[key] = value
    return value
