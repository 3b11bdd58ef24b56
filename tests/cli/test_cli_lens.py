"""``lensrt lens show|convert|list`` on the reference files and the format options."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest

from lensrt.cli import main
from lensrt.prescription.formats import read_lens


def run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def test_show_default_lens(capsys: pytest.CaptureFixture) -> None:
    rc, out, _ = run(["lens", "show"], capsys)
    assert rc == 0
    assert "Double Gauss 50 mm f/2" in out and "n@587.562nm" in out and "model 1.67000/47.10" in out


@pytest.mark.parametrize("name", ["cooke_triplet.zmx", "ag_dblgauss.seq", "dgauss.50mm.dat"])
def test_show_reference_files(data_dir: Path, name: str, capsys: pytest.CaptureFixture) -> None:
    rc, out, err = run(["lens", "show", str(data_dir / name)], capsys)
    assert rc == 0 and not err
    rc, out, _ = run(["lens", "show", str(data_dir / name), "--json"], capsys)
    doc = json.loads(out)
    lens = read_lens(data_dir / name)
    assert len(doc["surfaces"]) == lens.n_surfaces
    assert doc["wavelengths_nm"] == list(lens.wavelengths.nm)


def test_show_indices_at_primary_wavelength(data_dir: Path, capsys: pytest.CaptureFixture) -> None:
    rc, out, _ = run(["lens", "show", str(data_dir / "ag_dblgauss.seq"), "--json"], capsys)
    rows = json.loads(out)["surfaces"]
    n = [r["n@587.6nm"] for r in rows if r["material"] != "air"]
    assert n[0] == pytest.approx(1.622292, abs=5e-7)  # N-SSK2, listing at 587.6 nm


def test_convert_and_show_again(data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out_path = tmp_path / "triplet.toml"
    rc, out, _ = run(["lens", "convert", str(data_dir / "cooke_triplet.zmx"), str(out_path)], capsys)
    assert rc == 0 and "wrote" in out
    assert read_lens(out_path) == read_lens(data_dir / "cooke_triplet.zmx")
    assert run(["lens", "show", str(out_path)], capsys)[0] == 0
    rc, _, err = run(["lens", "convert", str(data_dir / "cooke_triplet.zmx"), str(tmp_path / "x.zmx")], capsys)
    assert rc == 2 and "must be a .toml file" in err


def test_format_option(data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    odd = tmp_path / "triplet.lens"
    shutil.copy(data_dir / "cooke_triplet.zmx", odd)
    assert run(["lens", "show", str(odd), "--format", "zemax"], capsys)[0] == 0
    # content sniffing also finds it; a wrong --format is an error
    assert run(["lens", "show", str(odd)], capsys)[0] == 0
    rc, _, err = run(["lens", "show", str(odd), "--format", "codev"], capsys)
    assert rc == 2 and "holds a Zemax" in err


def test_pbrt_options(data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out_path = tmp_path / "dg.toml"
    rc, _, _ = run(["lens", "convert", str(data_dir / "dgauss.dat"), str(out_path), "--pbrt-thickness", "previous",
                    "--pbrt-field-deg", "22"], capsys)
    assert rc == 0
    lens = read_lens(out_path)
    assert math.degrees(lens.fields.y[-1]) == pytest.approx(22.0)
    assert lens.surfaces[0].thickness_mm == 7.52
    rc, _, err = run(["lens", "show", str(data_dir / "dgauss.dat"), "--pbrt-thickness", "next"], capsys)
    assert rc == 2 and "cross" in err  # 'next' on an axpos table: a 0 mm thick first element
    rc, _, err = run(["lens", "show", str(data_dir / "dgauss.50mm.dat"), "--pbrt-thickness", "previous"], capsys)
    assert rc == 2 and "first row's axial distance" in err


def test_list(capsys: pytest.CaptureFixture) -> None:
    rc, out, _ = run(["lens", "list"], capsys)
    assert rc == 0 and "dgauss_50mm_f2" in out and "155.9 deg" in out


def test_warnings_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    import warnings
    text = (Path(__file__).resolve().parents[1] / "data" / "cooke_triplet.zmx").read_text().replace("GLAS F2 ", "GLAS MYFLINT ")
    p = tmp_path / "odd.zmx"
    p.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        rc, out, err = run(["lens", "show", str(p)], capsys)
    assert rc == 2 and "MYFLINT" in err and "--glass-model-fallback" in err  # an unknown glass: one error
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        rc, out, err = run(["lens", "show", str(p), "--glass-model-fallback"], capsys)
    assert rc == 0 and "warning [glass_model]" in out
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines and all(ln.startswith("lensrt: warning: ") for ln in lines)
    assert "MYFLINT" in lines[0] and "Traceback" not in err
