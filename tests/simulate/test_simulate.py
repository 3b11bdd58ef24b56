"""Image simulation (lensrt.simulate, ``lensrt simulate``): oracles on small images and few rays.

* uniform white -> the output's falloff is lensrt's real relative illumination
  (lensrt.analysis.compare.vignetting, an independent flux computation) within 1 %;
* a point source reproduces the real PSF: centroid and RMS radius against the bokeh
  tracer's spot of the same object point (lensrt.analysis.bokeh.bokeh_spot);
* distortion: dots land where the real chief ray of their direction (traced forward,
  lensrt.trace.aiming.chief_rays) meets the sensor;
* occlusion: a sharp foreground takes nothing from the blurred background, a blurred
  foreground spreads onto the background no farther than its PSF's support;
* bad input: one clear error each.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.simulate.optics import picture_positions_mm, pinhole_focal_mm
from lensrt.simulate.pipeline import SimulateOptions, simulate

SHAPE = (48, 64)
SENSOR = "24x18"


@pytest.fixture(scope="module")
def dgauss():
    return load_lens("dgauss_50mm_f2")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("simcache"))


def _opts(cache, **kw):
    base = dict(sensor=SENSOR, grid=(3, 3), rays=1 << 12, ri_rays=1 << 14, bands=2, layers=2, cache_dir=cache,
                device="cpu")
    base.update(kw)
    return SimulateOptions(**base)


def _sensor_xy(cam, row, col):
    u, v = picture_positions_mm(cam, row, col)
    return -u, -v


def _centroid(img: np.ndarray) -> tuple[float, float]:
    r, c = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    s = img.sum()
    return float((r * img).sum() / s), float((c * img).sum() / s)


def test_uniform_white_follows_real_relative_illumination(dgauss, cache):
    from lensrt.analysis.compare.vignetting import vignetting
    sim = simulate(np.ones(SHAPE + (3,), np.float32), dgauss, None, _opts(cache, ri_rays=1 << 16, bands=1))
    # the oracle: vignetting's flux method at the field angles of 5 points along the picture's diagonal
    cam = sim.camera
    opt = sim.layers[0]
    idx = np.array([3, 7, 12, 17, 21])  # up to 0.95 of the corner radius
    theta = np.arctan(opt.object_height_mm[idx] / (opt.depth_mm + cam.z_ep_mm))
    vig = vignetting(dgauss, object_values=theta, exit_pupil=False, rays=1 << 16, device="cpu")
    ri = vig.values("relative_illumination")
    heights = vig.image_height_mm  # on the lens's image surface = the sensor (focus at infinity)
    y = sim.rgb[..., 1].astype(np.float64)
    from scipy.ndimage import map_coordinates
    # sample the output at those radii along the picture's half-diagonal to the bottom-right corner
    rows, cols = SHAPE
    half = 0.5 * cam.pitch_mm * math.hypot(cols - 1, rows - 1)
    t = heights / half
    rr, cc = 0.5 * (rows - 1) + t * 0.5 * (rows - 1), 0.5 * (cols - 1) + t * 0.5 * (cols - 1)
    got = map_coordinates(y, np.stack([rr, cc]), order=1)
    assert np.all(np.abs(got / ri - 1.0) < 0.01), (got, ri)
    assert ri[-1] < 0.6  # a real falloff was tested, not a flat field
    # a white input stays neutral (the spectral round trip)
    assert np.abs(sim.rgb[24, 32] / sim.rgb[24, 32, 1] - 1.0).max() < 1e-3


def _spot(lens, cam, row, col, depth_mm, wavelength_nm):
    """Centroid (row, col) and RMS radius (px) of the bokeh tracer's spot of the object point at depth_mm
    whose real chief ray lands on picture pixel (row, col), in picture coordinates."""
    from lensrt.analysis.bokeh import bokeh_spot, spot_source
    x, y = _sensor_xy(cam, row, col)
    src = spot_source(lens, cam.focus, depth_mm, image_mm=(float(x), float(y)), device="cpu")
    spot = bokeh_spot(lens, cam.focus, src, light=f"lines:{wavelength_nm:.4f}", rays=1 << 16, device="cpu")
    rec = spot.sources[0]
    cx, cy = rec["centroid_mm"]
    u, v = -cx, -cy
    r_c = 0.5 * (cam.shape[0] - 1) - v / cam.pitch_mm
    c_c = u / cam.pitch_mm + 0.5 * (cam.shape[1] - 1)
    return r_c, c_c, rec["rms_radius_mm"] / cam.pitch_mm


@pytest.mark.parametrize("pixel", [(12, 16), (18, 24)], ids=["node", "cell-centre"])
def test_point_source_reproduces_the_real_psf(dgauss, cache, pixel):
    img = np.zeros(SHAPE + (3,), np.float32)
    img[pixel] = 1.0
    depth = np.full(SHAPE, 1.0)
    opts = _opts(cache, sensor="2.4x1.8", focus_m=2.0, bands=1, rays=1 << 14, grid=(5, 5))
    sim = simulate(img, dgauss, depth, opts)
    out = sim.rgb[..., 1].astype(np.float64)
    r_c, c_c = _centroid(out)
    # where the dot lands: the warp moves it by the real chief ray (see the distortion test); the oracle spot is
    # the one whose chief ray lands at the dot's warped position -- find it from the output's own peak region
    wl = float(sim.bands.centre_nm[0])
    ref_r, ref_c, ref_rms = _spot(dgauss, sim.camera, *_chief_pixel(sim, pixel, 1000.0), 1000.0, wl)
    rr, cc = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    rms = math.sqrt(float((((rr - r_c) ** 2 + (cc - c_c) ** 2) * out).sum() / out.sum()))
    rms_ref = math.sqrt(ref_rms ** 2 + 2.0 / 12.0)  # the PSF integrated over square pixels
    assert abs(r_c - ref_r) < 0.15 and abs(c_c - ref_c) < 0.15, ((r_c, c_c), (ref_r, ref_c))
    assert abs(rms / rms_ref - 1.0) < 0.05, (rms, rms_ref)
    assert ref_rms > 1.5  # the spot spans pixels: the shape was tested


def _chief_pixel(sim, pixel, depth_mm, wavelength_nm=None):
    """Picture (row, col) where the real chief ray of the input pixel's direction lands (forward trace at
    ``wavelength_nm``, default the primary; the pinhole's direction is defined at the primary)."""
    from lensrt.trace import RayBatch, trace
    from lensrt.trace.aiming import FieldPoint, chief_rays
    from lensrt.trace.api import kernel_to_stop
    cam = sim.camera
    f_pin = pinhole_focal_mm(cam)
    u, v = picture_positions_mm(cam, pixel[0], pixel[1])
    # the pinhole's direction of that picture point, and the object point at depth_mm along it (sensor inverted)
    h = (depth_mm + cam.z_ep_mm) / f_pin
    obj = (float(u * h), float(v * h), -depth_mm)
    to_stop = kernel_to_stop(cam.lens, "cpu")
    wl = cam.wavelength_nm if wavelength_nm is None else wavelength_nm
    o, d, ok = chief_rays(cam.lens, [FieldPoint(False, None, obj)], wl, to_stop, fallback=True)
    assert ok[0]
    res = trace(cam.lens, RayBatch(o, d, np.full(1, wl)), "float64", "cpu", clip=False,
                plane_z_mm=cam.sensor_z_mm)
    x, y = res.position_mm[0, :2]
    return 0.5 * (cam.shape[0] - 1) + y / cam.pitch_mm, 0.5 * (cam.shape[1] - 1) - x / cam.pitch_mm


def test_distortion_dots_land_on_the_real_chief_rays(cache):
    lens = load_lens("nikkor_20mm_f2.8_retrofocus")
    dots = [(r, c) for r in (4, 14, 24, 33, 43) for c in (4, 14, 24, 32, 40, 50, 59)]
    rr, cc = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    blobs = sum(np.exp(-((rr - r) ** 2 + (cc - c) ** 2) / (2 * 0.8 ** 2)) for r, c in dots)  # round dots
    img = np.repeat(blobs[..., None], 3, axis=2).astype(np.float32)
    # f/11: small PSFs, so that where the light lands is where the chief ray lands (coma ~ aperture^2)
    sim = simulate(img, lens, None, _opts(cache, bands=1, rays=1 << 13, grid=(5, 7), f_number=11.0))
    out = sim.rgb[..., 1].astype(np.float64)
    shifts = []
    for p in dots:
        er, ec = _chief_pixel(sim, p, sim.layers[0].depth_mm, float(sim.bands.centre_nm[0]))
        r0, c0 = int(round(er)), int(round(ec))
        win = out[max(r0 - 3, 0):r0 + 4, max(c0 - 3, 0):c0 + 4]
        cr, cc = _centroid(win)
        cr, cc = cr + max(r0 - 3, 0), cc + max(c0 - 3, 0)
        assert abs(cr - er) < 0.03 and abs(cc - ec) < 0.03, (p, (cr, cc), (er, ec))  # 11 um
        shifts.append(math.hypot(er - p[0], ec - p[1]))
    assert max(shifts) > 0.5  # the lens really moves the corner dots (barrel distortion) by more than the tolerance


def _two_planes(lens, cache, focus_m, near_m=1.0, far_m=10.0):
    """Left half: a white plane at near_m; right half: black at far_m (an occluding vertical edge)."""
    img = np.zeros(SHAPE + (3,), np.float32)
    img[:, :32] = 1.0
    depth = np.full(SHAPE, far_m)
    depth[:, :32] = near_m
    sim = simulate(img, lens, depth, _opts(cache, sensor="2.4x1.8", focus_m=focus_m, bands=1, rays=1 << 13))
    return sim, sim.rgb[..., 1].astype(np.float64)


def _support_px(psf: np.ndarray) -> int:
    """Largest |row or col offset| of a pixel with light in any node PSF of the grid (gr, gc, n, n)."""
    lit = np.argwhere(psf.max(axis=(0, 1)) > 0)
    return int(np.abs(lit - psf.shape[-1] // 2).max())


def test_sharp_foreground_takes_nothing_from_the_blurred_background(dgauss, cache):
    sim, out = _two_planes(dgauss, cache, focus_m=1.0)
    ref = simulate(np.ones(SHAPE + (3,), np.float32), dgauss, np.full(SHAPE, 1.0),
                   _opts(cache, sensor="2.4x1.8", focus_m=1.0, bands=1, rays=1 << 13)).rgb[..., 1]
    halo = _support_px(sim.psf_grid.psf[1][0]) + 1  # the in-focus (near) layer's PSF support
    assert halo <= 3
    # no darkening of the foreground by the black background's blur beyond the sharp PSF's reach ...
    fg = slice(0, 32 - halo)
    assert np.abs(out[:, fg] - ref[:, fg]).max() < 1e-4
    # ... and nothing of the white foreground beyond it on the background
    assert out[:, 32 + halo:].max() < 1e-6


def test_blurred_foreground_spreads_no_farther_than_its_psf(dgauss, cache):
    sim, out = _two_planes(dgauss, cache, focus_m=10.0)
    halo = _support_px(sim.psf_grid.psf[1][0]) + 1  # the defocused near layer
    assert halo >= 4  # a real blur
    edge = out[:, 32:32 + halo]
    assert edge.max() > 0.05  # the foreground's blur does spread over the edge (partial occlusion) ...
    assert out[:, 32 + halo:].max() < 1e-6  # ... but not beyond its PSF's support


def test_psf_grid_is_cached_and_reused(dgauss, tmp_path):
    img = np.random.default_rng(3).random(SHAPE + (3,)).astype(np.float32)
    opts = _opts(str(tmp_path), bands=2, rays=1 << 11)
    a = simulate(img, dgauss, None, opts)
    b = simulate(img, dgauss, None, opts)
    assert not a.psf_grid.cached and b.psf_grid.cached
    assert len(list(tmp_path.glob("psf_*.npz"))) == 1
    np.testing.assert_array_equal(a.rgb, b.rgb)
    err = a.errors()
    assert err["interpolation"]["checks"] and err["psf_monte_carlo"]["rays_per_psf"] == 1 << 11


# ---- bad input: one clear error each (library and CLI) ----------------------------------------

def _cli(capsys, *argv):
    from lensrt.cli import main
    rc = main(list(argv))
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err


def test_cli_bad_inputs_end_in_one_line(tmp_path, capsys):
    from lensrt.io.png import write_png
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not an image at all")
    good = tmp_path / "in.png"
    write_png(good, np.full((12, 16, 3), 0.5), 8)
    for name, depth in (("small", np.ones((5, 5))), ("negative", -np.ones((12, 16))),
                        ("nan", np.full((12, 16), np.nan))):
        np.save(tmp_path / f"{name}.npy", depth)
    cases = [
        ([str(bad)], "cannot read"),
        ([str(tmp_path / "missing.png")], "does not exist"),
        ([str(good), "--depth", str(tmp_path / "small.npy")], "depth map is 5 x 5"),
        ([str(good), "--depth", str(tmp_path / "negative.npy")], "<= 0 m"),
        ([str(good), "--depth", str(tmp_path / "nan.npy")], "NaN"),
        ([str(good), "--sensor", "36x24"], "non-square"),
        ([str(good), "--sensor-preset", "no_such_sensor"], "unknown sensor preset"),
        ([str(good), "--iso", "100"], "need --sensor-preset"),
        ([str(good), "--max-memory", "lots"], "not a memory size"),
        ([str(good), "--max-memory", "1K"], "input and outputs alone"),
    ]
    import warp as wp
    wp.init()
    if not wp.is_cuda_available():  # a GPU asked for and not there: never a silent CPU run
        cases.append(([str(good), "--sensor", "16x12", "--device", "cuda"], "no CUDA device"))
    for argv, text in cases:
        rc, err = _cli(capsys, "simulate", *argv, "--sensor", "16x12", "--device", "cpu", "-o",
                       str(tmp_path / "o")) if "--sensor" not in argv else _cli(capsys, "simulate", *argv, "-o",
                                                                               str(tmp_path / "o"))
        assert rc == 2 and len(err) == 1 and err[0].startswith("lensrt: error:") and text in err[0], (argv, err)


def test_huge_image_is_one_clear_error(dgauss):
    big = np.broadcast_to(np.zeros((1, 1, 3), np.float32), (60000, 80000, 3))  # no memory behind it
    with pytest.raises(LensrtError, match="working memory"):
        simulate(big, dgauss, None, SimulateOptions(sensor="36x27", device="cpu"))


def test_cli_writes_linear_exr_png_and_sensor_outputs_with_sidecars(tmp_path, capsys):
    import json

    from lensrt.io.exr import read_exr
    from lensrt.io.png import write_png
    img = np.full((12, 16, 3), 0.6)
    img[:, 8:] = 0.2
    write_png(tmp_path / "in.png", img, 16)
    from lensrt.cli import main
    rc = main(["simulate", str(tmp_path / "in.png"), "--sensor", "16x12", "--grid", "2x2", "--rays", "2048",
               "--bands", "2", "--cache-dir", str(tmp_path / "c"), "--sensor-preset", "phone_12mp", "--iso", "200",
               "--no-noise", "--device", "cpu", "-o", str(tmp_path / "out" / "sim")])
    assert rc == 0, capsys.readouterr().err
    ch, meta = read_exr(tmp_path / "out" / "sim.exr")
    assert set(ch) == {"R", "G", "B", "Y_stderr"} and ch["G"].shape == (12, 16)
    assert ch["G"][:, :6].mean() > 2 * ch["G"][:, 10:].mean()  # the picture came through (0.6 vs 0.2 sRGB)
    for name in ("sim.json", "sim_raw.json", "sim_camera.json"):
        side = json.loads((tmp_path / "out" / name).read_text())
        assert {"psf_monte_carlo", "interpolation"} <= set(side["errors"])
    assert json.loads((tmp_path / "out" / "sim_raw.json").read_text())["sensor"]["iso"] == 200
    assert (tmp_path / "out" / "sim_raw.exr").is_file() and (tmp_path / "out" / "sim_camera.png").is_file()


def test_readers_png16_tiff16_exr_and_depth_codes(tmp_path):
    from lensrt.io.exr import write_exr
    from lensrt.io.png import write_png, write_tiff
    from lensrt.colour import srgb_decode
    from lensrt.simulate.inputs import read_depth_m, read_image_linear
    rng = np.random.default_rng(0)
    enc = rng.random((6, 9, 3))
    q16 = np.round(enc * 65535) / 65535
    write_png(tmp_path / "a.png", enc, 16)
    np.testing.assert_allclose(read_image_linear(tmp_path / "a.png"), srgb_decode(q16), atol=1e-6)  # all 16 bits
    write_tiff(tmp_path / "a.tif", enc, 16)
    np.testing.assert_allclose(read_image_linear(tmp_path / "a.tif"), srgb_decode(q16), atol=1e-6)
    lin = rng.random((6, 9, 3)) * 4.0  # HDR, linear
    write_exr(tmp_path / "a.exr", {"R": lin[..., 0], "G": lin[..., 1], "B": lin[..., 2]})
    np.testing.assert_allclose(read_image_linear(tmp_path / "a.exr"), lin, rtol=1e-6)
    codes = rng.integers(100, 60000, (6, 9))
    write_png(tmp_path / "d.png", np.repeat((codes / 65535.0)[..., None], 3, axis=2), 16)
    np.testing.assert_allclose(read_depth_m(tmp_path / "d.png", (6, 9), 0.001), codes * 0.001)
    with pytest.raises(LensrtError, match="depth-scale-m"):
        read_depth_m(tmp_path / "d.png", (6, 9))


def test_source_side_interpolation_is_exact_and_seamless():
    """A point anywhere gets exactly the bilinear blend of its four node PSFs (no seams, flux kept), and the
    all-bands FFT path equals the one-band one (float64 reference)."""
    from lensrt.simulate.convolve import convolve_varying
    from lensrt.simulate.psf_grid import blend_at, hat_weights, node_positions
    rng = np.random.default_rng(1)
    h, w, n = 30, 41, 9
    rows, cols = node_positions(h, 3), node_positions(w, 4)
    psf = rng.random((len(rows), len(cols), n, n))
    psf /= psf.sum(axis=(2, 3), keepdims=True)
    wr, wc = hat_weights(rows, h), hat_weights(cols, w)
    for r, c in [(7, 9), (15, 20), (22, 33), (14, 14)]:
        img = np.zeros((h, w, 1))
        img[r, c] = 1.0
        out = convolve_varying(img, psf, wr, wc, rows, cols)[..., 0]
        want = blend_at(psf, wr[:, r], wc[:, c])
        np.testing.assert_allclose(out[r - n // 2:r + n // 2 + 1, c - n // 2:c + n // 2 + 1], want, atol=1e-12)
        assert abs(out.sum() - 1.0) < 1e-12
    # the layer path (all bands at once, single-precision FFTs, only the tiles a layer needs) equals the
    # float64 one-band reference, over the plan's box, for a layer that covers part of the frame
    from lensrt.simulate.convolve import convolve_layer, tile_plan
    img = rng.random((3, h, w)).astype(np.float32)
    alpha = np.zeros((h, w), np.float32)
    alpha[:, 30:] = 1.0
    shared, own = img * alpha, img[:1] * alpha
    psfs = np.stack([psf, psf[::-1]]).astype(np.float32)
    plan = tile_plan(alpha, rows, cols, n // 2)
    assert plan.cells.sum() < plan.cells.size  # some cells are skipped
    blurred, ones = convolve_layer(shared, own, psfs, wr, wc, rows, cols, plan)
    r0, r1, c0, c1 = plan.box
    for k, p in enumerate((psf, psf[::-1])):
        ref = convolve_varying(np.concatenate([shared, own]).transpose(1, 2, 0), p, wr, wc, rows, cols)
        np.testing.assert_allclose(blurred[k].transpose(1, 2, 0), ref[r0:r1, c0:c1], atol=2e-6)
        one = convolve_varying(np.ones((h, w, 1)), p, wr, wc, rows, cols)[r0:r1, c0:c1, 0]
        lit = ref[r0:r1, c0:c1, 0] > 0  # where the layer shows, its normalisation is exact
        np.testing.assert_allclose(ones[k][lit], one[lit], atol=1e-6)
    assert c0 > 0  # the box leaves out what the layer's blur cannot reach


@pytest.mark.slow
def test_acceptance_against_the_path_tracer_on_a_textured_plane(tmp_path):
    """benchmarks/acceptance_simulate.py, smaller: per-pixel relative difference of Y <= 2 % RMS beyond the
    render's own noise, absolute scale within 1 % (the full-size numbers are in docs/guide/simulate.md)."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import acceptance_simulate as acc
    res = acc.run(acc.parser().parse_args(["--pixels", "48x36", "--spp", "256", "--rays", "16384", "--grid",
                                           "4x5", "--bands", "3", "--out", str(tmp_path)]))
    assert abs(res["mean_ratio_sim_over_render"] - 1.0) < 0.01, res
    assert res["rel_rms_beyond_noise"] < 0.02, res
    assert res["corners_rel_rms"] < 0.02 + res["corners_noise_rel_rms"], res


def test_layer_fill_continues_a_layer_behind_nearer_ones_only():
    """The disocclusion fill: a layer goes on behind nearer layers (never over farther ones) as far as the
    reach, with its own colour; each layer's input is independent of the layers drawn before it."""
    from lensrt.simulate.compose import LayerFill
    h, w = 40, 64
    img = np.zeros((h, w, 3), np.float32)
    idx = np.zeros((h, w), np.int32)
    idx[:, 20:40], idx[:, 40:] = 1, 2          # far (0) | middle (1) | near (2)
    img[:, :20], img[:, 20:40], img[:, 40:] = 0.2, 0.5, 0.9
    col, mask = LayerFill(img, idx)(1, 10)
    assert not mask[:, :20].any()              # not over the farther layer
    assert mask[:, 20:40].all() and mask[:, 40:50].all() and not mask[:, 60:].any()  # reach 10 (+ a block)
    np.testing.assert_allclose(col[mask], 0.5)  # its own colour
    fill = LayerFill(img, idx)
    fill(0, 30)
    again, mask1 = fill(1, 10)
    np.testing.assert_array_equal(again, col)
    np.testing.assert_array_equal(mask1, mask)
    np.testing.assert_array_equal(fill(2, 0)[0][:, 40:], img[:, 40:])  # the nearest layer is not continued
