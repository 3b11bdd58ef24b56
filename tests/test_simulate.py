"""Image simulation (lensrt.simulate, ``lensrt simulate``): oracles on small images and few rays.

* uniform white -> the output's falloff is lensrt's real relative illumination
  (lensrt.analysis.vignetting, an independent flux computation) within 1 %;
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
    from lensrt.analysis.vignetting import vignetting
    sim = simulate(np.ones(SHAPE + (3,), np.float32), dgauss, None, _opts(cache, ri_rays=1 << 16, bands=1))
    # the oracle: vignetting's flux method at the field angles of 5 points along the picture's diagonal
    cam = sim.camera
    opt = sim.layers[0]
    idx = np.array([5, 12, 20, 30, 36])
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


def _spot(lens, cam, row, col, depth_mm):
    """Centroid (row, col) and RMS radius (px) of the bokeh tracer's spot of the object point at depth_mm
    whose real chief ray lands on picture pixel (row, col), in picture coordinates."""
    from lensrt.analysis.bokeh import bokeh_spot, spot_source
    x, y = _sensor_xy(cam, row, col)
    src = spot_source(lens, cam.focus, depth_mm, image_mm=(float(x), float(y)), device="cpu")
    spot = bokeh_spot(lens, cam.focus, src, light="587.6", rays=1 << 16, device="cpu")
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
    ref_r, ref_c, ref_rms = _spot(dgauss, sim.camera, *_chief_pixel(sim, pixel, 1000.0), 1000.0)
    rr, cc = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    rms = math.sqrt(float((((rr - r_c) ** 2 + (cc - c_c) ** 2) * out).sum() / out.sum()))
    rms_ref = math.sqrt(ref_rms ** 2 + 2.0 / 12.0)  # the PSF integrated over square pixels
    assert abs(r_c - ref_r) < 0.15 and abs(c_c - ref_c) < 0.15, ((r_c, c_c), (ref_r, ref_c))
    assert abs(rms / rms_ref - 1.0) < 0.05, (rms, rms_ref)
    assert ref_rms > 1.5  # the spot spans pixels: the shape was tested


def _chief_pixel(sim, pixel, depth_mm):
    """Picture (row, col) where the real chief ray of the input pixel's direction lands (forward trace)."""
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
    o, d, ok = chief_rays(cam.lens, [FieldPoint(False, None, obj)], cam.wavelength_nm, to_stop, fallback=True)
    assert ok[0]
    res = trace(cam.lens, RayBatch(o, d, np.full(1, cam.wavelength_nm)), "float64", "cpu", clip=False,
                plane_z_mm=cam.sensor_z_mm)
    x, y = res.position_mm[0, :2]
    return 0.5 * (cam.shape[0] - 1) + y / cam.pitch_mm, 0.5 * (cam.shape[1] - 1) - x / cam.pitch_mm
