"""TEST WORKLOAD -- not part of lensrt: a host-only job whose value depends on the order of its reduction.

Each item draws one float from its own generator (``item.rng()``, so from (job
seed, index) only) and scales it by 10^k with k in [-8, 8]: summing such
numbers in another order gives another float. The reduction adds them in the
order it is fed and records that order, so a value equal to the one-device
value proves the executor folded the items in index order.

Work stealing: with ``OrderSetup.block_dir`` set, item 0 (handed out first)
does not finish until every other item has written its marker file in that
folder. Its device therefore runs exactly one item, the others must take all
the rest from the shared queue (a static split would wait forever: the item
gives up after ``block_timeout_s`` and fails), and item 0 is the last to
finish -- the most out-of-order completion there is. The markers are files, so
this works for threads and for worker processes alike.
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from lensrt.parallel import Job, WorkItem, make_items


@dataclass(frozen=True)
class OrderSetup:
    block_dir: str = ""
    block_timeout_s: float = 120.0


def run(item: WorkItem, setup: OrderSetup, device: str) -> tuple[float, str]:
    """The item's number and who ran it (process id and thread name)."""
    rng = item.rng()
    value = float(rng.random() * 10.0 ** int(rng.integers(-8, 9)))
    runner = f"{os.getpid()}:{threading.current_thread().name}"
    if setup.block_dir:
        folder = Path(setup.block_dir)
        if item.index == 0:
            n_other = int(item.params) - 1
            deadline = time.monotonic() + setup.block_timeout_s
            while len(list(folder.glob("done-*"))) < n_other:
                if time.monotonic() > deadline:
                    raise RuntimeError("item 0 waited in vain: the other items were not taken by other devices")
                time.sleep(0.01)
        else:
            (folder / f"done-{item.index}").write_text(runner)
    return value, runner


def reduce(results: list[tuple[float, str]]) -> dict:
    """The float sum in the order fed, and who ran each item (not part of the compared value)."""
    total = 0.0
    for value, _ in results:
        total += value
    return {"sum": total, "values": [v for v, _ in results], "runners": [r for _, r in results]}


def make_job(n_items: int = 12, seed: int = 7, block_dir: str = "") -> Job:
    """``n_items`` items; item 0 first in the queue (highest cost), the rest in index order."""
    costs = [2.0] + [1.0] * (n_items - 1)
    return Job(make_items([n_items] * n_items, seed, costs=costs), run, reduce, context=OrderSetup(block_dir),
               name="order", uses_device=True)
