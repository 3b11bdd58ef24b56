"""Scene files: every built-in scene loads; units, photometry, textures, meshes; clear errors."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import LensrtError
import lensrt.colour as sp
from lensrt.render.scene.load import builtin_scenes, load_scene, loads_scene
from lensrt.render.scene.textures import pattern_level, texture_value_ref
from lensrt.units import LUMINOUS_EFFICACY_LM_PER_W as KM

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

SCENES = Path(__file__).resolve().parents[2] / "scenes"
BASE = """
[scene]
units = "{units}"
[camera]
focus_distance = 2
[sensor]
pixels = [60, 40]
"""


def scene(body: str, units: str = "m", path: Path | None = None):
    return loads_scene(BASE.format(units=units) + body, path)


LIT_PLANE = """
[illumination]
spectrum = "D65"
illuminance_lux = 1000
[[plane]]
name = "card"
center = [0, 0, -2]
size = [0.4, 0.2]
reflectance = 0.5
"""


def test_builtin_scenes_all_load():
    names = {p.stem for p in builtin_scenes()}
    assert {"default", "night_street", "resolution_chart", "colorchecker_d65", "colorchecker_a",
            "depth_of_field", "still_life_mesh", "sodium_star_test"} <= names
    for p in builtin_scenes():
        s = load_scene(p)
        assert s.emission_spectra() and s.summary()
    assert load_scene(None).name == "default"
    assert load_scene("night_street").name == "night_street"


def test_units_convert_to_mm():
    for units, k in (("m", 1000.0), ("cm", 10.0), ("mm", 1.0)):
        s = scene(LIT_PLANE.replace("[0, 0, -2]", "[0, 0, -3]"), units)
        assert s.planes[0].center_mm[2] == pytest.approx(-3 * k)
        assert s.planes[0].size_mm == pytest.approx((0.4 * k, 0.2 * k))
        assert s.camera.focus_distance_mm == pytest.approx(2 * k)


def test_camera_and_sensor_defaults_and_formats():
    s = scene(LIT_PLANE + '[spectral]\nstep_nm = 10\n')
    assert s.camera.lens == "dgauss_50mm_f2" and s.camera.lens_path is None
    assert s.sensor.width_mm == 36 and s.sensor.pixel_pitch_um == pytest.approx(600.0)
    assert s.grid.n == 41
    s = loads_scene(LIT_PLANE + '[sensor]\nformat = "aps-c"\npixels = 2360\n[camera]\nfocus_extension_mm = 1.5\n')
    assert (s.sensor.width_mm, s.sensor.height_mm, s.sensor.pixels_y) == (23.6, 15.7, 1570)
    assert s.camera.focus_distance_mm is None and s.camera.focus_extension_mm == 1.5
    assert math.isinf(loads_scene(LIT_PLANE).camera.focus_distance_mm)          # default: infinity


def test_photometric_normalisations():
    g = sp.DEFAULT_GRID
    s = scene("""
[[light]]
type = "sphere"
position = [0, 0, -5]
radius = 0.01
spectrum = "LED-B3"
luminance_cd_m2 = 2e4
[[light]]
type = "point"
position = [0, 0, -5]
spectrum = { blackbody_K = 2700 }
flux_lm = 800
[[light]]
type = "sphere"
position = [0, 1, -5]
radius = 0.1
spectrum = "A"
flux_lm = 1000
[illumination]
spectrum = "FL2"
illuminance_lux = 500
[background]
spectrum = "D65"
radiance_scale = 0.01
""")
    assert sp.luminous_value(s.sphere_lights[0].radiance.values, g) == pytest.approx(2e4, rel=1e-9)
    assert sp.luminous_value(s.point_lights[0].intensity.values, g) == pytest.approx(800 / (4 * math.pi), rel=1e-9)
    # a Lambertian sphere of flux F: L = F / (pi * 4 pi r^2), r in metres
    assert sp.luminous_value(s.sphere_lights[1].radiance.values, g) == pytest.approx(
        1000 / (math.pi * 4 * math.pi * 0.1 ** 2), rel=1e-9)
    assert sp.luminous_value(s.illumination.values, g) == pytest.approx(500, rel=1e-9)
    assert np.allclose(s.background.values, 0.01 * sp.spectrum("D65", g))
    assert s.sphere_lights[0].radiance.unit == "W/(m^2 sr nm)"
    assert s.point_lights[0].intensity.unit == "W/(sr nm)"


def test_line_spectrum_is_monochromatic_and_absolute():
    s = scene("""
[[light]]
type = "point"
position = [0, 0, -5]
spectrum = { line_nm = 555 }
intensity_cd = 683.002
""")
    assert s.line_nm == 555
    v555 = np.interp(555, sp.DEFAULT_GRID.nm, sp.photopic_v())
    assert s.point_lights[0].intensity.values[0] == pytest.approx(KM / KM / v555)     # 1 W/sr
    assert s.point_lights[0].intensity.unit == "W/(sr)"
    with pytest.raises(LensrtError, match="line spectra"):
        scene("""
[[light]]
type = "point"
position = [0, 0, -5]
spectrum = { line_nm = 555 }
intensity_cd = 1
[[light]]
type = "point"
position = [0, 0, -5]
spectrum = "D65"
intensity_cd = 1
""")


def test_reflectance_forms():
    g = sp.DEFAULT_GRID
    s = scene(LIT_PLANE.replace("reflectance = 0.5", 'reflectance = { colorchecker = "blue" }'))
    assert np.allclose(s.planes[0].tint.values, sp.colorchecker_reflectances()[12])
    s = scene(LIT_PLANE.replace("reflectance = 0.5", "reflectance = { colorchecker = 13 }"))
    assert np.allclose(s.planes[0].tint.values, sp.colorchecker_reflectances()[12])
    s = scene(LIT_PLANE.replace("reflectance = 0.5", "reflectance = { srgb = [1.0, 0.5, 0.0] }"))
    assert np.allclose(s.planes[0].tint.values, sp.linear_rgb_to_reflectance(sp.srgb_decode(np.array([1, .5, 0])), g))
    s = scene(LIT_PLANE.replace("reflectance = 0.5", "reflectance = { nm = [400, 700], values = [0.1, 0.9] }"))
    assert s.planes[0].tint.values[0] == pytest.approx(0.1) and s.planes[0].tint.values[-1] == pytest.approx(0.9)


def test_texture_patterns_geometry():
    s = scene("""
[illumination]
spectrum = "D65"
illuminance_lux = 1000
[[plane]]
center = [0, 0, -2]
size = [0.2, 0.2]
texture = "slanted_edge"
angle_deg = 5
[[plane]]
center = [0.5, 0, -2]
size = [0.6, 0.4]
texture = "grid"
cells = [6, 4]
line_width = 0.1
[[plane]]
center = [-0.5, 0, -2]
size = [0.2, 0.2]
texture = "siemens_star"
spokes = 8
""")
    edge, grid, star = s.planes
    assert pattern_level(edge.texture, edge.size_mm, 0.0, 0.0) == 0.2              # dark square in the middle
    assert pattern_level(edge.texture, edge.size_mm, 90.0, 90.0) == 0.8            # light corner
    # the square's right edge is tilted by 5 deg: crossing points at t = +-40 mm
    x_edge = 50.0 / math.cos(math.radians(5))
    for t in (-40.0, 40.0):
        x = x_edge - t * math.tan(math.radians(5))     # s' = cos a s + sin a t = half side
        assert pattern_level(edge.texture, edge.size_mm, x - 0.1, t) == 0.2
        assert pattern_level(edge.texture, edge.size_mm, x + 0.1, t) == 0.8
    # grid lines on the cell borders from the left edge: every 100 mm, 0.1 * 100 mm wide
    assert pattern_level(grid.texture, grid.size_mm, -300.0 + 100.0 * 2 + 4.0, 50.0) == 0.05
    assert pattern_level(grid.texture, grid.size_mm, -300.0 + 100.0 * 2 + 6.0, 50.0) == 0.8
    # star: 8 cycles -> 16 sectors of 22.5 deg, the first (0..22.5 deg) light
    r = 50.0
    for k in range(16):
        a = math.radians(22.5 * k + 11.25)
        assert pattern_level(star.texture, star.size_mm, r * math.cos(a), r * math.sin(a)) == (0.8 if k % 2 == 0
                                                                                                else 0.05)


def test_colorchecker_layout():
    g = sp.DEFAULT_GRID
    s = scene(LIT_PLANE.replace('reflectance = 0.5', 'texture = "colorchecker"').replace("[0.4, 0.2]", "[0.6, 0.4]"))
    pl = s.planes[0]
    cc = sp.colorchecker_reflectances()
    px, py = 100.0, 100.0
    for row in range(4):
        for col in range(6):
            x, y = -300 + (col + 0.5) * px, 200 - (row + 0.5) * py
            v = texture_value_ref(pl.texture, pl.size_mm, x, y, 550.0, g)
            assert v == pytest.approx(np.interp(550.0, g.nm, cc[row * 6 + col]))
    frame = texture_value_ref(pl.texture, pl.size_mm, -300 + 1.0, 200 - 1.0, 550.0, g)
    assert frame == pytest.approx(np.interp(550.0, g.nm, cc[23]))                    # the black patch


def test_image_texture_orientation(tmp_path):
    from PIL import Image
    img = np.zeros((2, 3, 3), dtype=np.uint8)
    img[0, 0] = (255, 0, 0)            # top-left red
    img[1, 2] = (0, 0, 255)            # bottom-right blue
    Image.fromarray(img).save(tmp_path / "t.png")
    s = scene(LIT_PLANE.replace("reflectance = 0.5", 'texture = "image"\nimage = "t.png"'),
              path=tmp_path / "s.toml")
    tex = s.planes[0].texture
    assert tex.image_linear.shape == (2, 3, 3)
    g = sp.DEFAULT_GRID
    red = sp.linear_rgb_to_reflectance(np.array([1.0, 0, 0]), g)
    # top-left texel centre: s = -w/2 + w/6, t = h/2 - h/4
    v = texture_value_ref(tex, (400.0, 200.0), -200 + 400 / 6, 100 - 50, g.nm, g)
    assert np.allclose(v, red, atol=1e-6)


def test_mesh_loading_and_transform():
    s = load_scene(SCENES / "still_life_mesh.toml")
    torus = s.meshes[0]
    assert torus.n_triangles == 4096
    lo, hi = torus.vertices_mm.min(axis=0), torus.vertices_mm.max(axis=0)
    # the torus stands on y = 0 in the model; placed at (-0.25, -0.12, -1.2) m
    assert lo[1] == pytest.approx(-120.0, abs=1e-6) and hi[1] == pytest.approx(-120 + 220.0, abs=1e-3)
    assert 0.5 * (lo[0] + hi[0]) == pytest.approx(-250.0, abs=1e-3)
    assert {m.source.rsplit(".", 1)[1] for m in s.meshes} == {"ply", "obj", "stl", "glb"}


def test_mesh_rotation_and_scale(tmp_path):
    import trimesh
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(tmp_path / "box.stl")
    s = loads_scene(BASE.format(units="cm") + LIT_PLANE + """
[[mesh]]
file = "box.stl"
scale = 10
rotation_deg = [0, 90, 0]
position = [0, 0, -100]
reflectance = 0.3
""", tmp_path / "s.toml")
    v = s.meshes[0].vertices_mm
    ext = v.max(axis=0) - v.min(axis=0)
    assert ext == pytest.approx([100.0, 100.0, 200.0])      # 2 x 1 x 1 box x 10 cm, turned about y
    assert v.mean(axis=0)[2] == pytest.approx(-1000.0)


@pytest.mark.parametrize("body, pattern", [
    (LIT_PLANE.replace("size", "sise"), r"unknown key 'sise'.*did you mean 'size'"),
    (LIT_PLANE.replace("[0.4, 0.2]", "[0.4, -0.2]"), r"'size'.*positive"),
    (LIT_PLANE.replace("[0, 0, -2]", "[0, 0, 0.5]"), r"z = 0.5 m.*z < 0"),
    (LIT_PLANE.replace("reflectance = 0.5", "reflectance = 1.5"), r"outside \[0, 1\]"),
    (LIT_PLANE.replace('"D65"', '"D66"'), r"unknown illuminant 'D66'"),
    (LIT_PLANE.replace("illuminance_lux", "luminance_cd_m2"), r"illuminance_lux"),
    (LIT_PLANE.replace("reflectance = 0.5", 'texture = "grid"\nspokes = 3'), r"'spokes'.*does not apply"),
    (LIT_PLANE.replace("reflectance = 0.5", 'texture = "image"\nimage = "nope.png"'), r"does not exist"),
    (LIT_PLANE.replace("reflectance = 0.5", 'emission = { spectrum = "A", luminance_cd_m2 = 10 }\n'
                                            'reflectance = 0.3'), r"emissive or reflective"),
    ('[[plane]]\ncenter = [0, 0, -2]\nsize = [1, 1]\nreflectance = 0.5\n', r"no light"),
    (LIT_PLANE + '[[light]]\ntype = "point"\nposition = [0, 0, -1]\nspectrum = "A"\nradius = 1\n'
                 'intensity_cd = 1\n', r"'radius'.*does not apply to a point"),
    (LIT_PLANE + '[[light]]\ntype = "lamp"\nposition = [0, 0, -1]\n', r"'type'.*not one of point, sphere"),
    (LIT_PLANE + '[spectral]\nmode = "monochromatic"\n', r"wavelength_nm"),
    (LIT_PLANE + '[spectral]\nsampling = "camera"\n', r"sensor\] preset"),
    (LIT_PLANE.replace("[illumination]", "[illumination]\nspectrum2 = 1"), r"unknown key 'spectrum2'"),
])
def test_errors_are_clear(body, pattern):
    with pytest.raises(LensrtError, match=pattern):
        scene(body)


def test_error_carries_file_and_line(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(BASE.format(units="m") + LIT_PLANE.replace("size = [0.4, 0.2]", "size = [0.4]"))
    with pytest.raises(LensrtError) as err:
        load_scene(p)
    text = str(err.value)
    line = next(i for i, ln in enumerate(p.read_text().splitlines(), 1) if ln.strip() == "[[plane]]")
    assert text.startswith(f"{p}:{line}: [[plane]] #1 ('card') key 'size'"), text


def test_sensor_errors():
    with pytest.raises(LensrtError, match="non-square photosites"):
        loads_scene(LIT_PLANE + "[sensor]\npixels = [600, 600]\n")
    with pytest.raises(LensrtError, match="unknown sensor format"):
        loads_scene(LIT_PLANE + '[sensor]\nformat = "super35"\n')
    with pytest.raises(LensrtError, match="noise needs a sensor preset"):
        loads_scene(LIT_PLANE + "[sensor]\nnoise = true\n")


def test_emissive_plane_facing_away_warns():
    s = scene("""
[[plane]]
center = [0, 0, -2]
size = [1, 1]
normal = [0, 0, -1]
emission = { spectrum = "D65", luminance_cd_m2 = 100 }
""")
    assert any("faces away" in w for w in s.warnings)


def test_readme_scene_example_loads():
    text = (SCENES.parent / "docs" / "reference" / "scene-format.md").read_text()
    block = text.split("## The format", 1)[1].split("```toml", 1)[1].split("```", 1)[0]
    s = loads_scene(block, SCENES / "readme_example.toml")
    assert s.name == "example" and len(s.planes) == 1 and len(s.meshes) == 1
    assert len(s.sphere_lights) == 1 and len(s.point_lights) == 1
    assert s.sensor.preset == "fullframe_24mp" and s.camera.f_number == 4.0
