"""TEST WORKLOAD -- not part of lensrt: a tiny Monte Carlo Warp job that stands in for a PSF map.

Used by tests/test_parallel*.py and by benchmarks/bench_multigpu.py (``--workload
mc-histogram``) until the real PSF map and render land. Each work item is one
field point h in [0, 1]: rays uniform over a unit pupil (px, py) get the
third-order transverse aberration of defocus plus coma growing with field,

    x = d px + 2 c h px py,    y = d py + c h (px^2 + 3 py^2),

and are streamed into a square image-plane histogram with *integer* atomics,
so each item's histogram is deterministic whatever the thread order. The
reduction stacks the histograms in item order (the "PSF map") and also sums
the unit-volume PSFs in float64 in item order -- a float reduction whose
bit-identity across executors the tests check.

The context counts how often it is unpickled in each process (``UNPICKLED``),
so a test can see that it was shipped once per worker, not once per item.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no greeting on stdout (Warp >= 1.10)

from lensrt.parallel import Job, WorkItem, make_items
from lensrt.parallel.workloads import parse_size

UNPICKLED = 0  # times a HistogramSetup was unpickled in this process


@dataclass(frozen=True)
class HistogramSetup:
    """The shared context: histogram geometry and aberration scale (mm), samples per item."""

    n_bins: int = 24
    half_width_mm: float = 0.05
    defocus_mm: float = 0.01
    coma_mm: float = 0.015
    samples_per_item: int = 20000
    kill_marker: str = ""  # fault test: the first item to see this file missing kills its worker
    host_loops: int = 0  # pure-Python iterations per item (host work that holds the GIL; changes no number)

    def __setstate__(self, state: dict) -> None:
        global UNPICKLED
        UNPICKLED += 1
        for k, v in state.items():
            object.__setattr__(self, k, v)


@wp.kernel
def mc_histogram_kernel(seed: int, defocus: float, coma: float, half_width: float, inv_bin: float,
                        n_bins: int, hist: wp.array(dtype=wp.int32)):
    tid = wp.tid()
    state = wp.rand_init(seed, tid)
    r = wp.sqrt(wp.randf(state))
    phi = 6.283185307179586 * wp.randf(state)
    px = r * wp.cos(phi)
    py = r * wp.sin(phi)
    x = defocus * px + 2.0 * coma * px * py
    y = defocus * py + coma * (px * px + 3.0 * py * py)
    ix = int(wp.floor((x + half_width) * inv_bin))
    iy = int(wp.floor((y + half_width) * inv_bin))
    if ix >= 0 and ix < n_bins and iy >= 0 and iy < n_bins:
        wp.atomic_add(hist, iy * n_bins + ix, 1)


def prepare(setup: HistogramSetup, device: str) -> HistogramSetup:
    """Once per process and device: load the Warp module there (read-only result, shared by threads)."""
    wp.load_module(device=device)
    return setup


def run(item: WorkItem, setup: HistogramSetup, device: str) -> np.ndarray:
    """One field point: the (n_bins, n_bins) int64 histogram of ``samples_per_item`` rays."""
    n = setup.n_bins
    _host_work(setup.host_loops)
    hist = wp.zeros(n * n, dtype=wp.int32, device=device)
    wp.launch(mc_histogram_kernel, dim=setup.samples_per_item,
              inputs=[item.seed, setup.defocus_mm, setup.coma_mm * float(item.params), setup.half_width_mm,
                      n / (2.0 * setup.half_width_mm), n, hist], device=device)
    return hist.numpy().reshape(n, n).astype(np.int64)


def _host_work(loops: int) -> int:
    """Stand-in for an item's host share (set-up, analysis): a pure-Python loop, GIL held throughout."""
    acc = 0
    for i in range(loops):
        acc ^= i
    return acc


def run_killing_once(item: WorkItem, setup: HistogramSetup, device: str) -> np.ndarray:
    """Like :func:`run`, but the first item to find ``setup.kill_marker`` missing creates it and kills
    its own worker process (mid-task, result never sent)."""
    marker = Path(setup.kill_marker)
    if item.index == 3 and not marker.exists():
        marker.write_text(f"killed pid {os.getpid()}\n")
        os._exit(17)
    return run(item, setup, device)


def reduce(results: list[np.ndarray]) -> dict[str, Any]:
    """The map (items in order) and the float64 sum of unit-volume PSFs, added in item order."""
    total = np.zeros_like(results[0], dtype=np.float64)
    for h in results:
        total += h / max(int(h.sum()), 1)
    return {"map": np.stack(results), "sum_of_unit_psfs": total}


def make_job(n_items: int = 6, seed: int = 1234, setup: HistogramSetup | None = None,
             killing: bool = False) -> Job:
    setup = setup or HistogramSetup()
    fields = np.linspace(0.0, 1.0, n_items)
    return Job(make_items(fields, seed), run_killing_once if killing else run, reduce, context=setup,
               prepare=prepare, name="mc-histogram")


def workload(size: str, seed: int) -> Job:
    """Benchmark factory (``--workload mc-histogram``): sizes tiny / small / large or key=value."""
    p = parse_size(size, {"tiny": {"items": 8, "samples": 20000, "bins": 24, "host_loops": 0},
                          "small": {"items": 32, "samples": 1 << 20, "bins": 64, "host_loops": 0},
                          "large": {"items": 256, "samples": 1 << 26, "bins": 128, "host_loops": 0}})
    return make_job(p["items"], seed, HistogramSetup(n_bins=p["bins"], samples_per_item=p["samples"],
                                                     host_loops=p["host_loops"]))


def worker_stats() -> dict:
    """This process's unpickle count and prepared-context counters (for ``client.run``)."""
    from lensrt.parallel import cache_stats
    return {"unpickled": UNPICKLED, **cache_stats()}
