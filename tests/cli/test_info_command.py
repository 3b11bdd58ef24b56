"""``lensrt info``: the table, the JSON keys of issue 3, and errors as one line."""
from __future__ import annotations

import json
import math

import pytest

from lensrt import load_lens
from lensrt.cli import main
from lensrt.paraxial import first_order
from lensrt.paraxial import photographic as ph

ISSUE_KEYS = ("wavelength_nm object_distance_mm efl_mm front_focal_length_mm rear_focal_length_mm bfl_mm ffl_mm "
              "front_focal_z_mm rear_focal_z_mm front_principal_z_mm rear_principal_z_mm entrance_pupil_z_mm "
              "entrance_pupil_diameter_mm exit_pupil_z_mm exit_pupil_diameter_mm pupil_magnification f_number "
              "working_f_number image_z_mm magnification lagrange_invariant petzval_sum_per_mm total_track_mm "
              "half_field_deg paraxial_image_height_mm seidel").split()
SEIDEL_KEYS = ("spherical_mm", "coma_mm", "astigmatism_mm", "petzval_mm", "distortion_mm", "axial_colour_mm",
               "lateral_colour_mm")


@pytest.fixture
def codev(library_dir):
    return str(library_dir / "codev_dblgauss_100mm_f2.toml")


def _json(capsys, *argv) -> dict:
    assert main(["info", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_json_has_the_issue_keys_and_null_at_infinity(capsys, codev) -> None:
    d = _json(capsys, codev)
    assert set(ISSUE_KEYS) <= set(d)
    assert set(SEIDEL_KEYS) <= set(d["seidel"])
    assert d["object_distance_mm"] is None
    assert d["efl_mm"] == pytest.approx(100.0038, abs=5e-5)
    assert d["third_order_transverse"]["SA_mm"] == pytest.approx(-0.306954, abs=5e-7)
    assert "sensor" not in d


def test_json_at_a_finite_distance_and_wavelength_with_a_sensor(capsys, codev) -> None:
    d = _json(capsys, codev, "--wavelength-nm", "486.1", "--object-distance-mm", "1200", "--sensor", "aps-c")
    fo = first_order(load_lens(codev), 486.1, 1200.0)
    assert d["wavelength_nm"] == 486.1 and d["object_distance_mm"] == 1200.0
    assert d["image_z_mm"] == pytest.approx(fo.image_z_mm, rel=1e-15)
    assert d["magnification"] == pytest.approx(fo.magnification, rel=1e-15)
    s = d["sensor"]
    assert s["crop_factor"] == pytest.approx(ph.sensor_format("aps-c").crop_factor, rel=1e-15)
    assert s["coc_mm"] == 0.020
    assert s["afov_deg"]["horizontal"] == pytest.approx(
        math.degrees(2 * math.atan(23.6 / (2 * fo.bellows_factor * fo.efl_mm))), rel=1e-14)
    dof = s["depth_of_field"]
    assert dof["focus_distance_from_entrance_pupil_mm"] == pytest.approx(1200.0 + fo.entrance_pupil_z_mm, rel=1e-15)
    assert dof["near_z_mm"] > -1200.0 > dof["far_z_mm"]
    assert dof["near_z_mm"] == pytest.approx(fo.entrance_pupil_z_mm - dof["near_from_entrance_pupil_mm"], rel=1e-15)


def test_json_infinite_far_limit_is_null(capsys, codev) -> None:
    d = _json(capsys, codev, "--object-distance-mm", "inf", "--sensor", "36x24", "--coc-mm", "0.05")
    dof = d["sensor"]["depth_of_field"]
    assert dof["far_z_mm"] is None and dof["total_mm"] is None and dof["focus_distance_from_entrance_pupil_mm"] is None
    assert d["sensor"]["coc_mm"] == 0.05


def test_readable_table(capsys, codev) -> None:
    assert main(["info", codev, "--sensor", "full-frame"]) == 0
    out = capsys.readouterr().out
    for text in ("100.0038", "61.4875", "-29.3208", "57.9120 / 50.0000", "Seidel sums", "-0.306954",
                 "crop factor 1.0000", "depth of field"):
        assert text in out


@pytest.mark.parametrize("argv, message", [
    (["--sensor", "vistavision"], "unknown sensor format"),
    (["--wavelength-nm", "0.55"], "outside 200..20000 nm"),
    (["--object-distance-mm", "-3"], "must be positive"),
    (["--coc-mm", "0.03"], "needs --sensor"),
])
def test_bad_input_is_one_error_line(capsys, codev, argv, message) -> None:
    assert main(["info", codev, *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lensrt: error:") and message in err and "Traceback" not in err
