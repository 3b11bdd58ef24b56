"""lensrt.parallel without Dask: seeds, the in-order fold, the prepared-context cache, and the
one-thread-per-device executor on a real (tiny) Warp Monte Carlo job."""
from __future__ import annotations

import argparse
import math
import random

import numpy as np
import pytest

import workload_mc_histogram as W
from lensrt.errors import LensrtError
from lensrt.parallel import (ItemOutcome, Job, ListReduction, LocalExecutor, OrderedFold, WorkItem, cache_stats,
                             clear_cache, content_hash, item_seed_sequence, make_items, resolve_devices)


# ---- seeds ---------------------------------------------------------------------------------

def test_item_seeds_are_the_spawned_children_and_do_not_depend_on_the_item_count() -> None:
    children = np.random.SeedSequence(42).spawn(10)
    for i, child in enumerate(children):
        mine = item_seed_sequence(42, i)
        assert np.array_equal(mine.generate_state(4), child.generate_state(4))
    few, many = make_items(range(3), 42), make_items(range(300), 42)
    assert [it.seed for it in few] == [it.seed for it in many[:3]]
    seeds = [it.seed for it in many]
    assert len(set(seeds)) == len(seeds)
    assert all(0 <= s < 2 ** 31 for s in seeds)
    assert make_items(range(3), 43)[0].seed != few[0].seed
    a, b = few[1].rng().standard_normal(5), make_items(range(3), 42)[1].rng().standard_normal(5)
    assert np.array_equal(a, b)


def test_job_items_must_be_indexed_in_order() -> None:
    with pytest.raises(ValueError, match="indexed 0..n-1"):
        Job((WorkItem(1), WorkItem(0)), W.run, W.reduce)
    job = Job(make_items([0, 1, 2], costs=[1, 5, 2]), W.run, W.reduce)
    assert job.schedule_order() == [1, 2, 0]


# ---- the in-order fold -----------------------------------------------------------------------

class _FloatSum:
    """A Reduction whose float result depends on the order of additions."""

    def start(self) -> list:
        return [0.0, []]

    def add(self, acc: list, index: int, result: float) -> list:
        acc[0] += result
        acc[1].append(index)
        return acc

    def finish(self, acc: list) -> tuple:
        return acc[0], tuple(acc[1])


def test_fold_is_in_index_order_whatever_the_arrival_order_and_drops_duplicates() -> None:
    rng = random.Random(3)
    values = [10.0 ** rng.randint(-8, 8) * rng.random() for _ in range(40)]
    expect = 0.0
    for v in values:
        expect += v
    shuffled_sums = set()
    for trial in range(5):
        order = list(range(40)) + [rng.randrange(40) for _ in range(15)]  # 15 duplicate deliveries
        rng.shuffle(order)
        fold = OrderedFold(_FloatSum(), 40)
        kept = [fold.add(ItemOutcome(i, values[i], 0.0, "cpu")) for i in order]
        total, indices = fold.finish()
        assert total == expect  # bit-identical: same additions, same order
        assert indices == tuple(range(40))
        assert fold.duplicates == 15 and sum(kept) == 40
        shuffled = 0.0
        for i in order:
            shuffled += values[i]
        shuffled_sums.add(shuffled)
    assert any(s != expect for s in shuffled_sums)  # the order really matters for these floats


def test_fold_reports_missing_items_and_rejects_foreign_indices() -> None:
    fold = OrderedFold(ListReduction(list), 3)
    fold.add(ItemOutcome(0, "a", 0.0, "cpu"))
    fold.add(ItemOutcome(2, "c", 0.0, "cpu"))
    assert fold.done == 1 and fold.received == 2
    with pytest.raises(RuntimeError, match=r"1 item\(s\) never came back \(first: \[1\]\)"):
        fold.finish()
    with pytest.raises(ValueError):
        fold.add(ItemOutcome(3, "d", 0.0, "cpu"))
    fold.add(ItemOutcome(1, "b", 0.0, "cpu"))
    assert fold.finish() == ["a", "b", "c"]


# ---- devices ---------------------------------------------------------------------------------

def test_resolve_devices() -> None:
    from lensrt.device import cuda_available
    assert resolve_devices("cpu") == ["cpu"]
    assert resolve_devices("cpu, cpu") == ["cpu", "cpu"]
    assert resolve_devices(["cpu"]) == ["cpu"]
    if not cuda_available():
        assert resolve_devices("all") == ["cpu"]
        assert resolve_devices(None) == ["cpu"]
        with pytest.raises(LensrtError, match="Warp sees 0 CUDA"):
            resolve_devices("cuda:1")
    with pytest.raises(LensrtError, match="unknown device"):
        resolve_devices("tpu")
    with pytest.raises(LensrtError, match="empty device list"):
        resolve_devices(" , ")


# ---- the local executor on the Monte Carlo test workload --------------------------------------

@pytest.fixture(scope="module")
def reference():
    """The single-device, single-thread result of the 6-item job."""
    return LocalExecutor("cpu").run(W.make_job(6))


def test_histogram_workload_is_a_sane_monte_carlo_psf(reference) -> None:
    setup = W.HistogramSetup()
    psf_map = reference.value["map"]
    assert psf_map.shape == (6, setup.n_bins, setup.n_bins) and psf_map.dtype == np.int64
    # on axis (h = 0): a uniform disc of radius d = defocus, all inside the histogram
    h0 = psf_map[0]
    assert h0.sum() == setup.samples_per_item
    half, n = setup.half_width_mm, setup.n_bins
    centres = (np.arange(n) + 0.5) * (2 * half / n) - half
    x, y = np.meshgrid(centres, centres)
    w = h0 / h0.sum()
    r2 = float((w * (x ** 2 + y ** 2)).sum())
    # float64 NumPy reference: the same disc, binned the same way, with 100x the samples
    rng = np.random.default_rng(5)
    m = 2_000_000
    rr, phi = np.sqrt(rng.random(m)), 2 * np.pi * rng.random(m)
    ix = np.floor((setup.defocus_mm * rr * np.cos(phi) + half) * n / (2 * half)).astype(int)
    iy = np.floor((setup.defocus_mm * rr * np.sin(phi) + half) * n / (2 * half)).astype(int)
    ref_r2 = centres[ix] ** 2 + centres[iy] ** 2
    se = math.sqrt(ref_r2.var() / h0.sum() + ref_r2.var() / m)
    assert abs(r2 - ref_r2.mean()) < 4 * se
    assert abs(float((w * x).sum())) < 4 * math.sqrt(centres[ix].var() / h0.sum())
    # coma grows with field: the centroid moves toward +y
    cy = [(m / m.sum() * y).sum() for m in psf_map]
    assert all(b > a for a, b in zip(cy, cy[1:]))


def test_same_seed_same_map_other_seed_other_map(reference) -> None:
    again = LocalExecutor("cpu").run(W.make_job(6))
    assert np.array_equal(again.value["map"], reference.value["map"])
    other = LocalExecutor("cpu").run(W.make_job(6, seed=99))
    assert not np.array_equal(other.value["map"], reference.value["map"])


def test_threads_on_several_devices_give_the_bit_identical_result(reference) -> None:
    res = LocalExecutor("cpu,cpu,cpu").run(W.make_job(6))
    assert np.array_equal(res.value["map"], reference.value["map"])
    assert np.array_equal(res.value["sum_of_unit_psfs"], reference.value["sum_of_unit_psfs"])  # float, in order
    assert res.n_items == 6 and res.duplicates == 0 and res.devices == ("cpu", "cpu", "cpu")
    assert len(res.item_seconds) == 6 and all(s > 0 for s in res.item_seconds)


def test_item_results_do_not_depend_on_scheduling_order(reference) -> None:
    # the same items handed out in another order (costs reversed) reduce to the same value
    job = W.make_job(6)
    rev = Job(make_items([it.params for it in job.items], 1234, costs=range(6)), W.run, W.reduce,
              context=job.context, prepare=W.prepare)
    assert rev.schedule_order() == [5, 4, 3, 2, 1, 0]
    res = LocalExecutor("cpu,cpu").run(rev)
    assert np.array_equal(res.value["sum_of_unit_psfs"], reference.value["sum_of_unit_psfs"])


def test_context_is_prepared_once_per_process_and_device() -> None:
    clear_cache()
    LocalExecutor("cpu,cpu").run(W.make_job(6))
    s = cache_stats()
    assert s["prepare_calls"] == 1 and s["hits"] == 5 and s["items"] == 6
    LocalExecutor("cpu").run(W.make_job(4))  # same context: still prepared
    assert cache_stats()["prepare_calls"] == 1
    LocalExecutor("cpu").run(W.make_job(4, setup=W.HistogramSetup(n_bins=8)))  # another context
    assert cache_stats()["prepare_calls"] == 2
    assert content_hash(W.HistogramSetup()) == content_hash(W.HistogramSetup())
    assert content_hash(W.HistogramSetup()) != content_hash(W.HistogramSetup(n_bins=8))


def _fail_on_two(item: WorkItem, context: object, device: str) -> int:
    if item.index == 2:
        raise LensrtError("item two is bad", hint="fix it")
    return item.index


def test_an_error_in_an_item_reaches_the_caller() -> None:
    job = Job(make_items(range(5)), _fail_on_two, list, name="failing")
    with pytest.raises(LensrtError, match="item two is bad -- fix it"):
        LocalExecutor("cpu,cpu").run(job)
    host = Job(make_items(range(5)), _fail_on_two, list, uses_device=False)
    with pytest.raises(LensrtError, match="item two is bad"):
        LocalExecutor("cpu").run(host)


def test_parallel_arguments_build_the_executor() -> None:
    from lensrt.commands._parallel import add_parallel_arguments, executor_from_args
    p = argparse.ArgumentParser()
    add_parallel_arguments(p)
    ex = executor_from_args(p.parse_args(["--devices", "cpu,cpu"]))
    assert isinstance(ex, LocalExecutor) and ex.devices == ["cpu", "cpu"]
    with pytest.raises(LensrtError, match="give one of them"):
        executor_from_args(p.parse_args(["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]))
    with pytest.raises(LensrtError, match="must be 0"):
        executor_from_args(p.parse_args(["--workers", "-1"]))


def test_lensrt_runs_without_dask(monkeypatch, capsys) -> None:
    """distributed is optional: in-process jobs run, --workers says what to install."""
    import sys

    from conftest import LIBRARY
    from lensrt.cli import main
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    from lensrt.parallel import cluster
    assert not cluster.distributed_available()
    lens = str(LIBRARY / "codev_dblgauss_100mm_f2.toml")
    assert main(["sweep", lens, "--focus-distance-mm", "inf", "--f-number", "4"]) == 0
    assert "1 item in" in capsys.readouterr().out
    assert main(["sweep", lens, "--workers", "2"]) == 2
    assert "pip install 'lensrt[dist]'" in capsys.readouterr().err


@pytest.mark.gpu
def test_every_gpu_gives_the_one_gpu_result() -> None:
    """On a CUDA machine: all GPUs (one thread and stream each) against cuda:0 alone, bit for bit;
    against the CPU within Monte Carlo agreement (different float math: a few ray bins may differ)."""
    from lensrt.device import cuda_available
    if not cuda_available():
        pytest.skip("no CUDA device")
    job = W.make_job(12)
    one = LocalExecutor("cuda:0").run(job)
    every = LocalExecutor("all").run(job)
    assert np.array_equal(every.value["map"], one.value["map"])
    assert np.array_equal(every.value["sum_of_unit_psfs"], one.value["sum_of_unit_psfs"])
    cpu = LocalExecutor("cpu").run(job)
    moved = np.abs(cpu.value["map"] - one.value["map"]).sum() / cpu.value["map"].sum()
    assert moved < 1e-3


def test_workload_sizes_take_a_preset_with_overrides() -> None:
    from lensrt.parallel.workloads import parse_size
    presets = {"tiny": {"items": 8, "bins": 24, "lens": "a"}, "large": {"items": 256, "bins": 128, "lens": "a"}}
    assert parse_size("large", presets) == presets["large"]
    assert parse_size("large,items=36", presets) == {"items": 36, "bins": 128, "lens": "a"}
    assert parse_size("items=3, lens=b", presets) == {"items": 3, "bins": 24, "lens": "b"}
    assert presets["large"]["items"] == 256  # the preset itself is left alone
    with pytest.raises(LensrtError, match="unknown workload size 'huge'"):
        parse_size("huge,items=3", presets)
    with pytest.raises(LensrtError, match="bad workload size 'colour=1'"):
        parse_size("large,colour=1", presets)
    with pytest.raises(LensrtError, match="items='many' is not a int"):
        parse_size("large,items=many", presets)
