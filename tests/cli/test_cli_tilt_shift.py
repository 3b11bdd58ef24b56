"""``lensrt bokeh``: a tilted/shifted lens (--lens-tilt-deg/--lens-shift-mm) and its bad input; a reflex lens's ring."""
from __future__ import annotations

import json

import numpy as np
import pytest

from lensrt.cli import main


def _run(argv, capsys) -> tuple[int, str, str]:
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        rc = exc.code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return rc, out, err


def _rms_by_row(doc: dict) -> np.ndarray:
    """RMS spot radius of each map source, as rows (y) of the sensor grid."""
    src = doc["sources"]
    ys = sorted({round(s["target_mm"][1], 6) for s in src})
    return np.array([np.mean([s["rms_radius_mm"] for s in src if round(s["target_mm"][1], 6) == y]) for y in ys])


def test_tilted_lens_blurs_one_side_of_the_frame(capsys: pytest.CaptureFixture) -> None:
    base = ["bokeh", "dgauss_50mm_f2", "--focus-m", "1", "--source-m", "1", "--map", "3x3", "--rays", "4096",
            "--batches", "8", "--pixels", "150x100", "--no-files", "--json", "--device", "cpu"]
    rc, out, _ = _run(base, capsys)
    assert rc == 0
    flat = _rms_by_row(json.loads(out))
    rc, out, _ = _run(base + ["--lens-tilt-deg", "6"], capsys)
    assert rc == 0
    doc = json.loads(out)
    tilted = _rms_by_row(doc)
    assert "tilt 6 deg" in doc["settings"]["lens"]
    # focused on the plane of the sources: every spot small; tilted, the plane of focus turns away from
    # the sources' plane: the blur differs from one edge of the frame to the other
    assert flat.max() < 0.05
    assert tilted.max() > 4 * flat.max()
    assert abs(tilted[0] - tilted[-1]) > 2 * flat.max()


@pytest.mark.parametrize("argv,needle", [(["--lens-tilt-deg", "60"], "45 deg"),
                                         (["--lens-shift-mm", "a,b"], "--lens-shift-mm"),
                                         (["--lens-tilt-deg", "nan"], "finite"),
                                         (["--lens-swing-deg", "-50"], "swing -50 deg")])
def test_bad_tilt_shift_gets_one_clear_error(argv, needle, capsys: pytest.CaptureFixture) -> None:
    rc, out, err = _run(["bokeh", "dgauss_50mm_f2", "--rays", "64", "--batches", "2", "--no-files"] + argv, capsys)
    assert rc == 2
    assert needle in err


def test_bokeh_of_a_reflex_lens_reports_its_ring(capsys: pytest.CaptureFixture) -> None:
    from reflex_cases import D_LINE_NM, edge_rays

    from lensrt import load_lens
    rc, out, _ = _run(["bokeh", "reflex_nikkor_500mm_f8", "--focus-m", "inf", "--source-m", "5", "--rays", "2e5",
                       "--spectrum", f"lines:{D_LINE_NM}", "--sampler", "random", "--no-files", "--json",
                       "--device", "cpu"], capsys)
    assert rc == 0
    ring = json.loads(out)["annulus"]
    _, _, r_in, r_out = edge_rays(load_lens("reflex_nikkor_500mm_f8"), 5000.0)
    assert 0 < ring["ratio_stderr"] < 2e-3
    assert abs(ring["ratio"] - r_in / r_out) < 3 * ring["ratio_stderr"]
    # a lens without an obscuration reports no ring
    rc, out, _ = _run(["bokeh", "dgauss_50mm_f2", "--rays", "4096", "--batches", "8", "--no-files", "--json",
                       "--device", "cpu"], capsys)
    assert rc == 0 and "annulus" not in json.loads(out)
