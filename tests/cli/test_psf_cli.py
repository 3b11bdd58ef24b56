"""``lensrt psf`` and ``lensrt mtf``: JSON keys, the PSF-map EXR (layers, metadata), PNGs, errors."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lensrt.cli import main
from lensrt.io.exr import read_exr
from lensrt.views.psf_files import read_psf_map_exr

LENS = "cooke_triplet_50mm_f5"
FAST = ["--device", "cpu", "--rays", "2e4", "--pixels", "32", "--batches", "8"]


def run_json(capsys, args: list[str]) -> dict:
    assert main(args + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_psf_json_reports_rays_seconds_and_standard_errors(capsys):
    d = run_json(capsys, ["psf", LENS, "--field", "0,1", "--focus", "best"] + FAST)
    assert d["lens"] and d["setup"]["focus"]["base"] == "best" and len(d["fields"]) == 2
    for f in d["fields"]:
        assert f["kind"] == "geometric" and f["samples"] == 20000 and f["seconds"] > 0 and f["batches"] == 8
        for key in ("rms_radius_mm", "centroid_x_mm", "centroid_y_mm", "ee50_radius_mm", "ee80_radius_mm"):
            e = f["estimates"][key]
            assert e["stderr"] >= 0 and e["samples"] == 20000 and "jackknife" in e["method"]
        assert 0 < f["estimates"]["rms_radius_mm"]["stderr"] < 0.1 * f["estimates"]["rms_radius_mm"]["value"]
        assert len(f["estimates"]["mtf_sagittal"]["value"]) == 3  # 10/20/40 lp/mm on full frame
        assert f["metadata"]["sampler"] == "sobol" and f["metadata"]["status_counts"]["OK"] > 0
    assert d["fields"][1]["reference_mm"][1] > 10  # the full field lands high on the sensor


def test_psf_map_exr_layers_metadata_and_png(capsys, tmp_path):
    out = tmp_path / "map"
    assert main(["psf", LENS, "--grid", "3x3", "--sensor", "mft", "--out", str(out)] + FAST) == 0
    text = capsys.readouterr().out
    assert "r2c2" in text and "wrote" in text
    chans, meta = read_exr(out / "psf.exr")
    names = [f"r{r}c{c}" for r in range(3) for c in range(3)]
    assert set(chans) == {f"{n}.{c}" for n in names for c in ("psf", "stderr")}
    psfs, m = read_psf_map_exr(out / "psf.exr")
    assert m["lensrt:grid"] == "3x3" and m["lensrt:sensor"] == "mft" and m["lensrt:layers"] == names
    assert m["lensrt:lens"] == meta["lensrt:lens"] and m["lensrt:rays"] == [20000] * 9 and m["lensrt:seed"] == 0
    assert len(m["lensrt:pitch_um"]) == 9 and len(m["lensrt:wavelength_nm"]) == 3
    fields = m["lensrt:fields"]
    assert fields[0]["target_mm"] == [-8.65, 6.5] and fields[8]["target_mm"] == [8.65, -6.5]
    for name, rec in zip(names, fields):
        a = psfs[name].astype(np.float64)
        assert a.shape == (32, 32) and np.all(a >= 0)
        # unit volume: the sum times the pixel area is the energy on the grid
        assert math.isclose(a.sum() * (rec["pitch_um"] * 1e-3) ** 2, rec["energy_on_grid"], rel_tol=1e-5)
        assert rec["estimates"]["rms_radius_mm"]["stderr"] > 0 and rec["seed"] is not None
        assert np.hypot(*(np.asarray(rec["reference_mm"]) - rec["target_mm"])) < 1e-3
    assert len({rec["seed"] for rec in fields}) == 9  # one seed per field, from the job seed
    png = out / "psf.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    d = json.loads((out / "psf.json").read_text())
    assert d["grid"] == [3, 3] and len(d["fields"]) == 9


def test_psf_spectrum_and_diffraction_options(capsys):
    d = run_json(capsys, ["psf", LENS, "--field", "0", "--spectrum", "D65", "--band", "450:650"] + FAST)
    spec = d["setup"]["spectrum"]
    assert spec["name"] == "D65 450-650 nm" and len(spec["wavelengths_nm"]) == 7 and spec["band_nm"] == [450, 650]
    d = run_json(capsys, ["psf", LENS, "--field", "0", "--method", "diffraction", "--wavelength-nm", "550",
                          "--focus", "best", "--device", "cpu", "--pixels", "64"])
    f = d["fields"][0]
    assert f["kind"].startswith("diffraction") and f["metadata"]["method_reason"]
    assert f["metadata"]["sampling"][0]["pitch_um"] > 0 and f["estimates"]["rms_radius_mm"]["stderr"] == 0


def test_mtf_json_plots_and_through_focus(capsys, tmp_path):
    out = tmp_path / "mtf"
    d = run_json(capsys, ["mtf", LENS, "--field", "0,1", "--method", "geometric", "--through-focus", "0.05:5",
                          "--n-freqs", "9", "--pixel-pitch-um", "5", "--out", str(out)] + FAST)
    assert d["detector"]["nyquist_cpmm"] == 100.0 and d["reference_freqs_cpmm"] == [10.0, 20.0, 40.0]
    for f in d["fields"]:
        assert len(f["freqs_cpmm"]) == 9 and f["freqs_cpmm"][-1] == 200.0
        for k in ("sagittal", "tangential"):
            sys_ = np.asarray(f[f"system_{k}"])
            assert np.allclose(sys_, np.asarray(f[f"lens_{k}"]) * f[f"olpf_{k}"] * np.asarray(f[f"detector_{k}"]))
            assert len(f[f"lens_{k}_stderr"]) == 9
    v = d["mtf_vs_field"]
    assert len(v["image_height_mm"]) == 2 and np.shape(v["sagittal"]) == (2, 3) and np.shape(v["sagittal_stderr"]) == (2, 3)
    tf = d["through_focus"][0]
    assert len(tf["focus_mm"]) == 5 and np.shape(tf["tangential"]) == (5, 3) and tf["method"] == "geometric"
    for name in ("mtf.png", "mtf_system.png", "mtf_field.png", "mtf_focus.png", "psf.exr", "mtf.json",
                 "mtf_focus_spots_0.png", "mtf_focus_spots_1.png"):
        assert (out / name).stat().st_size > 1000, name
    # through-focus spots beside it (their physics: tests/analysis/psf/test_psf_real.py)
    sp = d["through_focus_spots"][0]
    assert len(sp["focus_mm"]) == 5 and sp["rays"] > 0
    assert np.all(np.isfinite(sp["rms_radius_mm"])) and np.all(np.asarray(sp["rms_radius_mm"]) > 0)


def test_mtf_of_a_psf_wider_than_the_grid_cap_stops_at_its_grid_nyquist(capsys, tmp_path, monkeypatch):
    """A wide PSF whose grid would need more pixels than the per-batch histogram cap gets a coarser
    pitch: its MTF curve stops at that grid's Nyquist frequency (NaN / null after), all curves stay on
    one frequency axis, and the plots and JSON are written (this crashed in matplotlib, and a 4096^2 x
    32-batch histogram took minutes, on the 28 mm f/1.4's corner)."""
    from lensrt.analysis.psf import geometric as raypsf
    monkeypatch.setattr(raypsf, "HIST_BYTES_MAX", 8 * 8 * 40 * 40)  # 8 batches: at most 40 pixels a side
    out = tmp_path / "mtf"
    d = run_json(capsys, ["mtf", LENS, "--field", "0,1", "--method", "geometric", "--n-freqs", "17",
                          "--pixel-pitch-um", "2", "--out", str(out)] + FAST)
    ends = []
    for f in d["fields"]:
        assert len(f["freqs_cpmm"]) == 17 and f["freqs_cpmm"][-1] == 500.0
        lens_s = [math.nan if v is None else v for v in f["lens_sagittal"]]
        assert len(lens_s) == 17 and len(f["system_tangential"]) == 17 and len(f["diffraction_limit"]) == 17
        n_ok = int(np.sum(np.isfinite(lens_s)))
        assert np.all(np.isfinite(lens_s[:n_ok])) and not np.any(np.isfinite(lens_s[n_ok:]))  # a prefix
        assert f["curve_ends_cpmm"] == pytest.approx(f["freqs_cpmm"][n_ok - 1])
        ends.append(f["curve_ends_cpmm"])
    for f, psf in zip(d["fields"], d["psf"]):
        assert psf["grid"]["shape"][0] <= 40
        assert f["curve_ends_cpmm"] <= 0.5e3 / psf["grid"]["pitch_um"] * (1 + 1e-9)  # the grid's Nyquist
    assert min(ends) < 500.0  # a wide field's curve stops early
    assert max(len(f["metadata"].get("mtf_beyond_grid_nyquist_cpmm", [])) for f in d["psf"]) > 0
    for name in ("mtf.png", "mtf_system.png", "mtf_field.png", "mtf.json"):
        assert (out / name).stat().st_size > 1000, name


def test_psf_grid_cap_keeps_per_batch_histograms_within_the_memory_cap():
    from lensrt.analysis.psf import geometric as raypsf
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.loading import load_lens
    setup = make_setup(load_lens(LENS), None, "image", "cpu", max_pitch_um=1.0, batches=32, pixels=64)
    pitch_um, pixels, half = raypsf._window(setup, 5.0)  # a 10 mm wide PSF would need 11000 pixels
    assert pixels == 1024 and 32 * 8 * pixels ** 2 <= raypsf.HIST_BYTES_MAX
    assert pitch_um == pytest.approx(2.0 * half * 1e3 / pixels) and pixels * pitch_um >= 2e3 * half
    pitch_um, pixels, _ = raypsf._window(setup, 0.1)  # a narrower one gets the pitch asked for
    assert pitch_um == pytest.approx(1.0) and pixels == 222
    pitch_um, pixels, _ = raypsf._window(setup, 0.01)  # a narrow one keeps its 64 pixels, finer
    assert pitch_um < 1.0 and pixels == 64


def test_converge_prints_slopes(capsys, tmp_path):
    assert main(["psf", LENS, "--field", "0.7", "--converge", "--rays", "16384", "--batches", "8", "--device", "cpu",
                 "--wavelength-nm", "587.6", "--pixels", "32", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "fitted log-log slopes" in text and "stratified" in text
    d = json.loads((tmp_path / "converge.json").read_text())
    assert len(d["slopes"]) == 6 and {s["precision"] for s in d["slopes"]} == {"float32", "float64"}
    random = [s for s in d["slopes"] if s["sampler"] == "random"]
    assert all(-0.8 < s["slope_stderr_vs_rays"] < -0.25 for s in random)  # plain MC: about -1/2
    assert (tmp_path / "converge.png").stat().st_size > 10_000


@pytest.mark.parametrize("args,message", [
    (["--focus", "sideways"], "bad focus"),
    (["--spectrum", "D66"], "unknown illuminant"),
    (["--grid", "3x3", "--field", "0"], "give one way"),
    (["--grid", "3x3", "--sensor", "36x24", "--focus", "paraxial", "--field-deg", "1"], "give one way"),
    (["--image-height-mm", "500"], "beyond the lens's coverage"),
])
def test_bad_options_are_one_line_errors(capsys, args, message):
    assert main(["psf", LENS, "--device", "cpu"] + args) == 2
    err = capsys.readouterr().err
    assert err.startswith("lensrt: error:") and message in err and "Traceback" not in err
