"""Renders measured like a lab measures a lens, against geometric rays of the trace API.

* A slanted edge at 10 deg field: the edge spread measured from the render (ISO 12233-style
  supersampling across the fitted edge) against the edge spread predicted from the point spread of
  the edge's midpoint -- real rays over its real pupil box (lensrt.trace.stream.pupil_box,
  float64 store kernel), projected across the edge and averaged over the pixel aperture.
* A distortion grid: the corner crossing's measured position against the real chief ray (and the
  centroid of the real point spread, which coma moves off the chief ray by ~2 um at f/8).

Both use 5 um pixels (a 36 mm wide, 7200-pixel sensor) and render only a 64 x 64 / 48 x 48 window.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.loading import load_lens
from lensrt.render.camera import setup_camera
from lensrt.render.integrator import render
from lensrt.render.setup import RenderOptions
from lensrt.render.scene.load import loads_scene
from lensrt.trace import RayBatch, trace
from lensrt.trace.aiming import FieldPoint, aim_rays, ray_through_point
from lensrt.trace.reference import trace_reference
from lensrt.trace.stream import pupil_box

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")]

LAM = 587.56


def _chief_on_sensor(lens, cam, point_mm) -> np.ndarray:
    """Where the real chief ray (aimed at the centre of the real stop) of an object point meets the sensor."""
    fp = FieldPoint(False, None, tuple(point_mm))
    o, d, ok = aim_rays(lens, fp, np.zeros(1), np.zeros(1), LAM, "real")
    assert ok[0]
    q = trace_reference(lens, tuple(o[0]), tuple(d[0]), LAM, clip=False)
    t = (cam.sensor_z_mm - q.z_mm) / q.N
    return np.array([q.x_mm + t * q.L, q.y_mm + t * q.M])


def _psf_rays(lens, cam, point_mm, n: int = 300_000, seed: int = 1):
    """Real rays of an object point (Lambertian, facing +z) over its real pupil box: sensor (x, y) mm and weights."""
    fp = FieldPoint(False, None, tuple(point_mm))
    box = pupil_box(lens, fp, [LAM], stop_radius_mm=cam.stop_radius_mm, device="cpu")
    rng = np.random.default_rng(seed)
    pts = box.points(box.a0 + rng.random(n) * (box.a1 - box.a0), box.b0 + rng.random(n) * (box.b1 - box.b0))
    o, d = ray_through_point(fp, pts)
    tr = trace(lens, RayBatch(o, d, LAM), "float64", "cpu", stop_radius_mm=cam.stop_radius_mm,
               plane_z_mm=cam.sensor_z_mm)
    # solid angle per box area (cos / rho^2) times the Lambertian emitter's cos
    w = (d @ np.asarray(box.axis)) / np.sum((pts - np.asarray(point_mm)) ** 2, axis=1) * d[:, 2]
    return tr.position_mm[tr.ok, :2], w[tr.ok]


def _scene(texture: str, extra: str, f_number: float) -> object:
    return loads_scene(f"""
[scene]
name = "chart"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 1.5
f_number = {f_number}
[sensor]
format = "full-frame"
pixels = 7200
[[plane]]
name = "chart"
{extra}
texture = "{texture}"
emission = {{ spectrum = {{ line_nm = {LAM} }}, radiance_scale = 10.0 }}
""")


def _crossing(x, y, level):
    i = int(np.nonzero(y >= level)[0][0])
    return x[i - 1] + (level - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1])


def test_slanted_edge_spread_matches_the_real_psf():
    """Edge of a 5-deg slanted square at (0.275, 0.002, -1.5) m (10.4 deg field), f/2.8, 5 um pixels.

    Measured: per-row 50 % crossings -> fitted edge line -> pixels binned by distance to it (1/2 px)
    -> ESF normalised by the plateaus beyond 16 px. Predicted: the weighted distribution of real-ray
    distances across the same line, averaged over the pixel square and the bin. Tolerances: the
    edge's angle to 0.004 (chief rays give it), the ESFs bin by bin (Monte Carlo
    noise: 4 standard errors per bin from the render's own per-pixel errors, plus 0.01 for the plateau
    levels and the PSF's change across the window) and the 25-75 % widths within 6 %.
    """
    scene = _scene("slanted_edge", "center = [0.25, 0.0, -1.5]\nsize = [0.1, 0.1]", 2.8)
    lens = load_lens("dgauss_50mm_f2")
    cam = setup_camera(scene, lens)
    a = math.radians(5.0)
    mid = np.array([250.0 + 25.0 * math.cos(a), 25.0 * math.sin(a), -1500.0])    # the square's right edge
    row, col = cam.sensor.pixel_of(*_chief_on_sensor(lens, cam, mid))
    r0, c0 = int(round(float(row))) - 32, int(round(float(col))) - 32
    res = render(scene, lens, RenderOptions(samples_per_pixel=256, spp_per_pass=32, window=(r0, r0 + 64, c0, c0 + 64),
                                            device="cpu", seed=4))
    E = res.irradiance[..., 0].astype(np.float64)
    rows, cols = E.shape
    # measured edge line from the per-row 50 % crossings
    level = 0.5 * (np.percentile(E, 5) + np.percentile(E, 95))
    c50 = []
    for r in range(rows):
        ii = np.nonzero(np.diff(np.sign(E[r] - level)))[0]
        i = ii[np.argmin(np.abs(ii - cols / 2))]
        c50.append(i + (level - E[r, i]) / (E[r, i + 1] - E[r, i]))
    b, a0 = np.polyfit(np.arange(rows), c50, 1)
    q1 = _chief_on_sensor(lens, cam, mid - 4.0 * np.array([-math.sin(a), math.cos(a), 0.0]))
    q2 = _chief_on_sensor(lens, cam, mid + 4.0 * np.array([-math.sin(a), math.cos(a), 0.0]))
    (ra, ca), (rb, cb) = cam.sensor.pixel_of(*q1), cam.sensor.pixel_of(*q2)
    assert abs(b - (cb - ca) / (rb - ra)) < 0.004
    norm = math.sqrt(1.0 + b * b)
    R, C = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    s = (C - a0 - b * R) / norm
    lo, hi = E[s < -16].mean(), E[s > 16].mean()
    sign = 1.0 if hi > lo else -1.0
    s, (lo, hi) = sign * s, sorted((lo, hi))
    bw = 0.5
    edges = np.arange(-16.0, 16.0 + bw, bw)
    idx = np.digitize(s.ravel(), edges) - 1
    ok = (idx >= 0) & (idx < len(edges) - 1)
    cnt = np.bincount(idx[ok], minlength=len(edges) - 1)
    esf = np.bincount(idx[ok], weights=E.ravel()[ok], minlength=len(edges) - 1) / np.maximum(cnt, 1)
    sc = 0.5 * (edges[1:] + edges[:-1])
    # per-bin standard error from the render's per-pixel standard errors (batch means over passes)
    se_px = (res.xyz_stderr[..., 1] / np.maximum(res.xyz[..., 1], 1e-300) * E).ravel()
    se_bin = np.sqrt(np.bincount(idx[ok], weights=se_px[ok] ** 2, minlength=len(edges) - 1)) / np.maximum(cnt, 1)
    esf, se_bin = (esf - lo) / (hi - lo), se_bin / (hi - lo)
    # predicted from real rays across the same line
    xy, w = _psf_rays(lens, cam, mid)
    pr, pc = cam.sensor.pixel_of(xy[:, 0], xy[:, 1])
    sp = sign * ((pc - c0) - a0 - b * (pr - r0)) / norm
    order = np.argsort(sp)
    cdf = np.cumsum(w[order]) / w.sum()
    g = (np.arange(12) + 0.5) / 12 - 0.5
    U, V = np.meshgrid(g, g)
    offs = (((U - b * V) / norm).ravel()[:, None] + ((np.arange(4) + 0.5) / 4 - 0.5)[None, :] * bw).ravel()
    xs = np.linspace(-16.0, 16.0, 641)
    pred = np.array([np.interp(x + offs, sp[order], cdf, left=0.0, right=1.0).mean() for x in xs])
    m50, p50 = _crossing(sc, esf, 0.5), _crossing(xs, pred, 0.5)
    diff = esf - np.interp(sc - m50 + p50, xs, pred)
    inner = np.abs(sc - m50) < 14
    assert np.all(np.abs(diff[inner]) < 4.0 * se_bin[inner] + 0.01)
    w_meas = _crossing(sc, esf, 0.75) - _crossing(sc, esf, 0.25)
    w_pred = _crossing(xs, pred, 0.75) - _crossing(xs, pred, 0.25)
    assert w_pred > 1.0                                    # resolved: the lens's blur spans pixels
    assert abs(w_meas / w_pred - 1.0) < 0.06
    assert abs(m50 - p50) < 0.5                            # the edge sits where the rays put it


def test_distortion_grid_corner_is_where_the_real_chief_ray_lands():
    """Crossing of bright grid lines at (0.48, 0.32, -1.5) m (near the full-frame corner, 19.4 mm image
    height), f/8: its measured centroid against the real chief ray (distortion moves it ~0.28 mm from
    the paraxial image) and against the real PSF centroid. Tolerances: 1 um from the PSF centroid
    (0.2 px; Monte Carlo noise ~0.1 um), and from the chief ray by the PSF centroid's own offset + 1 um."""
    scene = _scene("grid", "center = [0.0, 0.0, -1.5]\nsize = [1.28, 0.8]\ncells = [16, 10]\n"
                           "line_width = 0.01\nlow = 1.0\nhigh = 0.0", 8.0)
    lens = load_lens("dgauss_50mm_f2")
    cam = setup_camera(scene, lens)
    point = np.array([480.0, 320.0, -1500.0])
    chief = _chief_on_sensor(lens, cam, point)
    paraxial = cam.magnification * point[:2]
    assert np.linalg.norm(chief - paraxial) > 0.1                 # distortion is resolved
    row, col = cam.sensor.pixel_of(*chief)
    r0, c0 = int(round(float(row))) - 24, int(round(float(col))) - 24
    res = render(scene, lens, RenderOptions(samples_per_pixel=256, spp_per_pass=32, window=(r0, r0 + 48, c0, c0 + 48),
                                            device="cpu", seed=5))
    E = res.irradiance[..., 0].astype(np.float64)
    cr, cc = row - r0, col - c0
    R, C = np.meshgrid(np.arange(48), np.arange(48), indexing="ij")
    h = 14.0
    for _ in range(30):                       # centroid in a square window re-centred on it (a cross is symmetric)
        wr = np.clip(np.minimum(R + 0.5, cr + h) - np.maximum(R - 0.5, cr - h), 0.0, 1.0)
        wc = np.clip(np.minimum(C + 0.5, cc + h) - np.maximum(C - 0.5, cc - h), 0.0, 1.0)
        wgt = wr * wc * E
        cr, cc = (wgt * R).sum() / wgt.sum(), (wgt * C).sum() / wgt.sum()
    measured = np.array([float(v) for v in res.position_of(cr, cc)])
    xy, w = _psf_rays(lens, cam, point, 200_000)
    centroid = np.average(xy, axis=0, weights=w)
    assert np.linalg.norm(measured - centroid) < 1e-3
    assert np.linalg.norm(measured - chief) < np.linalg.norm(centroid - chief) + 1e-3
