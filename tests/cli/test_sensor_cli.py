"""`lensrt sensor ...` end to end through the CLI entry point (small frames)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from lensrt.cli import main
from lensrt.io.exr import write_spectral_exr
from lensrt.io.raw import read_raw_exr


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_presets_and_show(capsys):
    rows = _json(capsys, ["sensor", "presets", "--json"])
    assert [r["preset"] for r in rows] == ["fullframe_24mp", "apsc_16mp", "phone_12mp"]
    show = _json(capsys, ["sensor", "show", "--preset", "phone_12mp", "--json"])
    assert show["derived"]["srgb_image_dynamic_range_stops"] == pytest.approx(11.69, abs=0.01)
    assert show["derived"]["sos_iso_at_gain_1"] > 0
    assert main(["sensor", "show"]) == 0
    assert "unity gain" in capsys.readouterr().out


def test_characterize_json_and_plots(capsys, tmp_path):
    out = _json(capsys, ["sensor", "characterize", "--size", "64x64", "--levels", "20", "--stack", "4", "--json",
                         "--plot", str(tmp_path)])
    assert out["g_e_per_dn"] == pytest.approx(out["expected"]["g_e_per_dn"], rel=0.05)
    assert (tmp_path / "photon_transfer.png").is_file() and (tmp_path / "snr.png").is_file()


def test_expose_colorchecker_writes_everything(capsys, tmp_path):
    files = {k: tmp_path / v for k, v in
             {"raw": "raw.exr", "out": "cc.png", "out16": "cc.tif", "linear": "lin.exr", "hist": "hist.png"}.items()}
    argv = ["sensor", "expose", "--colorchecker", "--patch-px", "16", "--json"]
    for k, p in files.items():
        argv += [f"--{k}", str(p)]
    rep = _json(capsys, argv)
    assert rep["delta_e2000"]["mean"] < 2.0
    assert all(p.is_file() for p in files.values())
    raw = read_raw_exr(files["raw"])
    assert raw.dn.shape == (64, 96) and raw.cfa.name == "RGGB"


def test_expose_spectral_exr_file(capsys, tmp_path):
    wl = np.linspace(400, 700, 16)
    E = np.full((20, 30, wl.size), 2e-3, np.float32)
    write_spectral_exr(tmp_path / "E.exr", E, wl)
    rep = _json(capsys, ["sensor", "expose", "--irradiance", str(tmp_path / "E.exr"), "--exposure-s", "0.01",
                         "--iso", "400", "--set", "cfa=XTRANS", "--json", "--out", str(tmp_path / "o.png")])
    assert rep["cfa"] == "XTRANS" and rep["iso"] == 400 and rep["raw_mean_dn"] > rep["black_level_dn"]
    np.savez(tmp_path / "E.npz", irradiance=E, wavelength_nm=wl)
    rep2 = _json(capsys, ["sensor", "expose", "--irradiance", str(tmp_path / "E.npz"), "--exposure-s", "0.01",
                          "--iso", "400", "--set", "cfa=XTRANS", "--json"])
    assert rep2["raw_mean_dn"] == pytest.approx(rep["raw_mean_dn"], rel=0.01)


@pytest.mark.parametrize("argv", [["sensor", "show", "--preset", "nope"],
                                  ["sensor", "show", "--set", "fill_factor=2"],
                                  ["sensor", "expose", "--flat", "10", "--iso", "10"],
                                  ["sensor", "expose", "--irradiance", "missing.npz"],
                                  ["sensor", "expose", "--flat", "10", "--wb", "grey"]])
def test_bad_input_is_one_line_error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("lensrt: error:") and "Traceback" not in err
