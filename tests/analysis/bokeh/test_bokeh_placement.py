"""Bokeh source placement: the chief-ray object-height search of every source in one kernel launch.

Oracles: the host search (a batched float64 store-kernel trace per Newton step of every secant step, the
algorithm before the kernel) -- the same bits on the CPU, where Warp contracts no multiply-add -- and the
float64 NumPy reference tracer, whose real chief ray from each solved object point must land on its target.
"""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.analysis.bokeh.entry import focus_lens, near_far_depths_mm
from lensrt.analysis.bokeh.trace import object_heights_for_image
from lensrt.core.telemetry import measure
from lensrt.errors import LensrtError


def _both(lens, depths, radii, focus, device):
    """(host heights, host ok, host launches), (kernel heights, kernel ok, kernel launches)."""
    out = []
    for on_device in (False, None):
        with measure() as rec:
            y, ok = object_heights_for_image(lens, depths, focus.sensor_z_mm, radii, focus.wavelength_nm, device,
                                             on_device=on_device)
        out.append((y, ok, rec.launches))
    return out


def _same(a: np.ndarray, b: np.ndarray, ok: np.ndarray, device: str) -> None:
    if device == "cpu":
        assert np.array_equal(a, b)
    else:  # a GPU fuses multiply-adds in the kernel (not in NumPy): the secant may stop one step apart inside
        # its 1e-7 mm image tolerance, i.e. object heights apart by that over the magnification (<~ 1e-5 mm)
        assert np.allclose(a[ok], b[ok], rtol=1e-9, atol=1e-5)


def test_report_placement_is_one_launch_and_the_host_search_bit_for_bit(device):
    # the report's near/far map: 2 depths, heights from the axis to the corner of a 36 x 24 mm sensor
    lens = load_lens(None)
    focus = focus_lens(lens, 1000.0)
    depths = np.repeat(near_far_depths_mm(1000.0), 25)
    radii = np.tile(np.linspace(0.0, 21.6, 25), 2)
    (yh, okh, nh), (yk, okk, nk) = _both(lens, depths, radii, focus, device)
    assert nk == 1 and nh >= 20  # was a trace per Newton step of every secant step
    assert okk.all() and np.array_equal(okh, okk)
    _same(yh, yk, okh, device)
    assert np.all(yk[radii == 0.0] == 0.0) and np.all(np.diff(yk[1:25]) < 0)  # inverted image, monotonic


def test_strong_distortion_steps_back_toward_the_axis_in_the_kernel(device):
    # the macro lens focused far away: the paraxial start for 11-14 mm has no chief ray, so the kernel's
    # threads run the shrink and the halving branches; they must give the host's heights
    lens = load_lens("micro_nikkor_105mm_f2.8_macro")
    focus = focus_lens(lens, 2000.0)
    radii = np.array([8.0, 11.0, 14.0, 11.0])
    depths = np.array([1000.0, 1000.0, 1000.0, 3000.0])
    (yh, okh, nh), (yk, okk, nk) = _both(lens, depths, radii, focus, device)
    assert nk == 1 and nh > 30
    assert okk.all() and np.array_equal(okh, okk)
    _same(yh, yk, okh, device)


def test_solved_object_points_put_their_real_chief_rays_on_target(device):
    from lensrt.trace import RayBatch, trace
    from lensrt.trace.aiming import FieldPoint, aim_rays, reference_to_stop
    lens = load_lens(None)
    focus = focus_lens(lens, 2000.0)
    radii = np.array([3.0, 12.0, 20.0])
    y, ok = object_heights_for_image(lens, 5000.0, focus.sensor_z_mm, radii, focus.wavelength_nm, device)
    assert ok.all()
    for yk, r in zip(y, radii):
        fp = FieldPoint(False, None, (0.0, float(yk), -5000.0))
        o, d, aimed = aim_rays(lens, fp, np.zeros(1), np.zeros(1), focus.wavelength_nm, "real",
                               reference_to_stop(lens))
        hit = trace(lens, RayBatch(o, d, focus.wavelength_nm), "float64", device, clip=False,
                    plane_z_mm=focus.sensor_z_mm)
        assert aimed[0] and hit.ok[0]
        assert hit.position_mm[0, 1] == pytest.approx(r, abs=1e-6)


def test_no_chief_ray_is_one_clear_error_from_either_search():
    # an object point 20 mm behind the first vertex (inside the lens) has no chief ray: the kernel flags it and
    # the host raises what the host search raises, naming the first such depth
    lens = load_lens(None)
    focus = focus_lens(lens, 1000.0)
    for on_device in (False, None):
        with pytest.raises(LensrtError, match="no real chief ray from a point -20 mm"):
            object_heights_for_image(lens, [1000.0, -20.0, -60.0], focus.sensor_z_mm, 10.0, focus.wavelength_nm,
                                     "cpu", on_device=on_device)


def test_heights_beyond_the_image_circle_fail_alike_in_the_kernel(device):
    # the 10 mm fisheye: targets from 2 mm to beyond its image circle -- secant steps into heights with no chief
    # ray are halved hundreds of times and the far targets never converge; the kernel must say the same
    lens = load_lens("fisheye_10mm_f4")
    focus = focus_lens(lens, 1000.0)
    radii = np.linspace(2.0, 30.0, 15)
    (yh, okh, nh), (yk, okk, nk) = _both(lens, np.full(15, 1000.0), radii, focus, device)
    assert nk == 1 and nh > 30
    assert np.array_equal(okh, okk) and okk[0] and not okk[-1]
    _same(yh, yk, okh, device)
