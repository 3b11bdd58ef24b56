"""The render integrator's light splat (point and sphere lights traced from the light side) against camera
paths, and the render's files (EXR, PNG, JSON, raw through the sensor stage)."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from lensrt.render.integrator import render
from lensrt.render.setup import RenderOptions
from lensrt.render.scene.load import loads_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

SPHERE_SCENE = """
[scene]
name = "one lamp"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 3.0
f_number = 4.0
[sensor]
format = "full-frame"
pixels = [48, 32]
[render]
samples_per_pixel = 64
seed = 2
[[light]]
name = "lamp"
type = "sphere"
position = [0.8, 0.3, -8.0]
radius = 0.1
spectrum = { line_nm = 550.0 }
radiance_scale = 1000.0
"""


def test_light_splat_agrees_with_camera_paths():
    """The same small sphere light rendered from the light side and by camera paths: the same total
    power on the sensor (4 standard errors) and the same bokeh disc, in the same place."""
    scene = loads_scene(SPHERE_SCENE)
    s = render(scene, options=RenderOptions(device="cpu"))
    assert s.mode == "light_splat"
    c = render(scene, options=RenderOptions(device="cpu", samples_per_pixel=1024, spp_per_pass=128,
                                            window=(0, 32, 0, 48)))
    assert c.mode == "camera_paths"
    ps, pc = s.regions["image"], c.regions["image"]
    assert abs(ps.value - pc.value) < 4.0 * math.hypot(ps.stderr, pc.stderr)
    ys, yc = s.xyz[..., 1], c.xyz[..., 1]
    rs, cs = np.unravel_index(np.argmax(ys), ys.shape)
    rc, cc = np.unravel_index(np.argmax(yc), yc.shape)
    assert abs(rs - rc) <= 1 and abs(cs - cc) <= 1


LAMPS_SCENE = SPHERE_SCENE.replace('name = "one lamp"', 'name = "three lamps"').replace(
    "spectrum = { line_nm = 550.0 }", "spectrum = { gaussian_nm = 550, fwhm_nm = 20 }") + """
[[light]]
name = "warm"
type = "sphere"
position = [-0.6, -0.2, -6.0]
radius = 0.15
spectrum = "A"
radiance_scale = 20.0
[[light]]
name = "small"
type = "sphere"
position = [0.0, 0.0, -10.0]
radius = 0.08
spectrum = { gaussian_nm = 620, fwhm_nm = 30 }
radiance_scale = 300.0
"""


def test_light_splat_of_many_lights_in_one_launch_agrees_with_camera_paths():
    """Three sphere lights of different sizes and spectra (two gaussians, illuminant A): the splat traces
    them in one launch per pass, each source with its own spectrum and scale; per region
    around each lamp and in all, the power equals the camera paths' (4 standard errors)."""
    scene = loads_scene(LAMPS_SCENE)
    s = render(scene, options=RenderOptions(device="cpu", samples_per_pixel=64))
    assert s.mode == "light_splat" and "3 light(s)" in s.notes[0]
    c = render(scene, options=RenderOptions(device="cpu", samples_per_pixel=1024, spp_per_pass=128,
                                            window=(0, 32, 0, 48)))
    ps, pc = s.regions["image"], c.regions["image"]
    assert abs(ps.value - pc.value) < 4.0 * math.hypot(ps.stderr, pc.stderr)
    ys, yc = s.xyz[..., 1], c.xyz[..., 1]
    es, ec = s.xyz_stderr[..., 1], c.xyz_stderr[..., 1]
    for r0, r1, c0, c1 in ((0, 16, 24, 48), (16, 32, 0, 24)):   # the lamp top right, the warm one bottom left
        a, b = ys[r0:r1, c0:c1].sum(), yc[r0:r1, c0:c1].sum()
        ea, eb = np.sqrt((es[r0:r1, c0:c1] ** 2).sum()), np.sqrt((ec[r0:r1, c0:c1] ** 2).sum())
        assert a > 0 and abs(a - b) < 4.0 * math.hypot(ea, eb) + 1e-3 * b


def test_light_splat_lamp_lands_top_right():
    """The lamp is up (+y) and to the photographer's right (+x): top right of the upright image."""
    scene = loads_scene(SPHERE_SCENE)
    s = render(scene, options=RenderOptions(device="cpu", samples_per_pixel=16))
    y = s.xyz[..., 1]
    r, c = np.unravel_index(np.argmax(y), y.shape)
    assert r < 16 and c >= 24


# ---- outputs and the command line --------------------------------------------------------------

def test_cli_render_writes_fichet_exr_png_json(tmp_path, capsys):
    import json
    import re
    from colour.io.fichet2021 import PATTERN_FICHET2021
    from lensrt.cli import main
    from lensrt.io.exr import read_exr, read_spectral_exr
    out = tmp_path / "d"
    assert main(["render", "default", "--width", "32", "--spp", "4", "--device", "cpu", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "samples/pixel" in text and "paths/s" in text and "+-" in text
    chans, meta = read_exr(out.with_suffix(".exr"))
    spectral = [k for k in chans if k.startswith("S0.")]
    assert len(spectral) == 40 and "S0.555,000000nm" in spectral
    for k in spectral:
        assert re.fullmatch(r"S0\." + PATTERN_FICHET2021, k)
    assert meta["spectralLayoutVersion"] == "1.0" and meta["emissiveUnits"] == "W.m^-2.nm^-1"
    assert {"R", "G", "B", "Y_stderr"} <= set(chans)
    E, wl, _ = read_spectral_exr(out.with_suffix(".exr"))
    assert E.shape == (21, 32, 40) and wl[0] == pytest.approx(385.0) and np.all(E >= 0)
    assert out.with_suffix(".png").is_file()
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["samples_per_pixel"] == 4 and summary["regions_Y_lux"]["centre"]["stderr"] > 0
    assert main(["render", "default", "--width", "16", "--spp", "2", "--device", "cpu", "--json",
                 "-o", str(tmp_path / "j")]) == 0
    assert json.loads(capsys.readouterr().out)["pixels"] == [16, 11]
    assert main(["render", "default", "--window", "1,2,3", "--device", "cpu"]) == 2


def test_sensor_stage_writes_raw_and_camera_png(tmp_path, capsys):
    from lensrt.cli import main
    from lensrt.io.raw import read_raw_exr
    out = tmp_path / "cc"
    assert main(["render", "colorchecker_d65", "--width", "48", "--spp", "2", "--device", "cpu",
                 "-o", str(out)]) == 0
    raw = read_raw_exr(str(out) + "_raw.exr")
    assert raw.dn.shape == (32, 48) and raw.iso == 100 and raw.dn.max() > raw.black_level_dn
    assert Path(str(out) + "_camera.png").is_file()
