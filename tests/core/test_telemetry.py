"""Telemetry counts lensrt's kernel launches and host<->device copies (no timing asserts)."""
from __future__ import annotations

import numpy as np

from lensrt import load_lens
from lensrt.core.telemetry import measure
from lensrt.trace import RayBatch, trace


def _rays(n: int) -> RayBatch:
    o = np.zeros((n, 3))
    o[:, 1] = np.linspace(-1.0, 1.0, n)
    d = np.zeros((n, 3))
    d[:, 2] = 1.0
    return RayBatch(o, d, 587.56)


def test_a_small_trace_is_one_launch_one_upload_three_downloads():
    lens = load_lens("cooke_triplet_50mm_f5")
    trace(lens, _rays(5), "float64", "cpu")  # packs the lens (cached per lens, precision, device)
    with measure() as rec:
        trace(lens, _rays(5), "float64", "cpu")
    assert (rec.launches, rec.copies) == (1, 4)  # one store launch; rays up; out, status, surface down
    assert rec.wall_s >= rec.kernel_s >= 0.0
    assert set(rec.to_dict()) == {"wall_s", "kernel_s", "launches", "copies"}


def test_records_nest_and_count_only_inside():
    lens = load_lens("cooke_triplet_50mm_f5")
    trace(lens, _rays(3), "float64", "cpu")
    with measure() as outer:
        trace(lens, _rays(3), "float64", "cpu")
        with measure() as inner:
            trace(lens, _rays(3), "float64", "cpu")
            trace(lens, _rays(3), "float64", "cpu", record=True)
        trace(lens, _rays(3), "float64", "cpu")
    trace(lens, _rays(3), "float64", "cpu")
    assert (inner.launches, inner.copies) == (2, 9)  # the recorded trace downloads its records too
    assert (outer.launches, outer.copies) == (4, 17)
    assert outer.wall_s >= inner.wall_s


def test_a_json_result_carries_its_commands_telemetry(capsys):
    import json

    from lensrt.cli import main
    assert main(["ray", "cooke_triplet_50mm_f5", "--hy", "1", "--py", "1", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)["telemetry"]
    assert set(rec) == {"wall_s", "kernel_s", "launches", "copies"}
    assert rec["launches"] >= 1 and rec["copies"] >= 2 * rec["launches"]


def test_a_launch_sliced_over_cpu_cores_counts_once():
    lens = load_lens("cooke_triplet_50mm_f5")
    trace(lens, _rays(5000), "float64", "cpu")  # >= 4096 rays: one slice per core this process may use
    with measure() as rec:
        trace(lens, _rays(5000), "float64", "cpu")
    assert (rec.launches, rec.copies) == (1, 4)


def test_launch_slices_runs_every_thread_once_and_counts_one_launch():
    """A logical launch cut into slices (empty ones skipped) runs each thread id once, in its slice, and counts as
    one launch (the slice that starts at thread 0)."""
    import warp as wp
    from lensrt.core.telemetry import launch_slices
    from telemetry_kernels import count_threads
    hits = wp.zeros(10, dtype=wp.int32, device="cpu")
    owner = wp.zeros(10, dtype=wp.int32, device="cpu")
    with measure() as rec:
        launch_slices(count_threads, [0, 3, 3, 10], "cpu", lambda w, start: [start, w, hits, owner])
    assert rec.launches == 1
    assert hits.numpy().tolist() == [1] * 10  # every thread id once
    assert owner.numpy().tolist() == [0] * 3 + [2] * 7  # threads 0-2 in slice 0, 3-9 in slice 2 (slice 1 empty)
