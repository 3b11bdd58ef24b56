"""A tilt-shift camera in ``lensrt render``: the lens tilted/swung/shifted in front of the fixed sensor.

Oracles: the Scheimpflug condition (Field Guide to Geometrical Optics, tan(theta') = |m| tan(theta);
:mod:`scheimpflug`) for the plane that the render itself shows sharpest; the light splat, which traces
the moved lens forward with the general kernel variant (every surface in its tilted frame), for the
camera paths' radiometry and geometry (the same lamp, the same power and spot); the plain camera for a
vanishing tilt (the same image within noise) and for a zero one (the same bits).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scheimpflug import scheimpflug_slopes
from scipy.optimize import curve_fit

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order
from lensrt.prescription.tilt_shift import lens_frame
from lensrt.render.camera import setup_camera
from lensrt.render.integrator import render
from lensrt.render.scene.load import loads_scene
from lensrt.render.setup import RenderOptions

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

DG = "dgauss_50mm_f2"

# --- the Scheimpflug acceptance test -------------------------------------------------------------------------
# A close-up (m about -0.6, where a tilt-shift lens is used for table-top work and where the render resolves
# the focus plane's angle well): the lens tilted 8 deg about its stop and shifted so that its axis meets the
# sensor's centre; a tall, narrow sensor crop (1.6 x 12 mm, 20 um pixels) along the direction of the tilt.
# The target: a bright vertical stripe on a plane receding at the predicted Scheimpflug slope, moved along the
# lens axis by delta; for each band of image rows the edge width (mean absolute deviation of the edge spread
# from a step) is least at the delta where that part of the plane is in focus. The sharpest plane's slope
# is the predicted slope plus d(delta*)/dh along the object height h (a quadratic fit takes the field
# curvature, as the bokeh Scheimpflug test does).
TILT_DEG = 8.0
FOCUS_MM = 120.0
F_NUMBER = 4.0
HALF_PLANE_MM = 20.0
DELTAS_MM = np.linspace(-3.0, 3.0, 7)
CAMERA = """
[scene]
name = "scheimpflug"
units = "mm"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = {focus}
f_number = {fno}
lens_tilt_deg = {tilt}
lens_shift_mm = [0.0, {shift}]
[sensor]
format = "1.2x12"
pixels = [60, 600]
[spectral]
mode = "monochromatic"
wavelength_nm = 550
[render]
samples_per_pixel = {spp}
seed = 11
"""
PLANE = """
[[plane]]
name = "stripe"
center = [{c[0]}, {c[1]}, {c[2]}]
size = [{w}, {h}]
normal = [{n[0]}, {n[1]}, {n[2]}]
up = [{u[0]}, {u[1]}, {u[2]}]
texture = "uniform"
emission = {{ spectrum = {{ line_nm = 550.0 }}, luminance_cd_m2 = 1000 }}
"""


def _stripe(z0: float, slope: float, delta: float, origin, rot) -> str:
    """The bright half plane x < 0 of the plane z = z0 + delta + slope y (lens frame), in the camera frame: one
    straight edge along the lens frame's y axis."""
    nl = np.array([0.0, -slope, 1.0]) / math.hypot(1.0, slope)
    ul = np.array([0.0, 1.0, slope]) / math.hypot(1.0, slope)
    centre = np.array([-0.5 * HALF_PLANE_MM, 0.0, z0 + delta])
    return PLANE.format(c=origin + rot @ centre, w=HALF_PLANE_MM, h=60.0, n=rot @ nl, u=rot @ ul)


def _edge_widths(y: np.ndarray, band: int) -> np.ndarray:
    """Per band of ``band`` rows, the edge width (px): the mean absolute deviation of the normalised edge spread
    from a step at its centroid, as the pixels see that step (a sharp edge has width 0 whatever its sub-pixel
    position; noise has zero mean in it). The plateaus are the outer 8 columns on each side."""
    rows, cols = y.shape
    out = []
    for b in range(rows // band):
        esf = y[b * band:(b + 1) * band].mean(axis=0)
        if esf[:8].mean() > esf[-8:].mean():
            esf = esf[::-1]                                  # dark -> bright
        lo, hi = esf[:8].mean(), esf[-8:].mean()
        e = (esf - lo) / (hi - lo)
        x0 = len(e) - e.sum()                                # where a step of the same area rises
        step = np.clip(np.arange(1, len(e) + 1) - x0, 0.0, 1.0)
        out.append(np.abs(e - step).sum())
    return np.array(out)


def _focus_offset(deltas: np.ndarray, w: np.ndarray) -> float:
    """delta of least width: the hyperbola w = sqrt(a^2 (delta - delta*)^2 + c^2) fitted to every sample (its arms,
    where the blur spans pixels, fix delta*; a parabola through the few samples near focus would rest on widths
    of a fraction of a pixel)."""
    def hyperbola(d, d0, a, c):
        return np.sqrt(a * a * (d - d0) ** 2 + c * c)
    return float(curve_fit(hyperbola, deltas, w, p0=(float(deltas[np.argmin(w)]), 0.3, 0.3))[0][0])


@pytest.mark.slow
def test_render_sharpest_plane_obeys_scheimpflug() -> None:
    lens = load_lens(DG)
    fo = first_order(lens)
    plain = loads_scene(CAMERA.format(focus=FOCUS_MM, fno=F_NUMBER, tilt=0.0, shift=0.0, spp=1)
                        + _stripe(-FOCUS_MM, 0.0, 0.0, np.zeros(3), np.eye(3)))
    sensor_z = setup_camera(plain, lens).sensor_z_mm
    tilt = math.radians(TILT_DEG)
    pivot = float(lens.vertex_z_mm()[lens.stop_index])
    shift = -(sensor_z - pivot) * math.tan(tilt)            # the lens axis meets the sensor's centre
    origin, rot = lens_frame(tilt, (0.0, shift), pivot)
    z0, slopes = scheimpflug_slopes(lens, tilt, (0.0, shift), sensor_z)
    slope = float(slopes[1])
    band = 30
    widths = []
    for d in DELTAS_MM:
        scene = loads_scene(CAMERA.format(focus=FOCUS_MM, fno=F_NUMBER, tilt=TILT_DEG, shift=shift, spp=48)
                            + _stripe(z0, slope, d, origin, rot))
        res = render(scene, options=RenderOptions(device="cpu"))
        assert res.mode == "camera_paths" and res.camera.is_tilt_shift
        widths.append(_edge_widths(res.xyz[..., 1], band))
    widths = np.array(widths)                                # (deltas, bands)
    best = np.array([_focus_offset(DELTAS_MM, widths[:, b]) for b in range(widths.shape[1])])
    # object height h of each band on the predicted plane (first order: the band's lens-frame image height
    # over the magnification of the plane's point there, by fixed-point iteration)
    res_rows = (np.arange(widths.shape[1]) + 0.5) * band - 0.5
    x_s, y_s = res.position_of(res_rows, np.full_like(res_rows, 30.0))
    q = (np.stack([x_s, y_s, np.full_like(x_s, sensor_z)], axis=1) - origin) @ rot
    h = q[:, 1] / ((z0 - fo.front_focal_z_mm) / -fo.efl_mm)
    for _ in range(20):
        m = fo.efl_mm / (z0 + slope * h - fo.front_focal_z_mm)
        h = q[:, 1] / m
    fit = np.polyfit(h, best, 2)
    got = math.degrees(math.atan(slope + fit[1]))
    want = math.degrees(math.atan(slope))
    print(f"Scheimpflug: sharpest plane {got:.3f} deg, predicted {want:.3f} deg; best delta per band {best}")
    assert abs(got - want) < 0.2, (got, want)
    # the plane is really tilted: the plain camera's plane of focus (slope 0) is far outside the tolerance
    assert abs(want) > 10.0
    # the widths do vary through focus (the measurement sees the defocus)
    assert (widths.max(axis=0) > 2.0 * widths.min(axis=0)).all()


# --- camera paths against the light splat, and against the plain camera -------------------------------------
LAMP = """
[scene]
name = "lamp"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 3.0
f_number = 4.0
{camera}
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
spectrum = {{ line_nm = 550.0 }}
radiance_scale = 1000.0
"""


def _centroid(y: np.ndarray) -> np.ndarray:
    r, c = np.indices(y.shape)
    return np.array([(y * r).sum(), (y * c).sum()]) / y.sum()


@pytest.mark.parametrize("camera", ["lens_tilt_deg = 6.0\nlens_shift_mm = [2.0, -3.0]",
                                    "lens_swing_deg = -5.0\nlens_tilt_deg = 3.0\nlens_shift_mm = [-3.0, 0.0]"])
def test_tilted_camera_paths_agree_with_the_light_splat(camera: str) -> None:
    """A small sphere light through the moved lens: the splat traces it forward through the general kernel (every
    surface in its tilted frame), the camera paths backward through the centred lens from the tilted sensor.
    The same power on the sensor (4 standard errors) and the same bokeh spot, in the same place."""
    scene = loads_scene(LAMP.format(camera=camera))
    s = render(scene, options=RenderOptions(device="cpu"))
    assert s.mode == "light_splat"
    c = render(scene, options=RenderOptions(device="cpu", samples_per_pixel=1024, spp_per_pass=128,
                                            window=(0, 32, 0, 48)))
    assert c.mode == "camera_paths" and c.camera.is_tilt_shift
    ps, pc = s.regions["image"], c.regions["image"]
    assert abs(ps.value - pc.value) < 4.0 * math.hypot(ps.stderr, pc.stderr)
    cs, cc = _centroid(s.xyz[..., 1]), _centroid(c.xyz[..., 1])
    assert np.abs(cs - cc).max() < 0.25, (cs, cc)
    # and the shift moved the spot (about the shift: 4 px and more): not where the plain camera puts it
    plain = render(loads_scene(LAMP.format(camera="")), options=RenderOptions(device="cpu"))
    assert np.abs(_centroid(plain.xyz[..., 1]) - cs).max() > 2.0


CHART = """
[scene]
name = "chart"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 2.0
f_number = 2.8
{camera}
[sensor]
format = "full-frame"
pixels = [36, 24]
[render]
samples_per_pixel = 64
seed = 4
[illumination]
spectrum = "D65"
illuminance_lux = 1000
[background]
spectrum = "D65"
luminance_cd_m2 = 200
[[plane]]
name = "star"
center = [0.0, 0.0, -2.0]
size = [0.6, 0.4]
texture = "siemens_star"
"""


def test_zero_tilt_is_the_plain_camera_and_a_tiny_tilt_agrees_within_noise() -> None:
    """Tilt 0 written out: the same bits as no tilt (the plain kernel variant). A tilt of 1e-7 deg runs the
    tilt-shift variant on an (all but) unmoved lens: every region mean within 4 standard errors of the plain one."""
    opts = RenderOptions(device="cpu")
    plain = render(loads_scene(CHART.format(camera="")), options=opts)
    zero = render(loads_scene(CHART.format(camera="lens_tilt_deg = 0.0\nlens_shift_mm = [0.0, 0.0]")), options=opts)
    assert not zero.camera.is_tilt_shift
    assert np.array_equal(plain.irradiance, zero.irradiance)
    tiny = render(loads_scene(CHART.format(camera="lens_tilt_deg = 1e-7")), options=opts)
    assert tiny.camera.is_tilt_shift
    assert not np.array_equal(plain.irradiance, tiny.irradiance)   # another kernel variant, other rounding
    for name, p in plain.regions.items():
        t = tiny.regions[name]
        assert abs(p.value - t.value) < 4.0 * math.hypot(p.stderr, t.stderr) + 1e-6 * abs(p.value), name


# --- bad input ------------------------------------------------------------------------------------------------
def test_tilt_shift_bad_input_gets_one_clear_error(tmp_path) -> None:
    from lensrt.cli import main
    with pytest.raises(LensrtError, match="lens_tilt_deg"):
        loads_scene(CHART.format(camera="lens_tilt_deg = 50.0"))
    with pytest.raises(LensrtError, match="lens_shift_mm"):
        loads_scene(CHART.format(camera="lens_shift_mm = [1.0]"))
    # a mirror lens cannot be tilted (nor traced backwards by camera paths)
    reflex = CHART.replace('lens = "dgauss_50mm_f2"', 'lens = "reflex_nikkor_500mm_f8"').replace(
        "focus_distance = 2.0", "focus_distance = 20.0").replace("f_number = 2.8\n", "")
    lamp = LAMP.replace('lens = "dgauss_50mm_f2"', 'lens = "reflex_nikkor_500mm_f8"').replace(
        "focus_distance = 3.0", "focus_distance = 20.0").replace("f_number = 4.0\n", "")
    with pytest.raises(LensrtError, match="centred refractive lens"):
        render(loads_scene(lamp.format(camera="lens_tilt_deg = 2.0")), options=RenderOptions(device="cpu"))
    with pytest.raises(LensrtError, match="has mirrors"):
        render(loads_scene(reflex.format(camera="")), options=RenderOptions(device="cpu"))
    # a shift that leaves the sensor's centre outside the image circle
    with pytest.raises(LensrtError, match="does not cover the sensor"):
        render(loads_scene(CHART.format(camera="lens_shift_mm = [0.0, 60.0]")), options=RenderOptions(device="cpu"))
    # a swing that drives a sensor corner into the rear element
    big = CHART.replace('format = "full-frame"', 'format = "120x90"').replace("pixels = [36, 24]", "pixels = [12, 9]")
    with pytest.raises(LensrtError, match="rear element"):
        render(loads_scene(big.format(camera="lens_swing_deg = 35.0")), options=RenderOptions(device="cpu"))
    # the command line: one line, exit 2
    scene = tmp_path / "chart.toml"
    scene.write_text(CHART.format(camera=""))
    assert main(["render", str(scene), "--lens-tilt-deg", "60", "--device", "cpu", "-o", str(tmp_path / "x")]) == 2
    assert main(["render", str(scene), "--lens-shift-mm", "a,b", "--device", "cpu", "-o", str(tmp_path / "x")]) == 2


def test_cli_render_takes_the_tilt_shift_options(capsys) -> None:
    """--lens-tilt-deg / --lens-swing-deg / --lens-shift-mm reach the camera (the plan shows it, as JSON)."""
    import json

    from lensrt.cli import main
    assert main(["render", "sodium_star_test", "--plan", "--json", "--lens-tilt-deg", "5", "--lens-swing-deg", "-2",
                 "--lens-shift-mm", "1,2"]) == 0
    cam = json.loads(capsys.readouterr().out)["camera"]
    assert cam["lens_tilt_rad"] == pytest.approx(math.radians(5.0), abs=1e-15)
    assert cam["lens_swing_rad"] == pytest.approx(math.radians(-2.0), abs=1e-15)
    assert cam["lens_shift_mm"] == [1.0, 2.0]
