"""Telemetry: kernel launches, host<->device copies and seconds of a piece of work.

lensrt's own code launches kernels through :func:`launch`, uploads NumPy arrays through :func:`upload`
and downloads through :func:`download`; :func:`measure` counts them while it is open::

    from lensrt.core.telemetry import measure
    with measure() as rec:
        trace(lens, rays, device="cpu")
    rec.launches, rec.copies, rec.kernel_s, rec.wall_s

``kernel_s`` is the time the kernels ran: on CUDA the sum of the CUDA-event intervals around each
launch (read back when :func:`measure` closes); on the CPU the wall time each launch call took. A launch
that lensrt splits into slices on several CPU cores counts once, timed by its first slice (the slices
run side by side), so ``launches`` is the same on every machine for the same work.
Records nest: every open record counts what happens inside it. Counting is thread-safe.
Only lensrt's own launches and copies are counted (those of Warp itself or of a user's code are not).
"""
from __future__ import annotations

import threading
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from typing import Any, Iterator

from .compile_ahead import wait_for

__all__ = ["Telemetry", "measure", "snapshot", "launch", "launch_slices", "replay", "upload", "download",
           "count_copy"]

_LOCK = threading.Lock()
_OPEN: list["Telemetry"] = []


@dataclass(eq=False)
class Telemetry:
    """What a :func:`measure` block did: wall seconds, kernel seconds, kernel launches, host<->device copies."""

    wall_s: float = 0.0
    kernel_s: float = 0.0
    launches: int = 0
    copies: int = 0
    #: perf_counter() when the block opened
    _t0: float = field(default=0.0, repr=False)
    #: (start, end) CUDA events of the launches, turned into kernel_s when the block closes
    _events: list = field(default_factory=list, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """``{wall_s, kernel_s, launches, copies}`` (JSON-ready)."""
        d = asdict(self)
        d.pop("_events")
        d.pop("_t0")
        return d

    @property
    def busy(self) -> float:
        """kernel_s / wall_s (0 when nothing ran)."""
        return self.kernel_s / self.wall_s if self.wall_s > 0.0 else 0.0


@contextmanager
def measure() -> Iterator[Telemetry]:
    """Count launches and copies and time the block; yields the :class:`Telemetry` it fills in."""
    rec = Telemetry(_t0=time.perf_counter())
    with _LOCK:
        _OPEN.append(rec)
    try:
        yield rec
    finally:
        with _LOCK:
            _OPEN[:] = [r for r in _OPEN if r is not rec]
        rec.kernel_s += _event_seconds(rec._events)
        rec._events = []
        rec.wall_s = time.perf_counter() - rec._t0


def snapshot() -> dict[str, Any] | None:
    """The outermost open record so far (``{wall_s, kernel_s, launches, copies}``), or None when none is open.

    The CLI opens one around each command, so that a ``--json`` result can say what its command cost.
    """
    with _LOCK:
        if not _OPEN:
            return None
        rec = _OPEN[0]
        events = list(rec._events)
        out = {"wall_s": 0.0, "kernel_s": rec.kernel_s, "launches": rec.launches, "copies": rec.copies}
    out["kernel_s"] += _event_seconds(events)
    out["wall_s"] = time.perf_counter() - rec._t0
    return out


def _event_seconds(events: list) -> float:
    """Sum of the CUDA-event intervals (s); waits for the last ones to finish."""
    if not events:
        return 0.0
    import warp as wp
    wp.synchronize_event(events[-1][1])
    return sum(wp.get_event_elapsed_time(a, b, synchronize=False) for a, b in events) * 1e-3


def _add(launches: int = 0, copies: int = 0, kernel_s: float = 0.0, events: tuple | None = None) -> None:
    with _LOCK:
        for rec in _OPEN:
            rec.launches += launches
            rec.copies += copies
            rec.kernel_s += kernel_s
            if events is not None:
                rec._events.append(events)


def count_copy(n: int = 1) -> None:
    """Count ``n`` host<->device copies made outside :func:`upload` / :func:`download`."""
    if _OPEN:
        _add(copies=n)


def launch(kernel, dim, inputs=(), *, device=None, slice_of: int = 0, **kwargs) -> None:
    """``wp.launch`` with counting (same arguments; ``device`` as Warp takes it).

    ``slice_of``: where this slice starts (first thread id) when one logical launch runs as slices on several
    CPU cores; only the slice that starts at 0 counts (a launch and its wall time), so that launch counts do not depend on the core count.
    """
    import warp as wp
    wait_for(kernel, device, kwargs.get("block_dim"))  # its module loaded once (or by a preload): compile_ahead
    if not _OPEN or slice_of:
        wp.launch(kernel, dim=dim, inputs=list(inputs), device=device, **kwargs)
        return
    dev = wp.get_device(device)
    if dev.is_cuda:
        start, end = wp.Event(dev, enable_timing=True), wp.Event(dev, enable_timing=True)
        stream = kwargs.get("stream") or dev.stream
        stream.record_event(start)
        wp.launch(kernel, dim=dim, inputs=list(inputs), device=device, **kwargs)
        stream.record_event(end)
        _add(launches=1, events=(start, end))
        return
    t0 = time.perf_counter()
    wp.launch(kernel, dim=dim, inputs=list(inputs), device=device, **kwargs)
    _add(launches=1, kernel_s=time.perf_counter() - t0)


def launch_slices(kernel, cuts, device, inputs_of) -> None:
    """One logical launch cut into slices of threads ``cuts[w]`` .. ``cuts[w + 1] - 1`` (one per CPU core): slice w
    launched with ``inputs_of(w, cuts[w])`` (:func:`launch`, ``slice_of=cuts[w]``), the slices side by side in
    threads; a single slice in the calling thread. Empty slices are skipped."""
    from concurrent.futures import ThreadPoolExecutor

    def run(w: int) -> None:
        if cuts[w + 1] > cuts[w]:
            launch(kernel, dim=cuts[w + 1] - cuts[w], device=device, inputs=inputs_of(w, cuts[w]), slice_of=cuts[w])

    if len(cuts) <= 2:
        run(0)
    else:
        with ThreadPoolExecutor(len(cuts) - 1) as pool:
            list(pool.map(run, range(len(cuts) - 1)))


def replay(cmd, *, slice_of: int = 0) -> None:
    """``cmd.launch()`` of a launch recorded with ``wp.launch(..., record_cmd=True)`` (its arguments packed once,
    replayed with only the changed ones set again), counted as :func:`launch` counts a launch."""
    import warp as wp
    if not _OPEN or slice_of:
        cmd.launch()
        return
    dev = cmd.device
    if dev.is_cuda:
        start, end = wp.Event(dev, enable_timing=True), wp.Event(dev, enable_timing=True)
        stream = dev.stream
        stream.record_event(start)
        cmd.launch()
        stream.record_event(end)
        _add(launches=1, events=(start, end))
        return
    t0 = time.perf_counter()
    cmd.launch()
    _add(launches=1, kernel_s=time.perf_counter() - t0)


def upload(host, dtype, device, **kwargs):
    """``wp.array(host, dtype=dtype, device=device)`` from a NumPy array, counted as one copy."""
    import warp as wp
    count_copy()
    return wp.array(host, dtype=dtype, device=device, **kwargs)


def download(arr):
    """``arr.numpy()``, counted as one copy."""
    count_copy()
    return arr.numpy()
