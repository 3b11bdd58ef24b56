"""``lensrt compare``: the table, the JSON (units in the keys), the figures, and bad input."""
from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.cli import main

FIGURES = ("layout", "spots", "ray_fans", "opd_fans", "field_curvature_distortion", "grid_distortion",
           "relative_illumination", "longitudinal", "pupils")


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk; fails unless the file is a PNG."""
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


def check_png(path: Path, min_bytes: int = 20_000) -> None:
    assert path.exists() and path.stat().st_size > min_bytes, path
    w, h = png_size(path)
    assert w >= 400 and h >= 300


UNIT_SUFFIXES = ("_mm", "_nm", "_deg", "_percent", "_mm2", "_sr", "_per_mm", "_um", "_waves", "seconds")
#: keys of numbers without a unit (ratios, counts, normalised coordinates, Estimate fields)
DIMENSIONLESS = {"hy", "value", "stderr", "samples", "rays", "rays_per_field", "weights", "zones", "pupil",
                 "cos4", "mapping_factor", "relative_illumination_exit_pupil", "f_number", "working_f_number",
                 "real_working_f_number", "paraxial_magnification", "real_magnification", "primary_nm"}


def _numeric_keys(obj, key: str, out: set[str]) -> None:
    if isinstance(obj, dict):
        for k, v in obj.items():
            _numeric_keys(v, k, out)
    elif isinstance(obj, list):
        for v in obj:
            _numeric_keys(v, key, out)
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        out.add(key)


@pytest.fixture(scope="module")
def codev_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    return out


def test_compare_json_and_plots(codev_run, capsys):
    plots = codev_run / "plots"
    rc = main(["compare", "codev_dblgauss_100mm_f2", "--json", "--rays", "4096", "--spot-rays", "2048",
               "--plot", str(plots), "--device", "cpu"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    # CODE V's printed distortion through the inferred definition, the textbook value beside it
    rows = {(round(r["field_deg"], 6), r["wavelength_nm"]): r for r in d["per_field"]}
    assert round(rows[(10.0, 587.6)]["distortion_codev_percent"], 4) == -0.4976
    assert round(rows[(14.0, 587.6)]["distortion_codev_percent"], 4) == -1.0557
    assert rows[(14.0, 587.6)]["distortion_percent"] == pytest.approx(-1.05221, abs=1e-5)
    assert d["distortion_type_at_largest_field"] == "barrel"
    assert d["focus"]["image_surface_from_paraxial_mm"] == pytest.approx(-0.400269, abs=1e-6)
    assert d["pupils"]["entrance_pupil_z_mm"][1] == pytest.approx(58.7753, abs=5e-5)
    fl = {f["wavelength_nm"]: f for f in d["focal_length"]}
    assert fl[587.6]["paraxial_efl_mm"] == pytest.approx(100.0038, abs=5e-5)
    assert abs(fl[587.6]["real_efl_near_axis_mm"] / fl[587.6]["paraxial_efl_mm"] - 1) < 1e-7
    assert d["spherical_aberration"]["correction"][1] in ("under-corrected", "over-corrected")
    vg = d["vignetting"]
    assert vg["relative_illumination"][0]["samples"] > 0 and vg["relative_illumination"][0]["seconds"] > 0
    assert len(vg["cos4"]) == len(vg["relative_illumination"])
    # units in the keys: every number's key names its unit, or the number is dimensionless by name
    keys: set[str] = set()
    _numeric_keys(d, "", keys)
    assert {"paraxial_height_mm", "distortion_codev_percent", "wavelength_nm", "field_deg",
            "sagittal_focus_from_paraxial_mm", "real_working_f_number", "entrance_pupil_z_mm"} <= keys
    unnamed = sorted(k for k in keys if not k.endswith(UNIT_SUFFIXES) and k not in DIMENSIONLESS)
    assert unnamed == []
    # every figure written, non-empty, a real PNG of a sensible size
    assert sorted(Path(p).name for p in d["figures"]) == sorted(f"{n}.png" for n in FIGURES)
    for n in FIGURES:
        check_png(plots / f"{n}.png")


def test_compare_table_default_lens(capsys):
    rc = main(["compare", "--rays", "2048", "--spot-rays", "1024", "--field", "5", "--wavelength-nm", "550",
               "--device", "cpu"])
    assert rc == 0
    text = capsys.readouterr().out
    for title in ("Focal length (mm)", "Image height at", "Focus on axis", "Longitudinal spherical aberration",
                  "Field curvature at", "Axial colour", "Lateral colour", "Pupils at", "Vignetting and relative",
                  "Spots on the image surface"):
        assert title in text
    assert "5.00 deg" in text and "550" in text


@pytest.mark.parametrize("argv, message", [
    (["--field", "-1"], "must be a non-negative number"),
    (["--field", "200"], "beyond 108 degrees"),
    (["--rays", "10"], "at least 64"),
    (["--wavelength-nm", "50"], "outside 200..20000 nm"),
])
def test_compare_bad_input(argv, message, capsys):
    rc = main(["compare", "--device", "cpu"] + argv)
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("lensrt: error:") and message in err


def test_fisheye_and_finite_object_figures(tmp_path):
    """The fisheye-mapping distortion panel and the finite-object illumination figure."""
    from lensrt.analysis.compare.distortion import distortion_curve
    from lensrt.analysis.compare.focus import field_curvature
    from lensrt.analysis.compare.vignetting import vignetting
    from lensrt.views.plots.analysis import plot_field_curvature_distortion, plot_relative_illumination
    fish = library_lens("fisheye_10mm_f4")
    h = np.linspace(0.0, 1.0, 7)
    p = plot_field_curvature_distortion(tmp_path / "fish.png", field_curvature(fish, h, device="cpu"),
                                        distortion_curve(fish, h, device="cpu"))
    check_png(p)
    macro = library_lens("micro_nikkor_105mm_f2.8_macro")
    v = vignetting(macro, [0.0, 0.5, 1.0], rays=1 << 11, batches=8, device="cpu")
    assert not v.infinite and math.isfinite(v.relative_illumination[-1].value)
    check_png(plot_relative_illumination(tmp_path / "macro_ri.png", v))
