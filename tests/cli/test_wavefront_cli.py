"""``lensrt wavefront``: JSON keys with units, --plot files, the printed table, bad options (one line, exit 2)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from lensrt.cli import main

STIG = str(Path(__file__).resolve().parents[1] / "data" / "plano_hyperbolic_f5.toml")


def test_wavefront_json_plot_and_table(capsys, tmp_path):
    out = tmp_path / "wf"
    args = ["wavefront", STIG, "--field-deg", "0,5", "--focus", "paraxial+0.05", "--device", "cpu",
            "--zernike-terms", "15"]
    assert main(args + ["--json", "--plot", "--out", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["reference"] == "chief" and len(d["fields"]) == 2
    w = d["fields"][0]["wavelengths"][0]
    for key in ("rms_waves", "pv_waves", "rms_waves_no_tilt", "pv_waves_no_tilt", "strehl", "strehl_marechal",
                "zernike_noll_waves", "zernike_fringe_waves", "zernike_noll_residual_rms_waves",
                "zernike_normalisation"):
        assert key in w
    assert len(w["zernike_noll_waves"]) == 15 and 0 < w["strehl"] <= 1.0
    assert w["rms_waves"] > 0.1          # 0.05 mm of defocus at f/5: 0.41 waves PV
    assert (out / "wavefront.json").is_file() and (out / "wavefront_0.png").stat().st_size > 1000
    assert main(args[:-2] + ["--reference", "best_fit"]) == 0
    text = capsys.readouterr().out
    assert "Strehl" in text and "reference sphere best_fit" in text and "Noll" in text


@pytest.mark.parametrize("extra, words", [(["--zernike-terms", "2"], "--zernike-terms"),
                                          (["--plot"], "--out"),
                                          (["--pupil-samples", "8"], "--pupil-samples")])
def test_wavefront_bad_options(capsys, extra, words):
    assert main(["wavefront", STIG, "--device", "cpu"] + extra) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0]
