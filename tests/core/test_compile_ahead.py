"""Warp modules compiled ahead of their first launch in background threads (lensrt.core.compile_ahead).

Each test makes a kernel in a fresh Warp module (``module="unique"`` inside the test), so that the
module starts unloaded in this process; the kernel's output is the oracle that the launch ran the
right code, whoever compiled it.
"""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from lensrt.core import compile_ahead
from lensrt.core.telemetry import launch
from lensrt.device import warp


def _fresh_kernel(scale: float):
    """A kernel ``out[i] = scale * i`` in a Warp module of its own (not loaded yet)."""
    wp = warp()

    @wp.kernel(module="unique", enable_backward=False)
    def times_index(out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        out[i] = wp.float64(scale) * wp.float64(i)

    return times_index


def _run(kernel, n: int = 5) -> np.ndarray:
    wp = warp()
    out = wp.zeros(n, dtype=wp.float64, device="cpu")
    launch(kernel, dim=n, inputs=[out], device="cpu")
    return out.numpy()


def test_a_preloaded_module_is_loaded_before_its_first_launch_and_runs_right():
    k = _fresh_kernel(3.0)
    job = compile_ahead.start([k.module], "cpu")
    loads = job.wait()
    assert [(ld.name, ld.device, ld.error, ld.skipped) for ld in loads] == [(k.module.name, "cpu", None, False)]
    assert any(ctx is None for ctx, _ in k.module.execs)  # loaded on the CPU by the preload
    assert job.done and compile_ahead.pending() == []
    np.testing.assert_array_equal(_run(k), 3.0 * np.arange(5))


def test_preloading_twice_is_harmless():
    k = _fresh_kernel(2.0)
    first = compile_ahead.start([k.module, k.module], "cpu")  # a module listed twice loads once
    second = compile_ahead.start([k.module], "cpu")  # while the first may still be loading
    assert len(first.loads) == 1
    first.wait()
    second.wait()
    assert second.loads[0].skipped and second.loads[0].error is None
    third = compile_ahead.start([k.module], "cpu")  # loaded: nothing to do
    assert third.wait()[0].skipped
    np.testing.assert_array_equal(_run(k), 2.0 * np.arange(5))


def test_a_failed_preload_falls_back_to_compiling_on_first_use(monkeypatch):
    wp = warp()
    k = _fresh_kernel(5.0)

    def broken(*args, **kwargs):
        raise RuntimeError("no compiler today")

    monkeypatch.setattr(wp, "force_load", broken)
    loads = compile_ahead.start([k.module], "cpu").wait()
    assert "no compiler today" in loads[0].error
    assert not k.module.execs  # nothing loaded by the failed preload
    monkeypatch.undo()
    np.testing.assert_array_equal(_run(k), 5.0 * np.arange(5))  # compiled by the launch itself


def test_a_launch_waits_for_its_module_still_loading_instead_of_compiling_it_again(monkeypatch):
    wp = warp()
    k = _fresh_kernel(7.0)
    events: list[str] = []
    real_force_load, real_launch = wp.force_load, wp.launch
    started = threading.Event()

    def slow_force_load(*args, **kwargs):
        started.set()
        time.sleep(0.5)  # the launch below comes while this load is under way
        real_force_load(*args, **kwargs)
        events.append("preload done")

    def spy_launch(kernel, *args, **kwargs):
        events.append("launch")
        return real_launch(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "force_load", slow_force_load)
    monkeypatch.setattr(wp, "launch", spy_launch)
    job = compile_ahead.start([k.module], "cpu")
    assert started.wait(30)
    values = _run(k)
    job.wait()
    assert events == ["preload done", "launch"]
    assert job.loads[0].waited_s > 0.0  # the launch did wait (how long is not asserted)
    np.testing.assert_array_equal(values, 7.0 * np.arange(5))


def test_the_worker_count_can_be_set_and_is_checked(monkeypatch):
    from lensrt.errors import LensrtError
    monkeypatch.setenv("LENSRT_COMPILE_WORKERS", "3")
    assert compile_ahead.default_workers() == 3
    monkeypatch.setenv("LENSRT_COMPILE_WORKERS", "three")
    with pytest.raises(LensrtError, match="LENSRT_COMPILE_WORKERS"):
        compile_ahead.default_workers()
    monkeypatch.delenv("LENSRT_COMPILE_WORKERS")
    assert 1 <= compile_ahead.default_workers() <= compile_ahead.MAX_WORKERS


def test_slices_launched_on_several_threads_compile_their_module_once(monkeypatch):
    """Without a preload, the first launch loads the module under a lock: the slices of one launch on
    several CPU threads (the stream and pupil-box kernels) wait for it instead of each compiling it."""
    wp = warp()
    k = _fresh_kernel(11.0)
    loads: list[str] = []
    real_force_load = wp.force_load

    def slow_force_load(*args, **kwargs):
        loads.append("load")
        time.sleep(0.5)  # the other threads arrive while this one loads
        real_force_load(*args, **kwargs)

    monkeypatch.setattr(wp, "force_load", slow_force_load)
    out = wp.zeros(8, dtype=wp.float64, device="cpu")
    gate = threading.Barrier(4)

    def slice_launch(w: int) -> None:
        gate.wait()
        launch(k, dim=8, inputs=[out], device="cpu", slice_of=w)  # as lensrt's CPU slices do (each writes all)

    threads = [threading.Thread(target=slice_launch, args=(w,)) for w in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert loads == ["load"]
    np.testing.assert_array_equal(out.numpy(), 11.0 * np.arange(8))


def test_a_module_still_queued_is_loaded_by_its_launch_not_after_the_modules_queued_before_it(monkeypatch):
    """One compiling thread, two modules: while the first is loading, a launch of the second (still queued in
    the pool) takes its load over on the launching thread instead of waiting for the first."""
    wp = warp()
    long_k, needed_k = _fresh_kernel(13.0), _fresh_kernel(17.0)  # scales of no other test: new modules
    real_force_load = wp.force_load
    started, release = threading.Event(), threading.Event()
    loaded_by: dict[str, str] = {}

    def force_load(*args, modules=(), **kwargs):
        if modules[0] is long_k.module:
            started.set()
            release.wait(20)  # the long compile: not over before the launch below has run
        loaded_by[modules[0].name] = threading.current_thread().name
        real_force_load(*args, modules=modules, **kwargs)

    monkeypatch.setattr(wp, "force_load", force_load)
    job = compile_ahead.start([long_k.module, needed_k.module], "cpu", workers=1)
    assert started.wait(30)
    values = _run(needed_k)
    long_done = bool(loaded_by.get(long_k.module.name)) and not release.is_set()
    release.set()
    loads = job.wait()
    assert loaded_by[needed_k.module.name] == threading.current_thread().name  # taken over by the launch
    assert not long_done  # ... while the first module was still loading
    assert [(ld.name, ld.error) for ld in loads] == [(long_k.module.name, None), (needed_k.module.name, None)]
    assert compile_ahead.pending() == []
    np.testing.assert_array_equal(values, 17.0 * np.arange(5))
    np.testing.assert_array_equal(_run(long_k), 13.0 * np.arange(5))
