"""The work-item model: a job is independent, seeded work items plus an in-order reduction.

A :class:`Job` is what every executor runs (in-process, one thread per device,
or a Dask cluster). It holds

* ``items``: a tuple of :class:`WorkItem` -- one field point of a PSF map, a
  wavelength band, a depth slice, an image tile, a sample pass, a lens variant
  of a sweep. Each item carries its ``index``, a picklable ``params`` payload
  and the job seed; its random stream is derived from (job seed, index) alone
  (NumPy ``SeedSequence`` spawn keys), so it does not depend on how many items
  there are, where the item runs or in which order items finish;
* ``context``: the picklable data every item needs (a ``Lens``, a scene, a
  sensor), shipped once per worker process, never once per item;
* ``prepare(context, device) -> prepared``: optional, run once per (worker
  process, context, device) and cached -- pack the lens into device arrays,
  load the Warp module, build a BVH;
* ``run(item, prepared, device) -> result``: a pure function of its arguments,
  defined at module level in an importable module (it is pickled by reference);
* ``reduce``: a function of the list of results in item-index order, or a
  :class:`Reduction` (``start``/``add``/``finish``) that the executors feed in
  item-index order as soon as the next index is in.

Because results are keyed by item index and folded in index order exactly
once (:class:`OrderedFold`), the reduced value is the same whatever order the
items finish in, and a result delivered twice (a task retried after its worker
died) can never be counted twice.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Protocol, Sequence, runtime_checkable

import numpy as np

__all__ = ["WorkItem", "Job", "Reduction", "ListReduction", "OrderedFold", "ItemOutcome", "JobResult",
           "make_items", "item_seed_sequence", "WARP_SEED_MASK"]

#: Warp's ``rand_init(seed, offset)`` takes an int32 seed: item seeds are kept in [0, 2^31).
WARP_SEED_MASK = 0x7FFFFFFF


def item_seed_sequence(job_seed: int, index: int) -> np.random.SeedSequence:
    """The ``SeedSequence`` of item ``index`` of a job seeded with ``job_seed``.

    Equal to ``SeedSequence(job_seed).spawn(n)[index]`` for any ``n > index``:
    the child's spawn key is ``(index,)``.
    """
    if job_seed < 0 or index < 0:
        raise ValueError("job seed and item index must be non-negative integers")
    return np.random.SeedSequence(int(job_seed), spawn_key=(int(index),))


@dataclass(frozen=True)
class WorkItem:
    """One independent unit of a job.

    Attributes
    ----------
    index : int
        Position in the job (0-based); the reduction runs in this order.
    params : Any
        Picklable description of the item (e.g. ``{"field_xy": (0.0, 0.7), "wavelength_nm": 550.0}``).
    job_seed : int
        The job's seed; the item's random stream comes from (job_seed, index).
    cost : float
        Relative cost hint (1 = typical); executors hand out costly items first.
    """

    index: int
    params: Any = None
    job_seed: int = 0
    cost: float = 1.0

    @property
    def seed_sequence(self) -> np.random.SeedSequence:
        return item_seed_sequence(self.job_seed, self.index)

    @property
    def seed(self) -> int:
        """A 31-bit integer seed for ``wp.rand_init(seed, offset)`` (offset = the thread's sample index)."""
        return int(self.seed_sequence.generate_state(1, dtype=np.uint32)[0]) & WARP_SEED_MASK

    def rng(self) -> np.random.Generator:
        """A NumPy generator for host-side sampling of this item (PCG64 on the item's seed sequence)."""
        return np.random.Generator(np.random.PCG64(self.seed_sequence))


def make_items(params: Iterable[Any], job_seed: int = 0, costs: Sequence[float] | None = None) -> tuple[WorkItem, ...]:
    """One :class:`WorkItem` per entry of ``params``, indexed 0, 1, ... in order."""
    plist = list(params)
    if costs is not None and len(costs) != len(plist):
        raise ValueError("costs must have one entry per item")
    return tuple(WorkItem(i, p, int(job_seed), 1.0 if costs is None else float(costs[i]))
                 for i, p in enumerate(plist))


@runtime_checkable
class Reduction(Protocol):
    """A fold over item results, fed in item-index order, each index exactly once."""

    def start(self) -> Any:
        """The empty accumulator."""

    def add(self, acc: Any, index: int, result: Any) -> Any:
        """Fold the result of item ``index`` into ``acc``; returns the new accumulator."""

    def finish(self, acc: Any) -> Any:
        """The job's value from the final accumulator."""


@dataclass(frozen=True)
class ListReduction:
    """A :class:`Reduction` that keeps every result and calls ``fn(results_in_index_order)``."""

    fn: Callable[[list], Any]

    def start(self) -> list:
        return []

    def add(self, acc: list, index: int, result: Any) -> list:
        acc.append(result)
        return acc

    def finish(self, acc: list) -> Any:
        return self.fn(acc)


@dataclass(frozen=True)
class Job:
    """A list of independent work items, the function that runs one, and the reduction.

    See the module docstring for the contract of each field. ``uses_device``
    is False for host-only jobs (NumPy, no Warp): executors then neither
    initialise Warp nor ask a cluster for GPUs.
    """

    items: tuple[WorkItem, ...]
    run: Callable[[WorkItem, Any, str], Any]
    reduce: Reduction | Callable[[list], Any]
    context: Any = None
    prepare: Callable[[Any, str], Any] | None = None
    name: str = "job"
    uses_device: bool = True

    def __post_init__(self) -> None:
        items = tuple(self.items)
        object.__setattr__(self, "items", items)
        for i, it in enumerate(items):
            if it.index != i:
                raise ValueError(f"work item at position {i} has index {it.index}: items must be indexed 0..n-1 "
                                 "in order (use make_items)")

    @property
    def reduction(self) -> Reduction:
        return self.reduce if isinstance(self.reduce, Reduction) else ListReduction(self.reduce)

    def schedule_order(self) -> list[int]:
        """Indices in the order to hand them out: costly items first (stable), to shorten the tail."""
        return sorted(range(len(self.items)), key=lambda i: (-self.items[i].cost, i))


@dataclass(frozen=True)
class ItemOutcome:
    """What a worker sends back for one item: the result and where/how long it ran."""

    index: int
    result: Any
    seconds: float
    device: str
    worker: str = ""


class OrderedFold:
    """Folds item results into a :class:`Reduction` in index order, each index exactly once.

    Results may arrive in any order and more than once (a retried task);
    out-of-order results wait in a buffer until every lower index is in, and a
    second delivery of an index is dropped (and counted in ``duplicates``).
    """

    def __init__(self, reduction: Reduction, n_items: int) -> None:
        self._red = reduction
        self._acc = reduction.start()
        self._n = int(n_items)
        self._next = 0
        self._pending: dict[int, Any] = {}
        self.duplicates = 0
        self.item_seconds = [0.0] * self._n
        self.item_devices = [""] * self._n
        self.item_workers = [""] * self._n

    @property
    def done(self) -> int:
        """Items folded so far."""
        return self._next

    @property
    def received(self) -> int:
        """Distinct items received (folded or waiting)."""
        return self._next + len(self._pending)

    def add(self, outcome: ItemOutcome) -> bool:
        """Take one outcome; returns False (and counts a duplicate) when its index was already received."""
        i = outcome.index
        if not 0 <= i < self._n:
            raise ValueError(f"result for item {i} of a job with {self._n} items")
        if i < self._next or i in self._pending:
            self.duplicates += 1
            return False
        self.item_seconds[i] = outcome.seconds
        self.item_devices[i] = outcome.device
        self.item_workers[i] = outcome.worker
        self._pending[i] = outcome.result
        while self._next in self._pending:
            self._acc = self._red.add(self._acc, self._next, self._pending.pop(self._next))
            self._next += 1
        return True

    def finish(self) -> Any:
        if self._next != self._n:
            missing = [i for i in range(self._n) if i >= self._next and i not in self._pending]
            raise RuntimeError(f"{len(missing)} item(s) never came back (first: {missing[:5]})")
        return self._red.finish(self._acc)


@dataclass(frozen=True)
class JobResult:
    """The reduced value of a job and how it ran.

    ``item_seconds``/``item_devices``/``item_workers`` are per item in index
    order (the run that was kept); ``duplicates`` counts results that came
    back a second time and were dropped.
    """

    value: Any
    n_items: int
    seconds: float
    executor: str
    devices: tuple[str, ...]
    item_seconds: tuple[float, ...] = ()
    item_devices: tuple[str, ...] = ()
    item_workers: tuple[str, ...] = ()
    duplicates: int = 0
    meta: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """JSON-ready description of the run (not the value)."""
        return {"n_items": self.n_items, "seconds": self.seconds, "executor": self.executor,
                "devices": list(self.devices), "item_seconds_total": float(sum(self.item_seconds)),
                "duplicates_dropped": self.duplicates, **self.meta}


def finish_result(fold: OrderedFold, job: Job, started: float, executor: str,
                  devices: Sequence[str], **meta: Any) -> JobResult:
    """Reduce and wrap; ``started`` is a ``time.perf_counter()`` value."""
    value = fold.finish()
    return JobResult(value, len(job.items), time.perf_counter() - started, executor, tuple(devices),
                     tuple(fold.item_seconds), tuple(fold.item_devices), tuple(fold.item_workers),
                     fold.duplicates, dict(meta))
