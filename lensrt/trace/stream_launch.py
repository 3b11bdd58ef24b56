"""Host side of the stream kernels, in steps: plan the slots, build the device tables, launch, fold.

:func:`lensrt.trace.stream.stream` validates its arguments and calls these in turn; the
contracts (slots, replicas, determinism) are in :mod:`lensrt.trace.kernels`.
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..errors import LensrtError
from .kernels import N_COUNTS, N_RECORD, N_STATS
from ..core.telemetry import launch, upload

__all__ = ["EPOCH_RAYS", "SLOTS_MAX", "SLOT_MIN_RAYS", "LAUNCH_SLOTS", "StreamPlan", "slot_layout", "plan_slots",
           "device_tables", "launch_all", "cpu_count"]

#: rays of one epoch (slots never straddle a change of epoch)
EPOCH_RAYS = 1 << 30
#: slots (one thread each: a contiguous run of rays of one source and batch) per batch: at most
#: SLOTS_MAX, of at least SLOT_MIN_RAYS rays (a power of two) -- a function of the rays per batch only
SLOTS_MAX = 8192
SLOT_MIN_RAYS = 64
#: slots per launch (all sources and batches) at most, per device kind: the per-slot sums take
#: 128 bytes each
LAUNCH_SLOTS = {"gpu": 1 << 20, "cpu": 1 << 16}


def cpu_count() -> int:
    """The CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def slot_layout(rays_per_batch: int, threads_per_batch: int | None = None) -> tuple[int, int]:
    """(rays per slot, slots per batch) of a stream (:mod:`.kernels`): a function of the rays per batch
    only -- at most :data:`SLOTS_MAX` slots of at least :data:`SLOT_MIN_RAYS` rays, a power of two --
    unless ``threads_per_batch`` fixes the number of slots."""
    n_b = int(rays_per_batch)
    if threads_per_batch is not None:
        per = max(1, -(-n_b // max(1, min(int(threads_per_batch), n_b))))
    else:
        per = max(SLOT_MIN_RAYS, 1 << max(0, (-(-n_b // SLOTS_MAX) - 1).bit_length()))
    if n_b > EPOCH_RAYS:  # slots must not straddle a change of epoch (2^30 rays)
        per = min(1 << max(0, (per - 1).bit_length()), EPOCH_RAYS)
    return per, -(-n_b // per)


@dataclass(frozen=True)
class StreamPlan:
    """How a stream call's rays are cut: S sources x B batches of n_b rays, in slots of
    ``slot_rays`` (``n_slots`` per batch), ``per_launch`` slots per batch per launch; the
    histogram's layers, batches (``hb``), channels and replicas."""

    S: int
    B: int
    n_b: int
    slot_rays: int
    n_slots: int
    per_launch: int
    layers: int
    hb: int
    n_chan: int
    replicas: int
    is_gpu: bool
    plane: int

    @property
    def hist_len(self) -> int:
        return self.replicas * self.bins

    @property
    def bins(self) -> int:
        """Bins of one replica: layers x batches x channels x plane."""
        return self.layers * self.hb * self.n_chan * self.plane


def replica_budget_mb() -> int:
    """GPU memory (MiB) the histogram replicas of one stream may take: ``LENSRT_REPLICA_MB``, else 256."""
    raw = os.environ.get("LENSRT_REPLICA_MB", "256")
    try:
        mb = int(raw)
    except ValueError:
        raise LensrtError(f"LENSRT_REPLICA_MB={raw!r} is not a whole number of MiB",
                          hint="set it to e.g. 256 or 2048, or unset it") from None
    if mb < 1:
        raise LensrtError(f"LENSRT_REPLICA_MB={mb} must be at least 1")
    return mb


def plan_slots(S: int, B: int, n_b: int, plane: int, layers: int, n_chan: int, is_gpu: bool, *,
               batch_histograms: bool, threads_per_batch: int | None, replicas: int | None,
               cpu_workers: int | None, rays_per_launch: int | None) -> StreamPlan:
    """Slots, histogram replicas and the slots per launch (module docstring of :mod:`.kernels`)."""
    slot_rays, n_slots = slot_layout(n_b, threads_per_batch)
    hb = B if batch_histograms else 1
    if is_gpu:
        if replicas is None:
            replicas = max(1, min(16, (replica_budget_mb() << 20) // max(8 * plane * layers * n_chan * hb, 1)))
    else:  # Warp's CPU atomics are plain adds: one histogram replica per worker thread
        replicas = max(1, int(cpu_workers or cpu_count()))
    if rays_per_launch is None:
        rays_per_launch = (1 << 30) if is_gpu else (1 << 22)
    cap = LAUNCH_SLOTS["gpu" if is_gpu else "cpu"]
    per_launch = max(1, min(int(rays_per_launch) // (S * B * slot_rays), cap // (S * B)))
    per_launch = min(per_launch, n_slots, max(1, EPOCH_RAYS // slot_rays))
    plan = StreamPlan(S, B, n_b, slot_rays, n_slots, per_launch, layers, hb, n_chan, int(replicas), is_gpu, plane)
    if plan.hist_len >= 2**31:
        raise LensrtError(f"histogram of {plan.hist_len} bins is too large (limit 2^31)")
    return plan


def device_tables(wp: Any, dev: str, precision: str, plan: StreamPlan, rows: np.ndarray, src_int: np.ndarray,
                  nm: np.ndarray, cdf: np.ndarray, table: np.ndarray, chan: np.ndarray) -> SimpleNamespace:
    """The kernels' arrays on ``dev``: sources, spectra, index and channel tables, the histogram,
    the per-slot sums of one launch and their running totals."""
    from .kernels.stream_body import source_array
    real = wp.float64 if precision == "float64" else wp.float32
    max_threads = plan.S * plan.B * plan.per_launch
    return SimpleNamespace(
        src=source_array(rows, precision, dev), src_int=upload(src_int, wp.int32, dev),
        spec_nm=upload(nm, real, dev), spec_cdf=upload(cdf, real, dev),
        table=upload(table, real, dev), chan=upload(chan, real, dev),
        hist=wp.zeros(plan.hist_len, dtype=wp.int64, device=dev),
        stats=wp.zeros((max_threads, N_STATS), dtype=wp.float64, device=dev),
        counts=wp.zeros((max_threads, N_COUNTS), dtype=wp.int64, device=dev),
        tot_stats=wp.zeros((plan.S * plan.B, N_STATS), dtype=wp.float64, device=dev),
        tot_counts=wp.zeros((plan.S * plan.B, N_COUNTS), dtype=wp.int64, device=dev),
        rec=wp.zeros((1, 1, N_RECORD), dtype=real, device=dev))


def _histogram(sb: Any, t: SimpleNamespace, plan: StreamPlan, nx: int, ny: int) -> Any:
    h = sb.Histogram()
    h.bins, h.nx, h.ny, h.n_layers = t.hist, int(nx), int(ny), plan.layers
    h.n_rep, h.batches, h.n_chan = 1 if not plan.is_gpu else plan.replicas, plan.hb, plan.n_chan
    return h


def _slots(sb: Any, plan: StreamPlan, epoch: int, ns: int, local: int, count: int, strata: tuple[int, int],
           tid_base: int, rep_base: int) -> Any:
    sl = sb.Slots()
    sl.epoch, sl.n_batches, sl.n_slots, sl.slot_rays = int(epoch), plan.B, int(ns), plan.slot_rays
    sl.start, sl.count, sl.n_wstrata, sl.n_strata = int(local), int(count), int(strata[0]), int(strata[1])
    sl.tid_base, sl.rep_base = int(tid_base), int(rep_base)
    return sl


def launch_all(wp: Any, dev: str, plan: StreamPlan, t: SimpleNamespace, nx: int, ny: int, strata: tuple[int, int],
               kernel: Any, head: list, after: list, fold: Any, sum_replicas: Any) -> tuple[Any, int, float]:
    """Launch ``kernel`` (arguments ``head``, then ``Histogram``, ``Slots``, the slot sums, ``after``)
    over all slots, launch by launch, folding each launch's slot sums into the totals in slot order;
    returns the histogram (replicas summed), the number of launches and the kernels' seconds."""
    from .kernels import stream_body as sb
    h = _histogram(sb, t, plan, nx, ny)
    pool = ThreadPoolExecutor(plan.replicas) if (not plan.is_gpu and plan.replicas > 1) else None
    if plan.is_gpu:
        ev0, ev1 = wp.Event(dev, enable_timing=True), wp.Event(dev, enable_timing=True)
        wp.get_stream(dev).record_event(ev0)
    t0 = time.perf_counter()
    launches, start = 0, 0
    try:
        while start < plan.n_b:
            epoch, local = divmod(start, EPOCH_RAYS)
            count = min(plan.per_launch * plan.slot_rays, plan.n_b - start, EPOCH_RAYS - local)
            ns = -(-count // plan.slot_rays)
            n_threads = plan.S * plan.B * ns
            workers = 1 if plan.is_gpu else max(1, min(plan.replicas, n_threads))
            bounds = [n_threads * w // workers for w in range(workers + 1)]

            def run(w: int) -> None:
                sl = _slots(sb, plan, epoch, ns, local, count, strata, bounds[w], 0 if plan.is_gpu else w)
                launch(kernel, dim=bounds[w + 1] - bounds[w], device=dev,
                       inputs=head + [h, sl, t.stats, t.counts] + after, slice_of=bounds[w])

            if pool is None or workers == 1:
                run(0)
            else:
                list(pool.map(run, range(workers)))
            launches += 1
            # the launch's slots added to the totals, in slot order (kernels.fold_slots)
            launch(fold, dim=plan.S * plan.B * (N_STATS + N_COUNTS), device=dev,
                   inputs=[t.stats, t.counts, ns, t.tot_stats, t.tot_counts])
            start += count
        out = t.hist
        if plan.replicas > 1:
            out = wp.empty(plan.bins, dtype=wp.int64, device=dev)
            launch(sum_replicas, dim=plan.bins, device=dev, inputs=[t.hist, plan.replicas, plan.bins, out])
        if plan.is_gpu:
            wp.get_stream(dev).record_event(ev1)
    finally:
        if pool is not None:
            pool.shutdown()
    seconds = wp.get_event_elapsed_time(ev0, ev1) * 1e-3 if plan.is_gpu else time.perf_counter() - t0
    return out, launches, seconds

