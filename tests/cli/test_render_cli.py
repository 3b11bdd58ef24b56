"""``lensrt render``: --list, --plan (text and JSON), clear errors."""
from __future__ import annotations

import json

import pytest

from lensrt.cli import main

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")


def test_render_list(capsys):
    assert main(["render", "--list"]) == 0
    out = capsys.readouterr().out
    assert "default" in out and "still_life_mesh" in out


def test_render_plan_text_and_json(capsys):
    assert main(["render", "scenes/still_life_mesh.toml", "--plan", "--lens", "codev_dblgauss_100mm_f2"]) == 0
    out = capsys.readouterr().out
    assert "render plan for scene 'still_life_mesh'" in out and "wp.Mesh BVH" in out
    assert "camera_spectral_mesh_shadowed" in out
    assert main(["render", "night_street", "--plan", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["plan"]["mode"] == "light_splat" and d["plan"]["variant"]["name"].startswith("splat_")


def test_render_errors_exit_2(capsys, tmp_path):
    assert main(["render", "no_such_scene", "--plan"]) == 2
    assert "built-in scenes:" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene]\nunits = \"furlong\"\n")
    assert main(["render", str(bad), "--plan"]) == 2
    assert "'units'" in capsys.readouterr().err


def test_band_width_that_cannot_split_the_spectrum_is_noted(capsys, tmp_path):
    """Bands are whole numbers of the scene's wavelength steps that split its range evenly: 20 nm is
    used as asked (no note); 7 nm cannot be, and the result says which width it got instead."""
    base = ["render", "--width", "24", "--spp", "4", "--device", "cpu", "--json"]
    assert main(base + ["--band-nm", "20", "-o", str(tmp_path / "a")]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["band_width_nm"] == 20.0 and not any("asked for" in n for n in d["notes"])
    assert main(base + ["--band-nm", "7", "-o", str(tmp_path / "b")]) == 0
    d = json.loads(capsys.readouterr().out)
    note = [n for n in d["notes"] if "asked for" in n]
    assert d["band_width_nm"] != 7.0 and len(note) == 1 and f"{d['band_width_nm']:g} nm wide" in note[0]
