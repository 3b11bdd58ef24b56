"""The render integrator: radiometry (camera equation, relative illumination), orientation, determinism,
progressive stopping, Jobs, light splat, outputs.

Radiometric references (tests/render_reference.py) use the float64 reference tracer and quadrature,
no Monte Carlo and no code of the integrator. Monte Carlo results are compared by z-tests with the
render's own standard errors (batch means over passes), fixed seeds.
"""
from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from lensrt.render.camera import SensorGrid
from lensrt.render.integrator import render
from lensrt.render.setup import RenderOptions
from lensrt.render.scene.load import loads_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
from render_reference import irradiance_quadrature, marginal_sine  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

LINE_NM = 587.56
RADIANCE = 100.0       # W / (m^2 sr) of the line


def uniform_scene(f_number: float | None = 8.0, pixels: int = 720, focus: str = "inf") -> object:
    """A Lambertian emitter (one line, radiance L) filling the view of the 50 mm double Gauss."""
    fno = f"f_number = {f_number}\n" if f_number else ""
    return loads_scene(f"""
[scene]
name = "uniform"
units = "m"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = {focus}
{fno}
[sensor]
format = "full-frame"
pixels = {pixels}
[render]
samples_per_pixel = 64
seed = 11
[[plane]]
name = "sky"
center = [0.0, 0.0, -100.0]
size = [1000.0, 1000.0]
emission = {{ spectrum = {{ line_nm = {LINE_NM} }}, radiance_scale = {RADIANCE} }}
""")


def window_estimate(scene, window, spp: int = 16384, spp_per_pass: int = 1024, seed: int = 3):
    """Mean irradiance over a window of pixels, its standard error, and the window centre (mm)."""
    r = render(scene, options=RenderOptions(samples_per_pixel=spp, spp_per_pass=spp_per_pass, window=window,
                                            device="cpu", seed=seed))
    est = r.regions["image"]                     # Y of one line is proportional to E
    e = float(r.irradiance[..., 0].astype(np.float64).mean())
    rows, cols = r.shape
    x, y = r.position_of(0.5 * (rows - 1), 0.5 * (cols - 1))
    return e, e * est.stderr / est.value, (float(x), float(y)), r


# ---- orientation ------------------------------------------------------------------------------

def test_sensor_grid_is_the_one_upright_map():
    g = SensorGrid(36.0, 24.0, 72, 48)
    x, y = g.position_of(0, 0)
    assert x > 0 and y < 0                      # image top-left <- sensor (+x, -y): rotated by 180 deg
    assert g.position_of(47, 71)[0] < 0 and g.position_of(47, 71)[1] > 0
    r, c = np.meshgrid(np.linspace(-0.5, 47.5, 7), np.linspace(-0.5, 71.5, 9), indexing="ij")
    back = g.pixel_of(*g.position_of(r, c))
    assert np.allclose(back[0], r) and np.allclose(back[1], c)
    x0, dx, y0, dy = g.affine()
    assert (x0, y0) == pytest.approx(g.position_of(0, 0)) and dx == pytest.approx(-0.5) and dy == pytest.approx(0.5)
    assert g.pixel_of(0.0, 0.0) == pytest.approx((23.5, 35.5))


def test_render_is_upright():
    """A lamp up and to the photographer's left lands in the image's top-left quadrant."""
    scene = loads_scene("""
[scene]
name = "marker"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 5.0
[sensor]
format = "full-frame"
pixels = [36, 24]
[[plane]]
name = "marker"
center = [-1.0, 0.6, -5.0]
size = [0.5, 0.5]
emission = { spectrum = "D65", luminance_cd_m2 = 1000 }
""")
    r = render(scene, options=RenderOptions(samples_per_pixel=4, device="cpu"))
    y = r.xyz[..., 1]
    quad = [y[:12, :18].sum(), y[:12, 18:].sum(), y[12:, :18].sum(), y[12:, 18:].sum()]
    assert quad[0] > 0 and quad[0] == max(quad) and sum(quad[1:]) < 1e-3 * quad[0]


# ---- radiometry --------------------------------------------------------------------------------

def test_camera_equation_on_axis():
    """Centre irradiance of a uniformly bright scene: E = pi L sin^2(theta') exactly; the camera equation
    (pi / 4) L T / N_w^2 (Field Guide p. 33, T = 1 for lensrt's uncoated, lossless lenses) holds as far
    as the lens obeys the sine condition (sin theta' = 1 / (2 N_w)), which at f/8 it does to 0.3 %.

    References: sin(theta') of the real marginal ray (float64 reference tracer, bisection); the
    tolerance is 4 standard errors of the render (batch means over 16 passes) plus 2e-4 (float32)."""
    scene = uniform_scene(8.0)
    e, se, (x, y), r = window_estimate(scene, (238, 242, 358, 362))
    assert abs(x) < 0.1 and abs(y) < 0.1 and se < 2e-3 * e
    cam = r.camera
    assert cam.working_f_number == pytest.approx(8.0) and r.unit == "W/m^2"
    sin_t = marginal_sine(cam, LINE_NM)
    exact = math.pi * RADIANCE * sin_t ** 2
    camera_eq = math.pi / 4.0 * RADIANCE * 1.0 / cam.working_f_number ** 2
    sine_condition = abs(exact / camera_eq - 1.0)
    assert sine_condition < 3e-3
    assert abs(e - exact) < 4.0 * se + 2e-4 * exact
    assert abs(e / camera_eq - 1.0) < 4.0 * se / e + sine_condition + 2e-4
    # Y is K_m y-bar(lambda) E for one line
    from lensrt.render.spectra import cie_xyz_cmfs
    ybar = float(np.interp(LINE_NM, scene.grid.nm, cie_xyz_cmfs(scene.grid)[1]))
    assert r.xyz[..., 1].mean() == pytest.approx(683.002 * ybar * e, rel=1e-5)


@pytest.mark.parametrize("f_number, window", [(8.0, (0, 4, 0, 4)), (8.0, (238, 242, 0, 4)),
                                              (2.04, (0, 4, 716, 720)), (2.04, (100, 104, 150, 154))])
def test_relative_illumination_follows_the_real_pupil(f_number, window):
    """Off axis the irradiance follows the real relative illumination (cos^4, pupil distortion and the
    cat's-eye vignetting at f/2): against quadrature over the real, vignetted pupil with the float64
    reference tracer, within 4 standard errors + 3e-4."""
    scene = uniform_scene(f_number)
    e, se, (x, y), r = window_estimate(scene, window)
    ref = irradiance_quadrature(r.camera, x, y, RADIANCE, LINE_NM)
    assert abs(e - ref) < 4.0 * se + 3e-4 * ref, (e, se, ref)
    centre = math.pi * RADIANCE * marginal_sine(r.camera, LINE_NM) ** 2
    assert ref < centre                          # darker than the centre


def test_relative_illumination_against_lensrt_analysis_vignetting():
    """Corner over centre of the render (full aperture, sensor on the lens's own image surface, as the
    analysis assumes) against lensrt.analysis.compare.vignetting's relative illumination (flux method) at the
    field angle whose real chief ray reaches that corner. Measured: 0.16611 +- 0.00003 against 0.16641
    +- 0.00004, a 0.18 % gap that the quadrature reference (0.166109) places on the analysis side;
    tolerance 0.5 % + 4 standard errors (the exit-pupil method, 0.1671, is within 0.7 %)."""
    from lensrt.analysis.compare.vignetting import vignetting
    from lensrt.trace.aiming import FieldPoint, aim_rays
    from lensrt.trace.reference import trace_reference
    scene = uniform_scene(None)
    out = []
    for window in ((238, 242, 358, 362), (0, 4, 716, 720)):
        r = render(scene, options=RenderOptions(samples_per_pixel=16384, spp_per_pass=1024, window=window,
                                                device="cpu", seed=3, focus="paraxial"))
        est = r.regions["image"]
        out.append((est.value, est.stderr, r.position_of(1.5, 1.5)))
    lens = r.camera.lens
    assert r.camera.sensor_z_mm == pytest.approx(lens.image_z_mm, abs=1e-9)
    (ec, sc, _), (ek, sk, (x, y)) = out
    ratio, se = ek / ec, ek / ec * math.hypot(sc / ec, sk / ek)
    target = math.hypot(float(x), float(y))

    def height(theta: float) -> float:
        fp = FieldPoint(True, (math.sin(theta), 0.0, math.cos(theta)), None)
        o, d, _ = aim_rays(lens, fp, np.zeros(1), np.zeros(1), LINE_NM, "real")
        q = trace_reference(lens, tuple(o[0]), tuple(d[0]), LINE_NM, clip=False)
        t = (lens.image_z_mm - q.z_mm) / q.N
        return math.hypot(q.x_mm + t * q.L, q.y_mm + t * q.M)

    a, b = 0.3, 0.45                       # secant: the field angle of the corner
    for _ in range(40):
        fa, fb = height(a) - target, height(b) - target
        if fb == fa:
            break
        a, b = b, b - fb * (b - a) / (fb - fa)
    v = vignetting(lens, object_values=[b], wavelength_nm=LINE_NM, rays=1 << 17, device="cpu", exit_pupil=False)
    ri = v.relative_illumination[0]
    assert abs(ratio / ri.value - 1.0) < 0.005 + 4.0 * math.hypot(se / ratio, ri.stderr / ri.value)


# ---- determinism, Jobs, stopping ---------------------------------------------------------------

def _small_default(**kw):
    from lensrt.render.scene.load import load_scene
    return load_scene("default"), RenderOptions(width=48, samples_per_pixel=4, spp_per_pass=2, device="cpu", **kw)


def test_same_seed_same_image_bit_for_bit(monkeypatch):
    from lensrt.render import pupil_table
    scene, opts = _small_default()
    a = render(scene, options=opts)
    b = render(scene, options=opts)
    monkeypatch.setattr(pupil_table, "_cpu_workers", lambda device, n: 3)   # another launch split
    c = render(scene, options=opts)
    for other in (b, c):
        assert np.array_equal(a.irradiance, other.irradiance)
        assert np.array_equal(a.xyz, other.xyz) and np.array_equal(a.xyz_stderr, other.xyz_stderr)
    d = render(scene, options=dataclasses.replace(opts, seed=99))
    assert not np.array_equal(a.irradiance, d.irradiance)


def _same_estimates(a, b, rel: float = 1e-12) -> None:
    """Region and through-the-lens estimates of two renders of the same passes agree to ``rel``."""
    assert a.regions.keys() == b.regions.keys() and len(a.regions) == 6
    for name in a.regions:
        for f in ("value", "stderr"):
            x, y = getattr(a.regions[name], f), getattr(b.regions[name], f)
            assert abs(x - y) <= rel * abs(x), (name, f, x, y)
    assert a.through.value == b.through.value and a.through.stderr == b.through.stderr
    assert a.through_fraction == b.through_fraction


def test_fixed_samples_on_an_executor_run_tiles_with_the_same_bits():
    """A fixed sample count on two devices: one Job of row-band tiles; the image bits of one device (3
    passes: the mean is times 1/6), its per-pass hits, and region means to 1e-12 (tile sums, other order)."""
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default()
    opts = dataclasses.replace(opts, samples_per_pixel=6)
    a = render(scene, options=opts)
    seen = []
    with LocalExecutor("cpu,cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex,
                   progress=lambda *p: seen.append(p))
    assert b.executor_items == "tiles" and b.executor_item_count == 6 and a.executor_items is None
    assert b.summary()["executor_items"] == "tiles"
    for f in ("irradiance", "xyz", "xyz_stderr"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert b.passes == a.passes == 3 and b.samples == a.samples and b.stop_reason == "samples"
    _same_estimates(a, b)
    assert len(b.history) == 1 and b.history[0]["passes"] == 3
    assert b.history[0]["rel_error"] == a.history[-1]["rel_error"]
    assert seen and seen[-1][:2] == (3, 3) and seen[-1][3] == 0.0


def test_tiles_with_a_window_equal_one_device():
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default(window=(3, 20, 5, 40))
    a = render(scene, options=opts)
    with LocalExecutor("cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex)
    assert b.executor_items == "tiles" and b.executor_item_count == 3
    assert np.array_equal(a.irradiance, b.irradiance) and np.array_equal(a.xyz_stderr, b.xyz_stderr)
    _same_estimates(a, b)


def test_progressive_runs_on_an_executor_keep_pass_rounds():
    """A target error needs a decision after every pass: rounds of one pass per device, one history row
    per pass, and the same passes and bits as one device (the error measure is computed from the same sums)."""
    from lensrt.parallel import LocalExecutor
    scene, opts = _small_default()
    opts = dataclasses.replace(opts, samples_per_pixel=None, target_rel_error=0.3)
    a = render(scene, options=opts)
    with LocalExecutor("cpu,cpu") as ex:
        b = render(scene, options=dataclasses.replace(opts, device=None), executor=ex)
    assert b.executor_items == "passes" and b.executor_item_count == b.passes
    assert b.stop_reason == a.stop_reason == "target_error" and b.passes == a.passes >= 4
    assert len(b.history) == b.passes
    assert np.array_equal(a.irradiance, b.irradiance) and np.array_equal(a.xyz_stderr, b.xyz_stderr)
    _same_estimates(a, b, rel=0.0)


def test_tile_region_sums_add_up_to_the_region_sums():
    """Any split of the pixels into ranges (row-aligned or not): the tiles' region sums add up to the sums
    over each region; the span a tile copies covers every region pixel it holds."""
    from lensrt.render.jobs import tile_region_span, tile_region_sums
    from lensrt.render.passes import region_slices
    shape = (23, 17)
    y = np.random.default_rng(1).random(shape)
    want = [y[r0:r1, c0:c1].sum() for r0, r1, c0, c1 in region_slices(shape)]
    cuts = [0, 5, 17, 40, 41, 200, 17 * 3 * 4, 391]
    got = np.zeros(len(want))
    for p0, p1 in zip(cuts[:-1], cuts[1:]):
        span = tile_region_span(p0, p1, shape)
        if span is not None:
            got += tile_region_sums(y.reshape(-1)[span[0]:span[1]], span[0], span[1], shape)
    assert np.allclose(got, want, rtol=1e-13, atol=0)


def test_render_job_workload_reduces_in_pass_order():
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    job = get_workload("render")("tiny", 5)
    one = LocalExecutor("cpu").run(job).value
    two = LocalExecutor("cpu,cpu").run(job).value
    assert np.array_equal(one.spec_sum, two.spec_sum) and np.array_equal(one.xyz_stderr, two.xyz_stderr)
    assert one.passes == 4 and np.all(np.isfinite(one.xyz_stderr))


def test_tiled_render_job_equals_the_pass_job_and_the_in_process_render():
    """Tiles with all their passes summed on the device: the same bits as items of one pass each (any
    number of tiles, one or two devices) and as the one-device render's irradiance."""
    from lensrt.parallel import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    passes = LocalExecutor("cpu").run(get_workload("render")("tiles=0", 3)).value
    for tiles, devices in ((1, "cpu"), (5, "cpu,cpu")):
        job = get_workload("render")(f"tiles={tiles}", 3)
        assert len(job.items) == tiles
        v = LocalExecutor(devices).run(job).value
        for f in ("spec_sum", "xyz", "xyz_stderr", "passes", "samples_per_pixel", "hits"):
            assert np.array_equal(getattr(passes, f), getattr(v, f)), (tiles, f)
    setup = job.context
    scene = setup.scene
    r = render(scene, options=RenderOptions(width=64, spp_per_pass=2, samples_per_pixel=8, seed=3, device="cpu"))
    assert np.array_equal(r.irradiance, v.irradiance(setup.shape, setup.n_bands))


def test_stop_rules_samples_time_and_target_error():
    scene, opts = _small_default()
    r = render(scene, options=opts)
    assert r.stop_reason == "samples" and r.samples_per_pixel == 4 and r.samples == 4 * 48 * 32
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=None, time_budget_s=1e-3))
    assert r.stop_reason == "time_budget" and r.passes == 4          # the rule waits for 4 passes
    target = 0.3
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=None, target_rel_error=target))
    assert r.stop_reason == "target_error" and r.history[-1]["rel_error"] <= target
    assert all(h["rel_error"] > target for h in r.history[3:-1])
    # error against run time: the error falls as passes are added
    errs = [h["rel_error"] for h in r.history if h["rel_error"] is not None]
    assert errs[-1] < errs[0]
    for h in r.history:
        assert {"passes", "samples", "seconds"} <= set(h)


def test_regions_carry_stderr_samples_seconds():
    scene, opts = _small_default()
    r = render(scene, options=dataclasses.replace(opts, samples_per_pixel=8))
    for name in ("image", "centre", "bottom left", "bottom right"):
        est = r.regions[name]
        assert est.value > 0 and 0 < est.stderr < est.value and est.samples == r.samples and est.seconds > 0
    assert 0.3 < r.through_fraction <= 1.0


# ---- light splat ------------------------------------------------------------------------------

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
