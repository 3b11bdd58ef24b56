"""Item results through shared memory (lensrt.parallel.shm): the same bits as a plain pickle, the segment
gone afterwards, small results left in the message; and large results through the process executor."""
from __future__ import annotations

import os
import pickle
from multiprocessing import shared_memory
from pathlib import Path

import numpy as np
import pytest

from lensrt.parallel import Job, LocalExecutor, ProcessExecutor, WorkItem, make_items
from lensrt.parallel.shm import Packed, pack, unpack


def test_a_large_result_round_trips_through_a_segment_that_is_then_gone() -> None:
    rng = np.random.default_rng(4)
    value = {"spec": rng.random(300_000), "xyz": rng.random((1000, 3)).astype(np.float32)[:, 1],  # a strided view
             "hits": np.arange(7, dtype=np.int64), "note": "tile 3", "n": 12}
    packed = pack(value)
    assert isinstance(packed, Packed) and len(pickle.dumps(packed)) < 20_000  # the message is small
    name = packed[0]
    back = unpack(packed)
    assert back.keys() == value.keys() and back["note"] == "tile 3" and back["n"] == 12
    for k in ("spec", "xyz", "hits"):
        assert back[k].dtype == value[k].dtype and np.array_equal(back[k], value[k])
    back["spec"][0] = -1.0                       # the arrays are the parent's own, writable
    with pytest.raises(FileNotFoundError):
        shared_memory.SharedMemory(name=name)    # unlinked


def test_a_worker_pool_reuses_its_two_segments_and_grows_one_when_needed() -> None:
    from lensrt.parallel.shm import Attached, SegmentPool
    pool, attached = SegmentPool(), Attached()
    rng = np.random.default_rng(5)
    names = []
    try:
        for n in (200_000, 200_000, 150_000, 400_000, 200_000):
            value = rng.random(n)
            packed = pack(value, pool=pool)
            assert isinstance(packed, Packed) and packed[3] is False      # pooled: the reader does not unlink
            names.append(packed[0])
            assert np.array_equal(unpack(packed, attached), value)
        assert names[2] == names[0] and names[1] != names[0]               # used in turn
        assert names[3] != names[1] and names[4] == names[2]               # a larger result: a new segment
        with pytest.raises(ValueError, match="Attached"):
            unpack(pack(np.zeros(200_000), pool=pool))
    finally:
        pool.close()
        attached.close()
    for name in set(names):
        with pytest.raises(FileNotFoundError):
            shared_memory.SharedMemory(name=name)


def test_without_room_in_shared_memory_a_result_stays_in_the_message(monkeypatch) -> None:
    """A full /dev/shm (a container's is often 64 MB) would kill the worker at its first write: no segment."""
    import lensrt.parallel.shm as shm
    from lensrt.parallel.shm import SegmentPool
    if not Path(shm.SHM_DIR).is_dir():
        pytest.skip("no /dev/shm to measure")
    monkeypatch.setattr(shm, "SHM_HEADROOM_BYTES", 1 << 62)
    value = {"spec": np.ones(300_000)}
    pool = SegmentPool()
    try:
        assert pack(value) is value and pack(value, pool=pool) is value
    finally:
        pool.close()


def test_small_or_unpicklable_results_stay_in_the_message() -> None:
    small = {"a": np.zeros(10)}
    assert pack(small) is small and unpack(small) is small
    odd = [lambda: 1]
    assert pack(odd, min_bytes=0) is odd


def _big(item: WorkItem, context: object, device: str) -> dict:
    rng = item.rng()
    return {"index": item.index, "values": rng.random(200_000 + item.index)}


def _concat(results: list) -> np.ndarray:
    return np.concatenate([r["values"] for r in results])


def _segments() -> set[str]:
    """Python's shared-memory segments on this machine (POSIX: files psm_* in /dev/shm; none elsewhere)."""
    shm = Path("/dev/shm")
    return {p.name for p in shm.glob("psm_*")} if shm.is_dir() else set()


def test_large_results_from_two_processes_equal_the_thread_run() -> None:
    job = Job(make_items(range(6), 9), _big, _concat, uses_device=False, name="big-results")
    want = LocalExecutor("cpu").run(job).value
    before = _segments()
    with ProcessExecutor("cpu,cpu") as ex:
        got = ex.run(job)
        again = ex.run(job)
        assert len(_segments() - before) <= 4     # two segments per worker, reused from job to job
    assert not _segments() - before               # and unlinked when the workers stop
    assert np.array_equal(got.value, want) and np.array_equal(again.value, want)
    assert got.duplicates == 0 and got.n_items == 6


def test_large_results_from_a_local_dask_cluster_equal_the_thread_run(monkeypatch) -> None:
    pytest.importorskip("distributed")
    from lensrt.parallel import DaskExecutor, cluster
    seen = []

    def spy(obj):
        seen.append(isinstance(obj, Packed))
        return unpack(obj)

    monkeypatch.setattr(cluster, "unpack", spy)
    job = Job(make_items(range(4), 9), _big, _concat, uses_device=False, name="big-results-dask")
    want = LocalExecutor("cpu").run(job).value
    with DaskExecutor.local(2, "cpu") as ex:
        before = _segments()
        got = ex.run(job)
        assert _segments() <= before
    assert np.array_equal(got.value, want) and got.n_items == 4
    assert seen == [True] * 4                     # every result came as a shared-memory segment


# --- results written in place: SharedArrays made by the parent, filled by the items -----------------------

_PART = 50_000


def _fill(item: WorkItem, context: object, device: str) -> dict:
    """Item ``index`` writes its random part into the run's shared arrays when it finds them."""
    from lensrt.parallel.shm import attach_shared
    token, n = item.params
    values = item.rng().random(_PART)
    arrays = attach_shared(token, {"v": ((n * _PART,), "float64")})
    if arrays is None:
        return {"placed": False, "values": values, "pid": os.getpid()}
    arrays["v"][item.index * _PART:(item.index + 1) * _PART] = values
    return {"placed": True, "values": None, "pid": os.getpid()}


class _InPlace:
    """Reduction: the run's arrays in shared memory; places the parts that came back instead."""

    def __init__(self, token: str, n: int) -> None:
        self.token, self.n = token, n

    def start(self) -> dict:
        from lensrt.parallel.shm import SharedArrays
        shared = SharedArrays(self.token, {"v": ((self.n * _PART,), "float64")})
        return {"shared": shared, "v": shared.arrays["v"], "placed": [], "pids": set()}

    def add(self, acc: dict, index: int, result: dict) -> dict:
        if not result["placed"]:
            acc["v"][index * _PART:(index + 1) * _PART] = result["values"]
        acc["placed"].append(result["placed"])
        acc["pids"].add(result["pid"])
        return acc

    def finish(self, acc: dict) -> tuple:
        acc["shared"].release()
        return acc["v"], acc["placed"], acc["pids"], acc["shared"].shared


def _in_place_job(n: int = 5) -> Job:
    token = f"lensrt-test-{os.getpid()}-{n}"
    return Job(make_items([(token, n)] * n, 11), _fill, _InPlace(token, n), uses_device=False, name="in-place")


def _want(n: int) -> np.ndarray:
    return np.concatenate([WorkItem(i, None, 11).rng().random(_PART) for i in range(n)])


def test_worker_processes_write_the_parents_shared_arrays_in_place() -> None:
    """Every part is written by a worker process straight into the parent's segment (no result arrays
    come back), the values are the thread run's, and the segment is gone once the run has finished."""
    job = _in_place_job()
    with ProcessExecutor("cpu,cpu") as ex:
        v, placed, pids, shared = ex.run(job).value
    assert shared and placed == [True] * 5 and os.getpid() not in pids
    assert np.array_equal(v, _want(5))
    assert not Path("/dev/shm", job.items[0].params[0]).exists()
    v2, placed2, pids2, _ = LocalExecutor("cpu,cpu").run(job).value   # threads: the same arrays, in process
    assert placed2 == [True] * 5 and pids2 == {os.getpid()} and np.array_equal(v2, v)


def test_without_room_the_arrays_stay_in_the_parent_and_processes_return_their_parts(monkeypatch) -> None:
    import lensrt.parallel.shm as shm
    monkeypatch.setattr(shm, "SHM_HEADROOM_BYTES", 1 << 62)
    job = _in_place_job(3)
    v, placed, _, shared = LocalExecutor("cpu").run(job).value
    assert not shared and placed == [True] * 3 and np.array_equal(v, _want(3))
    assert shm.attach_shared(job.items[0].params[0], {"v": ((3 * _PART,), "float64")}) is None   # released
    with ProcessExecutor("cpu") as ex:
        v2, placed2, _, _ = ex.run(job).value
    assert placed2 == [False] * 3 and np.array_equal(v2, v)


def test_a_run_that_failed_leaves_no_segment_and_does_not_block_the_next() -> None:
    from lensrt.parallel.shm import SharedArrays, attach_shared
    layout = {"a": ((4, 3), "float64"), "b": ((7,), "int64")}
    first = SharedArrays("lensrt-test-stale", layout)
    first.arrays["b"][:] = 5
    second = SharedArrays("lensrt-test-stale", layout)   # the first run never finished: replaced
    assert attach_shared("lensrt-test-stale", layout)["b"].sum() == 0
    assert attach_shared("lensrt-test-stale", {"a": ((5, 3), "float64")}) is None   # another layout: not these
    del second
    import gc
    gc.collect()
    assert not Path("/dev/shm/lensrt-test-stale").exists() and attach_shared("lensrt-test-stale", layout) is None
    assert first.arrays["b"].sum() == 35                  # the first run's arrays stay valid
