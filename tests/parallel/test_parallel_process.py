"""Work stealing and the process-per-device executor, on CPU devices.

Oracle: the one-device, one-thread run of the same job. Every other way of
running it -- 2 or 3 threads, 2 or 3 worker processes, items finishing in the
most shuffled order, a worker process killed in the middle of an item -- must
give the same value bit for bit (the float reductions here change with the
order of their additions, so an out-of-order fold would show).
"""
from __future__ import annotations

import argparse

import numpy as np
import pytest

import workload_mc_histogram as W
import workload_order as O
from lensrt.errors import LensrtError
from lensrt.parallel import Job, LocalExecutor, ProcessExecutor, WorkItem, make_items


@pytest.fixture(scope="module")
def order_reference() -> dict:
    return LocalExecutor("cpu").run(O.make_job(12)).value


@pytest.fixture(scope="module")
def procs():
    """Two worker processes on the CPU, shared by the tests of this module."""
    with ProcessExecutor("cpu,cpu") as ex:
        yield ex


def _check_stolen(value: dict, reference: dict) -> None:
    assert value["sum"] == reference["sum"] and value["values"] == reference["values"]
    runners = value["runners"]
    # item 0's device ran nothing else: the other devices took every other item from the queue
    assert runners[0] not in runners[1:]
    assert len(set(runners)) >= 2


def test_order_workload_really_depends_on_the_order(order_reference) -> None:
    values = order_reference["values"]
    backwards = 0.0
    for v in reversed(values):
        backwards += v
    rotated = 0.0
    for v in values[1:] + values[:1]:  # item 0 added last: the order it finishes in when blocked
        rotated += v
    assert backwards != order_reference["sum"] or rotated != order_reference["sum"]


@pytest.mark.parametrize("devices", ["cpu,cpu", "cpu,cpu,cpu"])
def test_threads_steal_work_and_fold_in_index_order(tmp_path, order_reference, devices) -> None:
    res = LocalExecutor(devices).run(O.make_job(12, block_dir=str(tmp_path)))
    _check_stolen(res.value, order_reference)
    assert res.duplicates == 0


@pytest.mark.parametrize("devices", ["cpu,cpu", "cpu,cpu,cpu"])
def test_processes_steal_work_and_fold_in_index_order(tmp_path, order_reference, devices) -> None:
    n = len(devices.split(","))
    with ProcessExecutor(devices) as ex:
        res = ex.run(O.make_job(12, block_dir=str(tmp_path)))
    _check_stolen(res.value, order_reference)
    assert len(set(res.item_workers)) == n  # every process ran items (hostname:pid)
    assert res.executor == f"processes ({devices.replace(',', ', ')})"


def test_two_processes_give_the_one_thread_psf_map(procs) -> None:
    reference = LocalExecutor("cpu").run(W.make_job(8))
    res = procs.run(W.make_job(8))
    assert np.array_equal(res.value["map"], reference.value["map"])
    assert np.array_equal(res.value["sum_of_unit_psfs"], reference.value["sum_of_unit_psfs"])
    assert res.n_items == 8 and res.duplicates == 0 and len(set(res.item_workers)) == 2
    # the processes stay up: a second job reuses them (no new process) and their prepared context
    again = procs.run(W.make_job(8))
    assert np.array_equal(again.value["map"], reference.value["map"])
    assert again.meta["processes_started"] == res.meta["processes_started"] == 2
    stats = procs_stats(procs)
    assert len(stats) == 2 and all(s["prepare_calls"] == 1 for s in stats)  # once per process, never per item or per job


def procs_stats(ex: ProcessExecutor) -> list[dict]:
    """Each worker process's prepared-context counters, read by running a host-only job on each."""
    out = {}
    for _ in range(20):  # items go to whichever process is free: ask until both have answered
        res = ex.run(Job(make_items([0] * 4), _stats, list, uses_device=False))
        out.update({s["pid"]: s for s in res.value})
        if len(out) == 2:
            break
    return list(out.values())


def _stats(item: WorkItem, context: object, device: str) -> dict:
    from lensrt.parallel import cache_stats
    return cache_stats()


def test_a_process_killed_mid_item_changes_nothing(tmp_path) -> None:
    """The first attempt of item 3 kills its worker process; the item re-runs on a new one."""
    marker = tmp_path / "killed"
    setup = W.HistogramSetup(kill_marker=str(marker))
    expect = LocalExecutor("cpu").run(W.make_job(8, setup=setup))
    with ProcessExecutor("cpu,cpu") as ex:
        res = ex.run(W.make_job(8, setup=setup, killing=True))
        assert marker.read_text().startswith("killed pid")  # a worker really died mid-item
        assert res.meta["processes_started"] == 3  # two, and one to replace the dead one
        assert np.array_equal(res.value["map"], expect.value["map"])
        assert np.array_equal(res.value["sum_of_unit_psfs"], expect.value["sum_of_unit_psfs"])
        assert res.n_items == 8 and res.duplicates == 0


def _always_dies(item: WorkItem, context: object, device: str) -> int:
    import os
    if item.index == 1:
        os._exit(9)
    return item.index


def _fail_on_two(item: WorkItem, context: object, device: str) -> int:
    if item.index == 2:
        raise LensrtError("item two is bad", hint="fix it")
    return item.index


def test_errors_reach_the_caller_and_the_executor_stays_usable(procs) -> None:
    with pytest.raises(LensrtError, match="item two is bad -- fix it"):
        procs.run(Job(make_items(range(6)), _fail_on_two, list, name="failing"))
    with pytest.raises(LensrtError, match="cannot be sent to a worker process"):
        procs.run(Job(make_items(range(2)), lambda item, ctx, dev: 1, list, name="lambda"))
    assert procs.run(Job(make_items(range(5)), _stats, list)).n_items == 5


def test_an_item_that_kills_every_process_stops_the_job() -> None:
    with ProcessExecutor("cpu", max_failures=2) as ex:
        with pytest.raises(LensrtError, match=r"item 1 of job 'deadly' killed 2 worker processes"):
            ex.run(Job(make_items(range(3)), _always_dies, list, name="deadly"))
        assert ex.run(Job(make_items(range(3)), _stats, list)).n_items == 3  # fresh processes serve the next job


def test_executor_option_builds_the_process_executor() -> None:
    from lensrt.commands._parallel import add_parallel_arguments, executor_from_args
    p = argparse.ArgumentParser()
    add_parallel_arguments(p)
    ex = executor_from_args(p.parse_args(["--devices", "cpu,cpu", "--executor", "process"]))
    assert isinstance(ex, ProcessExecutor) and ex.devices == ["cpu", "cpu"]
    ex.close()  # never started: nothing to stop
    with pytest.raises(LensrtError, match="--executor process starts its own worker processes"):
        executor_from_args(p.parse_args(["--executor", "process", "--workers", "2"]))


def test_psf_command_on_two_processes_equals_one_device(capsys) -> None:
    """`lensrt psf --executor process`: the same PSFs and estimates as the in-process run (only timings and
    the grouping of fields into items differ)."""
    import json

    from lensrt.cli import main
    argv = ["psf", "dgauss_50mm_f2", "--grid", "2x2", "--rays", "20000", "--pixels", "32", "--json"]
    assert main(argv + ["--devices", "cpu"]) == 0
    one = json.loads(capsys.readouterr().out)
    assert main(argv + ["--devices", "cpu,cpu", "--executor", "process"]) == 0
    two = json.loads(capsys.readouterr().out)
    assert two["run"]["executor"] == "processes (cpu, cpu)" and two["run"]["n_items"] == 4
    assert len(set(two["run"]["workers"])) == 2
    assert len(one["fields"]) == len(two["fields"]) == 4
    for a, b in zip(one["fields"], two["fields"]):
        assert _without_timings(a) == _without_timings(b)
        assert a["estimates"]["rms_radius_mm"]["value"] > 0  # real PSFs, not empty ones


def _without_timings(d: object) -> object:
    """A JSON value without its timings and run metadata (which differ from run to run)."""
    if isinstance(d, dict):
        return {k: _without_timings(v) for k, v in d.items() if k not in ("seconds", "metadata")}
    if isinstance(d, list):
        return [_without_timings(v) for v in d]
    return d


def test_a_worker_process_keeps_at_most_four_contexts() -> None:
    from lensrt.parallel.process import MAX_CONTEXTS
    with ProcessExecutor("cpu") as ex:
        for k in range(6):  # six jobs, six contexts
            job = O.make_job(3)
            job = Job(job.items, job.run, job.reduce, context=O.OrderSetup(block_timeout_s=float(k + 1)))
            assert ex.run(job).value["values"] == LocalExecutor("cpu").run(job).value["values"]
        stats = ex.run(Job(make_items([0]), _stats, list)).value[0]  # a seventh context: None
    assert stats["contexts_received"] == 7
    assert stats["contexts"] == MAX_CONTEXTS == 4


@pytest.mark.gpu
def test_every_gpu_in_its_own_process_gives_the_one_gpu_result() -> None:
    """On a CUDA machine: one worker process per GPU against cuda:0 alone in this process, bit for bit."""
    from lensrt.device import cuda_available
    if not cuda_available():
        pytest.skip("no CUDA device")
    job = W.make_job(12)
    one = LocalExecutor("cuda:0").run(job)
    with ProcessExecutor("all") as ex:
        every = ex.run(job)
    assert np.array_equal(every.value["map"], one.value["map"])
    assert np.array_equal(every.value["sum_of_unit_psfs"], one.value["sum_of_unit_psfs"])
    assert set(every.item_devices) <= {f"cuda:{k}" for k in range(len(ex.devices))}


@pytest.mark.slow  # 46 s on the loaded 2-core machine (two processes compile/load the render kernels)
@pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")
def test_render_tiles_on_two_processes_equal_one_device() -> None:
    """A fixed-sample render as row-band tiles on two worker processes: the image bits of the one-device
    render in this process (the render's own tests do the same with threads)."""
    import dataclasses

    from lensrt.render.integrator import render
    from lensrt.render.scene.load import load_scene
    from lensrt.render.setup import RenderOptions
    scene = load_scene("default")
    opts = RenderOptions(width=48, samples_per_pixel=6, spp_per_pass=2, device="cpu")
    a = render(scene, options=opts)
    with ProcessExecutor("cpu,cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex)
    assert b.executor_items == "tiles" and b.executor_item_count == 6
    for f in ("irradiance", "xyz", "xyz_stderr"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert b.samples == a.samples and b.through.value == a.through.value


def test_a_script_without_the_main_guard_gets_one_clear_error(tmp_path) -> None:
    """Spawned workers import the main module: a script that starts the executor at top level makes each
    worker try to start processes of its own and die. The parent says so, instead of retrying items."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    script = tmp_path / "no_guard.py"
    script.write_text(
        "import sys\n"
        f"sys.path[:0] = [{str(root)!r}, {str(root / 'tests' / 'oracles')!r}]\n"
        "import workload_order as O\n"
        "from lensrt.errors import LensrtError\n"
        "from lensrt.parallel import ProcessExecutor\n"
        "try:\n"
        "    with ProcessExecutor('cpu') as ex:\n"
        "        ex.run(O.make_job(2))\n"
        "except LensrtError as err:\n"
        "    print('ERROR', err)\n"
        "    sys.exit(3)\n")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 3, out.stderr[-2000:]
    assert "ERROR the worker process for cpu did not start (exit code 1)" in out.stdout
    assert "if __name__ == '__main__':" in out.stdout
