"""Tilt-shift: the whole lens tilted/shifted in front of a fixed sensor, traced by the generic kernels.

Oracle: the Scheimpflug condition (Field Guide to Geometrical Optics, tan(theta') = m tan(theta)),
with the sensor's tilt seen from the lens and m from the lens's first-order data; the plane in
sharpest focus is found with real rays (the RMS spot on the sensor minimised over the object
depth, at several heights along the plane), stopped down so that first-order optics holds.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order
from lensrt.prescription.frames import surface_frames
from lensrt.prescription.tilt_shift import lens_frame, tilt_shift_lens
from lensrt.trace import RayBatch, trace
from scheimpflug import scheimpflug_slopes

DG = "dgauss_50mm_f2"
D_LINE_NM = 587.6


def _sensor_z(lens, object_mm: float) -> float:
    """Camera sensor z at the paraxial image of an axial object ``object_mm`` in front of the lens (Newton)."""
    fo = first_order(lens)
    x = -object_mm - fo.front_focal_z_mm
    return float(fo.rear_focal_z_mm - fo.efl_mm ** 2 / x)


def _spot_rms(tilted, origin, rot, point_mm, sensor_z_mm: float, pupil, z_ep: float) -> float:
    """RMS radius on the sensor of rays from the lens-frame point ``point_mm`` through pupil points."""
    px, py = pupil
    p = origin + rot @ np.asarray(point_mm, dtype=np.float64)
    aim = (origin[:, None] + rot @ np.stack([px, py, np.full_like(px, z_ep)])).T
    d = aim - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    res = trace(tilted, RayBatch(np.repeat(p[None], len(d), 0), d, np.full(len(d), D_LINE_NM)), "float64", "cpu",
                plane_z_mm=sensor_z_mm)
    assert res.ok.all()
    xy = res.position_mm[:, :2]
    return float(np.sqrt(((xy - xy.mean(axis=0)) ** 2).sum(axis=1).mean()))


@pytest.mark.parametrize("tilt_deg,swing_deg,shift_mm,object_mm", [(5.0, 0.0, (0.0, 0.0), 1000.0),
                                                                   (-8.0, 0.0, (0.0, 4.0), 600.0),
                                                                   (3.0, 0.0, (2.0, 0.0), 3000.0),
                                                                   (0.0, 6.0, (0.0, 0.0), 800.0),
                                                                   (4.0, -5.0, (1.0, 1.0), 1500.0)])
def test_sharpest_plane_obeys_scheimpflug(tilt_deg: float, swing_deg: float, shift_mm, object_mm: float) -> None:
    lens = load_lens(DG)
    tilt, swing = math.radians(tilt_deg), math.radians(swing_deg)
    sensor_z = _sensor_z(lens, object_mm)
    tilted = tilt_shift_lens(lens, tilt, shift_mm, swing_rad=swing)
    origin, rot = lens_frame(tilt, shift_mm, float(lens.vertex_z_mm()[lens.stop_index]), swing)
    z0, slopes = scheimpflug_slopes(lens, tilt, shift_mm, sensor_z, swing)
    fo = first_order(lens)
    # a pupil grid stopped down to a fifth of the entrance pupil (f/10): first-order optics holds
    g = np.linspace(-1.0, 1.0, 9)
    px, py = np.meshgrid(g, g)
    inside = px ** 2 + py ** 2 <= 1.0
    r_ep = 0.1 * fo.entrance_pupil_diameter_mm
    pupil = (px[inside] * r_ep, py[inside] * r_ep)
    heights = np.linspace(-1.0, 1.0, 7) * 0.045 * abs(z0)
    for axis in (0, 1):  # along x (swing), along y (tilt)
        if abs(slopes[axis]) < 0.1:
            continue
        best = []
        for h in heights:
            zg = z0 + slopes[axis] * h

            def rms(z: float, h: float = h) -> float:
                point = [0.0, 0.0, z]
                point[axis] = h
                return _spot_rms(tilted, origin, rot, point, sensor_z, pupil, fo.entrance_pupil_z_mm)
            best.append(minimize_scalar(rms, bracket=(zg * 0.97, zg * 1.03), tol=1e-10).x)
        fitted = np.polyfit(heights, best, 2)[1]  # the quadratic term takes the field curvature
        got_deg, want_deg = math.degrees(math.atan(fitted)), math.degrees(math.atan(slopes[axis]))
        assert abs(got_deg - want_deg) < 0.2, (axis, got_deg, want_deg)
        # the plane is really tilted: far from the untilted lens's plane (dz/dy = 0)
        assert abs(want_deg) > 30.0


def test_tilt_shift_frames_and_identity() -> None:
    lens = load_lens(DG)
    assert tilt_shift_lens(lens) is lens
    tilted = tilt_shift_lens(lens, math.radians(6.0), (1.0, -2.0))
    o_img, a_img = surface_frames(tilted)[-1]
    assert np.allclose(a_img, np.eye(3), atol=1e-12)  # the image surface is the camera's sensor again
    assert np.allclose(o_img, [0.0, 0.0, lens.image_z_mm], atol=1e-9)
    o0, a0 = surface_frames(tilted)[0]
    origin, rot = lens_frame(math.radians(6.0), (1.0, -2.0), float(lens.vertex_z_mm()[lens.stop_index]))
    assert np.allclose(o0, origin) and np.allclose(a0, rot)
    # the stop's vertex is the pivot: it only moves by the shift
    assert np.allclose(surface_frames(tilted)[lens.stop_index][0],
                       [1.0, -2.0, lens.vertex_z_mm()[lens.stop_index]], atol=1e-9)
    # a pure shift of the lens moves the image of an axial point by the shift (1:1 for a far point)
    shifted = tilt_shift_lens(lens, 0.0, (0.0, 3.0))
    ray = RayBatch(np.array([[0.0, 3.0, -1e6]]), np.array([[0.0, 0.0, 1.0]]), np.array([D_LINE_NM]))
    a = trace(shifted, ray, "float64", "cpu")
    b = trace(lens, RayBatch(np.array([[0.0, 0.0, -1e6]]), np.array([[0.0, 0.0, 1.0]]), np.array([D_LINE_NM])),
              "float64", "cpu")
    assert a.position_mm[0, 1] == pytest.approx(b.position_mm[0, 1] + 3.0, abs=1e-9)


def test_tilt_shift_refuses_what_it_cannot_do() -> None:
    lens = load_lens(DG)
    with pytest.raises(LensrtError, match="45 deg"):
        tilt_shift_lens(lens, math.radians(60.0))
    with pytest.raises(LensrtError, match="finite"):
        tilt_shift_lens(lens, math.nan)
    with pytest.raises(LensrtError, match="swing 50 deg"):
        tilt_shift_lens(lens, 0.0, swing_rad=math.radians(50.0))
    with pytest.raises(LensrtError, match="centred refractive"):
        tilt_shift_lens(load_lens("reflex_nikkor_500mm_f8"), math.radians(2.0))
