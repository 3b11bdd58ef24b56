"""The render integrator: determinism (same seed, same bits; any tiling or executor), Jobs, progressive
stopping and region estimates with their standard errors."""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from lensrt.render.integrator import render
from lensrt.render.setup import RenderOptions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

# ---- determinism, Jobs, stopping ---------------------------------------------------------------

def _small_default(**kw):
    from lensrt.render.scene.load import load_scene
    return load_scene("default"), RenderOptions(width=48, samples_per_pixel=4, spp_per_pass=2, device="cpu", **kw)


def test_same_seed_same_image_bit_for_bit(monkeypatch):
    from lensrt.render import pupil_table
    scene, opts = _small_default()
    a = render(scene, options=opts)
    b = render(scene, options=opts)
    monkeypatch.setattr(pupil_table, "_cpu_workers", lambda device, n: 3)   # another launch split
    c = render(scene, options=opts)
    for other in (b, c):
        assert np.array_equal(a.irradiance, other.irradiance)
        assert np.array_equal(a.xyz, other.xyz) and np.array_equal(a.xyz_stderr, other.xyz_stderr)
    d = render(scene, options=dataclasses.replace(opts, seed=99))
    assert not np.array_equal(a.irradiance, d.irradiance)


def _same_estimates(a, b, rel: float = 1e-12) -> None:
    """Region and through-the-lens estimates of two renders of the same passes agree to ``rel``."""
    assert a.regions.keys() == b.regions.keys() and len(a.regions) == 6
    for name in a.regions:
        for f in ("value", "stderr"):
            x, y = getattr(a.regions[name], f), getattr(b.regions[name], f)
            assert abs(x - y) <= rel * abs(x), (name, f, x, y)
    assert a.through.value == b.through.value and a.through.stderr == b.through.stderr
    assert a.through_fraction == b.through_fraction


def test_fixed_samples_on_an_executor_run_tiles_with_the_same_bits():
    """A fixed sample count on two devices: one Job of row-band tiles; the image bits of one device (3
    passes: the mean is times 1/6), its per-pass hits, and region means to 1e-12 (tile sums, other order)."""
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default()
    opts = dataclasses.replace(opts, samples_per_pixel=6)
    a = render(scene, options=opts)
    seen = []
    with LocalExecutor("cpu,cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex,
                   progress=lambda *p: seen.append(p))
    assert b.executor_items == "tiles" and b.executor_item_count == 6 and a.executor_items is None
    assert b.summary()["executor_items"] == "tiles"
    for f in ("irradiance", "xyz", "xyz_stderr"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert b.passes == a.passes == 3 and b.samples == a.samples and b.stop_reason == "samples"
    _same_estimates(a, b)
    assert len(b.history) == 1 and b.history[0]["passes"] == 3
    assert b.history[0]["rel_error"] == a.history[-1]["rel_error"]
    assert seen and seen[-1][:2] == (3, 3) and seen[-1][3] == 0.0


def test_tiles_with_a_window_equal_one_device():
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default(window=(3, 20, 5, 40))
    a = render(scene, options=opts)
    with LocalExecutor("cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex)
    assert b.executor_items == "tiles" and b.executor_item_count == 3
    assert np.array_equal(a.irradiance, b.irradiance) and np.array_equal(a.xyz_stderr, b.xyz_stderr)
    _same_estimates(a, b)


def test_progressive_runs_on_an_executor_keep_pass_rounds():
    """A target error needs a decision after every pass: rounds of one pass per device, one history row
    per pass, and the same passes and bits as one device (the error measure is computed from the same sums)."""
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default()
    opts = dataclasses.replace(opts, samples_per_pixel=None, target_rel_error=0.3)
    a = render(scene, options=opts)
    with LocalExecutor("cpu,cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex)
    assert b.executor_items == "passes" and b.executor_item_count == b.passes
    assert b.stop_reason == a.stop_reason == "target_error" and b.passes == a.passes >= 4
    assert len(b.history) == b.passes
    assert np.array_equal(a.irradiance, b.irradiance) and np.array_equal(a.xyz_stderr, b.xyz_stderr)
    _same_estimates(a, b, rel=0.0)


def test_region_sums_from_row_segments_add_up_to_the_region_sums(device):
    """Any split of the pixels into ranges (row-aligned or not): the row-segment sums that the tile's
    per-pass kernel writes for each range give, added range by range, the sums over each region (numpy
    on the whole image) and the paths through of each range; the same launch adds the range's
    spectral values and XYZ moments to its float64 sums (numpy in float64: the same bits), on the
    CPU in slices that start at any thread id."""
    from lensrt.device import warp
    from lensrt.render.jobs import region_cuts, region_sums_from_segments
    from lensrt.render.passes import region_slices
    from lensrt.render.pupil_table import launch_sliced
    from lensrt.render.tile_kernels import tile_pass_sums
    wp = warp()
    shape, bands = (23, 17), 2
    rng = np.random.default_rng(1)
    y = rng.random(shape).astype(np.float32)
    hits = rng.integers(0, 9, shape[0] * shape[1]).astype(np.int32)
    spec = rng.random(y.size * bands).astype(np.float32)
    want = [y.astype(np.float64)[r0:r1, c0:c1].sum() for r0, r1, c0, c1 in region_slices(shape)]
    cuts = region_cuts(shape, longest=4)
    assert cuts[0] == 0 and cuts[-1] == shape[1] and np.all(np.diff(cuts) <= 4) and np.all(np.diff(cuts) > 0)
    xyz = rng.random((y.size, 3)).astype(np.float32)
    xyz[:, 1] = y.reshape(-1)
    got, through = np.zeros(len(want)), 0
    bounds = [0, 5, 17, 40, 41, 200, 17 * 3 * 4, 391]
    for p0, p1 in zip(bounds[:-1], bounds[1:]):
        ra, rb = p0 // shape[1], -(-p1 // shape[1])
        n, n_segs = p1 - p0, len(cuts) - 1
        n_cells, n_spec = (rb - ra) * n_segs, (p1 - p0) * bands
        seg = wp.zeros((2, rb - ra, n_segs), dtype=wp.float64, device=device)
        seg_hits = wp.zeros((2, rb - ra, n_segs), dtype=wp.int64, device=device)
        start = rng.random(n_spec)                           # sums so far (one pass before this one)
        spec_sum = wp.array(start, dtype=wp.float64, device=device)
        s1, s2 = (wp.array(np.full((n, 3), v), dtype=wp.float64, device=device) for v in (0.25, 0.5))
        args = [wp.array(spec[p0 * bands:p1 * bands], dtype=float, device=device), spec_sum, n_spec,
                wp.array(xyz[p0:p1], dtype=wp.vec3, device=device), s1, s2,
                wp.array(hits[p0:p1], dtype=wp.int32, device=device), p0, p1, ra, shape[1],
                wp.array(cuts, dtype=wp.int32, device=device), n_segs, n_cells, 1, seg, seg_hits]
        launch_sliced(tile_pass_sums, max(n_spec, n, n_cells), lambda base: [int(base)] + args, device, workers=3)
        got += region_sums_from_segments(seg.numpy()[1], ra, shape, cuts)
        assert not seg.numpy()[0].any() and not seg_hits.numpy()[0].any()      # slot 0 untouched
        through += int(seg_hits.numpy().sum())
        x = xyz[p0:p1].astype(np.float64)
        assert np.array_equal(spec_sum.numpy(), start + spec[p0 * bands:p1 * bands].astype(np.float64))
        assert np.array_equal(s1.numpy(), 0.25 + x) and np.array_equal(s2.numpy(), 0.5 + x * x)
    assert np.allclose(got, want, rtol=1e-13, atol=0)
    assert through == int(hits.sum())


def test_recorded_camera_passes_equal_launched_passes_and_count_as_launches(device):
    """The camera kernel recorded once per tile and replayed with each pass's seed gives the bits of a pass
    launched with all its arguments (every pass, not only the first), and telemetry counts each replay as
    a launch."""
    from lensrt.core.telemetry import measure
    from lensrt.parallel.workloads import get_workload
    from lensrt.render.passes import RecordedPasses, device_pass, prepare_setup
    prep = prepare_setup(get_workload("render")("tiles=2", 11).context, device)
    p0, p1 = 100, 900
    rec = RecordedPasses(prep, (p0, p1))
    with measure() as t:
        for index in (0, 1, 2):
            got = rec.run(index)
            want = device_pass(prep, index, None, (p0, p1))
            for f in ("spec", "xyz", "hits"):
                assert np.array_equal(getattr(got, f).numpy(), getattr(want, f).numpy()), (index, f)
    assert t.launches == 6
    first = rec.run(0).xyz.numpy().copy()                 # (on the CPU numpy() aliases the buffer)
    assert not np.array_equal(first, rec.run(1).xyz.numpy())   # the seed did change


def test_a_tile_copies_from_its_device_once_whatever_its_pass_count(monkeypatch):
    """A tile queues all its passes without bringing anything to the host between them (on a GPU each
    copy waits for the device): the number of device-to-host copies of one item does not grow with its
    passes."""
    import warp as wp
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    copies = []
    numpy_of = wp.array.numpy
    monkeypatch.setattr(wp.array, "numpy", lambda self: copies.append(1) or numpy_of(self))
    per_item = []
    for passes in (2, 5):
        job = get_workload("render")(f"passes={passes},tiles=2", 3)
        LocalExecutor("cpu").run(job)
        copies.clear()
        LocalExecutor("cpu").run(job)
        per_item.append(len(copies) / len(job.items))
    assert per_item[0] == per_item[1] <= 5


def test_tiles_written_in_place_equal_tiles_returned_to_the_reduction():
    """Tiles that copy their sums from the device straight into the run's image (and compute their XYZ
    mean and standard error there) give the bits of tiles that return their sums for the reduction to
    place: image, moments, per-pass hits and region means; every tile of a thread run finds the image,
    and the run's shared-memory segment is gone at its end."""
    import dataclasses as dc
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.shm import SHM_DIR
    from lensrt.parallel.workloads import get_workload
    from lensrt.render.jobs import render_tiles_job, run_tile_item
    setup = get_workload("render")("tiles=3", 7).context
    placed = []

    def spy(item, prep, device):
        r = run_tile_item(item, prep, device)
        placed.append(r.placed)
        return r

    values = []
    for in_place in (False, True):
        job = render_tiles_job(setup, 3, 5, in_place=in_place)
        job = dc.replace(job, run=spy)
        placed.clear()
        values.append(LocalExecutor("cpu,cpu").run(job).value)
        assert placed == [in_place] * 5
    ret, inp = values
    for f in ("spec_sum", "xyz", "xyz_stderr", "passes", "samples_per_pixel", "hits"):
        assert np.array_equal(getattr(ret, f), getattr(inp, f)), f
    assert inp.pass_sum.pass_hits == ret.pass_sum.pass_hits and inp.pass_sum.region_means == ret.pass_sum.region_means
    assert np.array_equal(inp.pass_sum.xyz2, ret.pass_sum.xyz2)
    assert not Path(SHM_DIR, job.items[0].params[3]).exists()
    assert get_workload("render")("tiles=2,in_place=0", 3).items[0].params[3] is None   # the benchmark's switch


@pytest.mark.gpu
def test_tiles_in_place_on_every_gpu_equal_returned_tiles_on_one() -> None:
    """On a CUDA machine: tiles written in place by one thread and by one worker process per GPU give the
    bits of tiles returned from cuda:0 alone (the copy straight from the device into the image)."""
    from lensrt.device import cuda_available
    if not cuda_available():
        pytest.skip("no CUDA device")
    from lensrt.parallel import LocalExecutor, ProcessExecutor
    from lensrt.parallel.workloads import get_workload
    from lensrt.render.jobs import render_tiles_job
    setup = get_workload("render")("small", 5).context
    want = LocalExecutor("cuda:0").run(render_tiles_job(setup, 4, 8, in_place=False)).value
    with ProcessExecutor("all") as px:
        for ex in (LocalExecutor("cuda:0"), LocalExecutor("all"), px):
            got = ex.run(render_tiles_job(setup, 4, 8)).value
            for f in ("spec_sum", "xyz", "xyz_stderr", "hits"):
                assert np.array_equal(getattr(got, f), getattr(want, f)), (ex.describe(), f)
            assert got.pass_sum.region_means == want.pass_sum.region_means


def test_render_job_workload_reduces_in_pass_order():
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    job = get_workload("render")("tiny", 5)
    one = LocalExecutor("cpu").run(job).value
    two = LocalExecutor("cpu,cpu").run(job).value
    assert np.array_equal(one.spec_sum, two.spec_sum) and np.array_equal(one.xyz_stderr, two.xyz_stderr)
    assert one.passes == 4 and np.all(np.isfinite(one.xyz_stderr))


def test_tiled_render_job_equals_the_pass_job_and_the_in_process_render():
    """Tiles with all their passes summed on the device: the same bits as items of one pass each (any
    number of tiles, one or two devices) and as the one-device render's irradiance."""
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    passes = LocalExecutor("cpu").run(get_workload("render")("tiles=0", 3)).value
    for tiles, devices in ((1, "cpu"), (5, "cpu,cpu")):
        job = get_workload("render")(f"tiles={tiles}", 3)
        assert len(job.items) == tiles
        v = LocalExecutor(devices).run(job).value
        for f in ("spec_sum", "xyz", "xyz_stderr", "passes", "samples_per_pixel", "hits"):
            assert np.array_equal(getattr(passes, f), getattr(v, f)), (tiles, f)
    setup = job.context
    scene = setup.scene
    r = render(scene, options=RenderOptions(width=64, spp_per_pass=2, samples_per_pixel=8, seed=3, device="cpu"))
    assert np.array_equal(r.irradiance, v.irradiance(setup.shape, setup.n_bands))


def test_stop_rules_samples_time_and_target_error():
    scene, opts = _small_default()
    r = render(scene, options=opts)
    assert r.stop_reason == "samples" and r.samples_per_pixel == 4 and r.samples == 4 * 48 * 32
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=None, time_budget_s=1e-3))
    assert r.stop_reason == "time_budget" and r.passes == 4          # the rule waits for 4 passes
    target = 0.3
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=None, target_rel_error=target))
    assert r.stop_reason == "target_error" and r.history[-1]["rel_error"] <= target
    assert all(h["rel_error"] > target for h in r.history[3:-1])
    # error against run time: the error falls as passes are added
    errs = [h["rel_error"] for h in r.history if h["rel_error"] is not None]
    assert errs[-1] < errs[0]
    for h in r.history:
        assert {"passes", "samples", "seconds"} <= set(h)


def test_regions_carry_stderr_samples_seconds():
    scene, opts = _small_default()
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=8))
    for name in ("image", "centre", "bottom left", "bottom right"):
        est = r.regions[name]
        assert est.value > 0 and 0 < est.stderr < est.value and est.samples == r.samples and est.seconds > 0
    assert 0.3 < r.through_fraction <= 1.0


# ---- light splat ------------------------------------------------------------------------------
