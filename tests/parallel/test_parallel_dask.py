"""lensrt.parallel on Dask distributed: LocalClusters of worker processes on loopback.

The Monte Carlo test workload run on two worker processes must give the same
PSF map, bit for bit, as the single-process run; the context must reach each
worker once; a worker killed in the middle of an item must not change the
result.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("distributed")

import workload_mc_histogram as W  # noqa: E402
from lensrt.cli import main  # noqa: E402
from lensrt.errors import LensrtError  # noqa: E402
from lensrt.parallel import DaskExecutor, Job, LocalExecutor, WorkItem, make_items  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes on 127.0.0.1 (shared by the tests of this module)."""
    with DaskExecutor.local(2, "cpu") as ex:
        ex.client.wait_for_workers(2, timeout=60)
        yield ex


@pytest.fixture(scope="module")
def reference():
    return LocalExecutor("cpu").run(W.make_job(8))


def test_two_worker_processes_give_the_single_process_psf_map(cluster, reference) -> None:
    res = cluster.run(W.make_job(8))
    assert np.array_equal(res.value["map"], reference.value["map"])
    assert np.array_equal(res.value["sum_of_unit_psfs"], reference.value["sum_of_unit_psfs"])
    assert res.duplicates == 0 and res.n_items == 8
    assert len(set(res.item_workers)) == 2  # both processes ran items
    assert "dask local cluster, 2 worker(s)" in res.executor


def test_items_in_chunks_give_the_same_map(cluster, reference) -> None:
    chunked = DaskExecutor(client=cluster.client, devices="cpu", chunk_size=3)
    res = chunked.run(W.make_job(8))
    assert np.array_equal(res.value["sum_of_unit_psfs"], reference.value["sum_of_unit_psfs"])
    assert chunked._chunk(W.make_job(8)) == 3


def test_context_is_shipped_and_prepared_once_per_worker(cluster) -> None:
    setup = W.HistogramSetup(n_bins=16)  # a context no other test ships
    res = cluster.run(W.make_job(10, setup=setup))
    assert res.value["map"].shape == (10, 16, 16)
    res = cluster.run(W.make_job(6, setup=setup))  # a second job on the same context ships nothing
    stats = cluster.client.run(W.worker_stats)
    assert len(stats) == 2
    for s in stats.values():
        # unpickled once per context shipped to this worker, never per item
        assert s["unpickled"] == s["contexts_received"] <= 2
        assert s["items"] >= 1
        assert s["prepare_calls"] <= s["contexts_received"]
    assert sum(s["items"] for s in stats.values()) >= 16


def _fail_on_two(item: WorkItem, context: object, device: str) -> int:
    if item.index == 2:
        raise LensrtError("item two is bad", hint="fix it")
    return item.index


def test_an_item_error_reaches_the_client_as_a_lensrt_error(cluster) -> None:
    with pytest.raises(LensrtError, match="item two is bad -- fix it"):
        cluster.run(Job(make_items(range(4)), _fail_on_two, list, name="failing", uses_device=False))


def test_gpu_tasks_need_workers_with_a_gpu_resource(cluster) -> None:
    ex = DaskExecutor(client=cluster.client, devices="cuda", gpu_tasks=True)
    with pytest.raises(LensrtError, match="advertises a 'GPU' resource"):
        ex.run(W.make_job(2))


def test_sweep_on_the_cluster_equals_the_in_process_sweep(cluster, capsys, library_dir) -> None:
    lens = str(library_dir / "codev_dblgauss_100mm_f2.toml")
    argv = ["sweep", lens, "--focus-distance-mm", "800:20000:5", "--f-number", "2,4,8", "--format", "json"]
    assert main(argv) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(argv + ["--scheduler", cluster.address]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert remote["rows"] == local["rows"] and len(local["rows"]) == 15
    assert remote["run"]["executor"].startswith(f"dask cluster {cluster.address}")


def test_a_worker_killed_mid_task_changes_nothing(tmp_path, reference) -> None:
    """The first attempt of item 3 kills its worker process; Dask reruns it elsewhere."""
    marker = tmp_path / "killed"
    setup = W.HistogramSetup(kill_marker=str(marker))
    expect = LocalExecutor("cpu").run(W.make_job(8, setup=setup))
    assert np.array_equal(expect.value["map"], reference.value["map"])  # the marker path changes no number
    with DaskExecutor.local(2, "cpu") as ex:
        ex.client.wait_for_workers(2, timeout=60)
        res = ex.run(W.make_job(8, setup=setup, killing=True))
    assert marker.read_text().startswith("killed pid")  # a worker really died mid-task
    assert np.array_equal(res.value["map"], expect.value["map"])
    assert np.array_equal(res.value["sum_of_unit_psfs"], expect.value["sum_of_unit_psfs"])
    assert res.n_items == 8 and len(res.item_seconds) == 8


def test_workers_option_starts_a_local_cluster(capsys, library_dir) -> None:
    lens = str(library_dir / "codev_dblgauss_100mm_f2.toml")
    argv = ["sweep", lens, "--focus-distance-mm", "1000,inf", "--f-number", "2.8,5.6", "--format", "json"]
    assert main(argv) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(argv + ["--workers", "2", "--devices", "cpu"]) == 0
    dist = json.loads(capsys.readouterr().out)
    assert dist["rows"] == local["rows"]
    assert "dask local cluster, 2 worker(s)" in dist["run"]["executor"]


@pytest.mark.gpu
def test_one_dask_worker_per_gpu_gives_the_one_gpu_result() -> None:
    """On a CUDA machine: a LocalCluster of one worker per GPU (GPU=1 resource each) against cuda:0 in
    this process, bit for bit."""
    from lensrt.device import cuda_available
    from lensrt.parallel import resolve_devices
    if not cuda_available():
        pytest.skip("no CUDA device")
    job = W.make_job(12)
    one = LocalExecutor("cuda:0").run(job)
    gpus = resolve_devices("all")
    with DaskExecutor.local(len(gpus), gpus) as ex:
        ex.client.wait_for_workers(len(gpus), timeout=120)
        every = ex.run(job)
    assert np.array_equal(every.value["map"], one.value["map"])
    assert np.array_equal(every.value["sum_of_unit_psfs"], one.value["sum_of_unit_psfs"])
    assert set(every.item_devices) <= set(gpus)
