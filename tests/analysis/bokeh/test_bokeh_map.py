"""Bokeh maps: batched pupil boxes, windows in one frame, the parallel job's determinism, files, the CLI."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bokeh_cases import singlet

from lensrt import load_lens
from lensrt.analysis.bokeh.entry import bokeh_map, bokeh_spot, focus_lens, map_sources, sensor_frame, spot_source
from lensrt.analysis.bokeh.trace import pupil_boxes
from lensrt.cli import main
from lensrt.parallel import LocalExecutor


@pytest.fixture(scope="module")
def dgauss():
    return load_lens("dgauss_50mm_f2")


def test_batched_pupil_boxes_equal_stream_source(dgauss, device):
    from lensrt.trace.aiming import FieldPoint
    from lensrt.trace.stream import stream_source
    f = focus_lens(dgauss, 2000.0)
    pts = np.array([[0.0, 0.0, -1000.0], [300.0, 200.0, -1000.0], [-450.0, 0.0, -1000.0], [0.0, 600.0, -1000.0]])
    boxes, foot = pupil_boxes(dgauss, pts, dgauss.wavelengths.nm, f.sensor_z_mm, device=device)
    for k, p in enumerate(pts):
        ref = stream_source(dgauss, field=FieldPoint(False, None, tuple(p)), plane_z_mm=f.sensor_z_mm, device=device)
        b = boxes[k]
        assert (b.a0, b.a1, b.b0, b.b1) == pytest.approx((ref.box.a0, ref.box.a1, ref.box.b0, ref.box.b1), abs=1e-9)
        if b.area_mm2 > 0:  # the footprint surrounds the chief ray's image point
            assert foot[k, 0] < ref.centre_mm[0] < foot[k, 1] and foot[k, 2] < ref.centre_mm[1] < foot[k, 3]
    assert boxes[3].area_mm2 == 0.0 and np.all(np.isnan(foot[3]))  # 31 deg: outside the lens's field


def test_map_is_the_sum_of_its_spots(device):
    # a 2 x 1 map must hold exactly what the two sources give as spots on the same pixel grid
    lens = load_lens(singlet(50.0, 4.0, -2.25, stop_gap_mm=10.0, fields_deg=(0.0, 15.0)))
    f = focus_lens(lens, 1000.0)
    img = bokeh_map(lens, f, grid=(2, 1), depths_mm=[5000.0], sensor_mm=(24.0, 12.0), pixels=(240, 120),
                    light="550", rays=1 << 16, device=device, intensity_scaling="none")
    assert len(img.sources) == 2 and all(r["reached_sensor"] for r in img.sources)
    assert img.rays == 2 * (1 << 16)
    pic = img.picture()[..., 1]
    # flux: each source's spot lands whole inside the frame
    total = pic.sum() * img.frame.pitch_mm ** 2 * 1e-6
    assert total == pytest.approx(sum(r["luminous_flux_lm"] for r in img.sources), rel=1e-5)
    assert all(r["off_window_fraction"] < 1e-6 for r in img.sources)
    # the spots sit around their chief rays' targets (coma moves the centroid a little off them), and
    # the picture is upright: its left half is the sensor's +x side
    for r in img.sources:
        assert math.dist(r["centroid_mm"], r["target_mm"]) < r["rms_radius_mm"]
    rows, cols = np.nonzero(pic > 0)
    x, _ = img.sensor_xy(rows, cols)
    left = cols < img.frame.nx // 2
    assert np.all(x[left] > 0) and np.all(x[~left] < 0)
    for r in img.sources:  # an object on the photographer's right appears on the picture's right
        _, col = img.pixel_of(*r["centroid_mm"])
        assert (col > img.frame.nx / 2) == (r["object_mm"][0] > 0)
    assert img.pixel_of(*img.sensor_xy(3.0, 7.0)) == pytest.approx((3.0, 7.0))


def test_map_is_the_same_on_any_number_of_devices(dgauss):
    f = focus_lens(dgauss, 2000.0)
    kw = dict(grid=(3, 2), depths_mm=[1000.0, 20000.0], pixels=(180, 120), rays=4096, seed=7, sources_per_item=4)
    one = bokeh_map(dgauss, f, executor=LocalExecutor("cpu"), **kw)
    two = bokeh_map(dgauss, f, executor=LocalExecutor("cpu,cpu"), **kw)
    assert np.array_equal(one.sensor_xyz, two.sensor_xyz) and np.array_equal(one.var_y, two.var_y)
    assert [r["transmission"] for r in one.sources] == [r["transmission"] for r in two.sources]
    assert one.digest() == two.digest()
    # every source draws its own random numbers: chunking the sources into items of 1 or all 12 (other
    # launches, other groups, other window sizes in a launch) gives the same bits
    for per_item in (1, 12):
        again = bokeh_map(dgauss, f, executor=LocalExecutor("cpu"), **{**kw, "sources_per_item": per_item})
        assert np.array_equal(one.sensor_xyz, again.sensor_xyz) and np.array_equal(one.var_y, again.var_y)
        assert [r["seed"] for r in again.sources] == [r["seed"] for r in one.sources]
    assert len({r["seed"] for r in one.sources}) == 12
    other = bokeh_map(dgauss, f, executor=LocalExecutor("cpu"), **{**kw, "seed": 8})
    assert not np.array_equal(one.sensor_xyz, other.sensor_xyz) and other.digest() != one.digest()
    d = one.to_dict()
    assert d["n_sources"] == 12 and d["rays"] == 12 * 4096 and d["seconds"] > 0
    assert 0 < d["noise"]["rel_stderr_median"] <= d["noise"]["rel_stderr_max"] < 1
    assert "Poisson" in d["noise"]["method"]


def test_cats_eyes_toward_the_corners(dgauss, device):
    # the double Gauss's clear apertures (pbrt table) vignette off axis: pupil transmission falls and
    # the corner discs are narrower across the radius than along the tangent
    f = focus_lens(dgauss, 1000.0)
    frame = sensor_frame((36.0, 24.0), (180, 120))
    src = map_sources(dgauss, f, frame, (3, 3), [20000.0], device=device)
    centre, corner = src[4], src[0]
    img = {}
    for name, s in (("centre", centre), ("corner", corner)):
        img[name] = bokeh_spot(dgauss, f, s, light="587.5618", rays=1 << 17, pixel_um=10.0, device=device,
                               batch_noise=False)
    assert img["corner"].sources[0]["pupil_area_mm2"] < 0.8 * img["centre"].sources[0]["pupil_area_mm2"]
    pic = img["corner"].picture()[..., 1]
    rows, cols = np.nonzero(pic > 0.3 * pic.max())
    x, y = img["corner"].sensor_xy(rows, cols)
    t = np.array(corner["target_mm"]) / np.hypot(*corner["target_mm"])
    along_r = (x - x.mean()) * t[0] + (y - y.mean()) * t[1]
    along_t = -(x - x.mean()) * t[1] + (y - y.mean()) * t[0]
    assert along_r.std() < 0.8 * along_t.std()


def test_workload_factory_runs():
    from lensrt.parallel.workloads import get_workload
    job = get_workload("bokeh-map")("tiny", 3)
    assert job.name == "bokeh-map" and len(job.items) >= 1
    res = LocalExecutor("cpu").run(job)
    assert res.value.rays > 0 and res.value.sensor_xyz.shape[1:] == (160, 240)


def test_files_round_trip(tmp_path, dgauss, device):
    from lensrt.views.bokeh_files import read_bokeh_exr, write_bokeh_files
    f = focus_lens(dgauss, 2000.0)
    img = bokeh_spot(dgauss, f, spot_source(dgauss, f, 10000.0), rays=1 << 15, seed=5, device=device)
    paths = write_bokeh_files(img, tmp_path, "spot")
    xyz, rel, meta = read_bokeh_exr(paths["exr"])
    assert np.allclose(xyz, img.picture(), rtol=1e-6, atol=0)
    assert rel.shape == xyz.shape[:2] and np.all(rel >= 0)
    assert meta["lensrt:kind"] == "bokeh" and meta["lensrt:rays"] == img.rays and meta["lensrt:seed"] == 5
    assert meta["lensrt:focus"]["distance_mm"] == 2000.0 and meta["lensrt:sources"][0]["depth_mm"] == 10000.0
    assert 0 < meta["lensrt:noise"]["rel_stderr_median"] < 1
    from PIL import Image
    png = Image.open(paths["png"])
    assert png.size == (img.frame.nx, img.frame.ny) and png.text["lensrt:rays"] == str(img.rays)
    summary = json.loads(paths["json"].read_text())
    assert summary["rays"] == img.rays and summary["sources"][0]["transmission"] > 0


def test_cli_spot_and_map(tmp_path, capsys):
    assert main(["bokeh", "--focus-m", "2", "--source-m", "10", "--rays", "2e4", "--out", str(tmp_path),
                 "--blades", "7", "--blade-rotation-deg", "10", "--device", "cpu"]) == 0
    out = capsys.readouterr().out
    assert "Gaussian blur disc" in out and "rays in" in out and "noise" in out
    assert (tmp_path / "bokeh.png").is_file() and (tmp_path / "bokeh.exr").is_file()
    assert main(["bokeh", "--focus-m", "2", "--map", "3x2", "--depths-m", "1,20", "--pixels", "150x100",
                 "--rays", "4096", "--out", str(tmp_path), "--json", "--devices", "cpu"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["n_sources"] == 12 and d["frame"]["pixels"] == [150, 100] and d["depths_m"] == [1.0, 20.0]
    assert d["settings"]["focus"]["distance_mm"] == 2000.0 and d["files"]["png"].endswith("bokeh_map.png")
    assert main(["bokeh", "--focus-m", "3", "--source-m", "1", "--image-mm", "10,5", "--f-number", "4",
                 "--rays", "4096", "--no-files", "--json", "--device", "cpu"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["sources"][0]["target_mm"] == [10.0, 5.0] and d["settings"]["stop_radius_mm"] < 5.0
    assert "files" not in d


@pytest.mark.parametrize("argv,msg", [
    (["--map", "3by2"], "COLSxROWS"),
    (["--focus-m", "2", "--extension-mm", "1"], "one of"),
    (["--blades", "2"], "iris"),
    (["--map", "2x2", "--field-deg", "5"], "places its own sources"),
    (["--field-deg", "a,b"], "not"),
    (["--spectrum", "D66"], "did you mean"),
    (["--rays", "10"], "--rays"),
    (["--source-m", "10", "--field-deg", "60"], "vignetted"),
])
def test_cli_errors(argv, msg, capsys):
    assert main(["bokeh", "--no-files", "--device", "cpu"] + argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("lensrt: error:") and msg in err and "Traceback" not in err


def test_report_entry_point_bokeh_near_far(dgauss):
    from lensrt.analysis.bokeh.entry import bokeh_near_far
    img = bokeh_near_far(dgauss, 2000.0, grid=(2, 1), pixels=(120, 80), rays=2048, device="cpu")
    assert [r["depth_mm"] for r in img.sources] == pytest.approx([1025.64, 40000.0, 1025.64, 40000.0], rel=1e-4)
    assert img.picture().shape == (80, 120, 3) and img.rays == 4 * 2048


def test_a_map_on_one_device_launches_the_same_for_few_or_many_sources(dgauss):
    # one device: the placement is one launch, every source in one item -- one pupil-box search (2 passes) and
    # one stream (the kernel, the slot fold and, on several CPU cores, the replica sum) -- whatever the map's size
    from lensrt.core.telemetry import measure
    f = focus_lens(dgauss, 2000.0)
    kw = dict(pixels=(180, 120), rays=2048, device="cpu")
    bokeh_map(dgauss, f, grid=(1, 1), depths_mm=[1000.0], **kw)  # pack the lens, load the kernels
    with measure() as few:
        bokeh_map(dgauss, f, grid=(2, 1), depths_mm=[1000.0], **kw)
    with measure() as many:
        img = bokeh_map(dgauss, f, grid=(6, 4), depths_mm=[1000.0, 20000.0], **kw)
    assert len(img.sources) == 48
    assert many.launches == few.launches <= 6  # was 1 + 4 x (Newton steps) + 5 per item of 32 sources


def test_sources_per_item_on_one_device_and_on_several():
    from lensrt.analysis.bokeh.entry import ONE_DEVICE_ITEM_SOURCES, default_sources_per_item
    one, two = LocalExecutor("cpu"), LocalExecutor("cpu,cpu")
    assert default_sources_per_item(108, one) == 108  # the report's map: one item
    assert default_sources_per_item(ONE_DEVICE_ITEM_SOURCES, one) == ONE_DEVICE_ITEM_SOURCES
    assert default_sources_per_item(ONE_DEVICE_ITEM_SOURCES + 1, one) == 65  # two even items
    assert default_sources_per_item(450, one) == 113  # four items
    assert default_sources_per_item(450, two) == 32  # several devices share the work item by item
