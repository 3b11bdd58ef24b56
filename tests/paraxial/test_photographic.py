"""The Field Guide's photographic formulas against worked values and paraxial traces."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order, marginal_ray, paraxial_system, pupils
from lensrt.paraxial import photographic as ph


def test_bellows_factor_is_two_at_unit_magnification() -> None:
    """b = 1 + |m|/mp = 2 at 1:1 with mp = 1; Nw = b N (p. 31)."""
    assert ph.bellows_factor(-1.0, 1.0) == 2.0
    assert ph.working_f_number(2.8, -1.0, 1.0) == pytest.approx(5.6, rel=1e-15)
    assert ph.bellows_factor(0.5, 0.5) == 2.0  # a telephoto (mp < 1) loses more light
    assert ph.magnification_at_distance(100.0, 50.0) == 1.0  # s = 2f: |m| = f / (s - f) (p. 8)
    assert ph.magnification_at_distance(math.inf, 50.0) == 0.0


def test_afov_and_focus_breathing() -> None:
    """alpha = 2 atan(d / (2 b f)) (p. 17); a unit-focusing lens narrows its field at close focus (p. 18)."""
    assert math.degrees(ph.afov_rad(36.0, 50.0)) == pytest.approx(39.5978, abs=5e-5)
    assert math.degrees(ph.afov_rad(math.hypot(36, 24), 50.0)) == pytest.approx(46.7930, abs=5e-5)
    s = np.array([math.inf, 5000.0, 1000.0, 100.0])
    a = ph.focus_breathing_afov_rad(s, 50.0, 36.0, 1.0)
    assert a[0] == ph.afov_rad(36.0, 50.0)
    assert np.all(np.diff(a) < 0)
    assert a[-1] == pytest.approx(2 * math.atan(36.0 / (4 * 50.0)), rel=1e-15)  # 1:1, b = 2


def test_unit_focus_extension_and_inverse() -> None:
    """e = f^2 / (s - f) (p. 12): 50 mm at 550 mm needs 5 mm; 1:1 needs e = f."""
    assert ph.unit_focus_extension_mm(550.0, 50.0) == pytest.approx(5.0, rel=1e-15)
    assert ph.unit_focus_extension_mm(100.0, 50.0) == pytest.approx(50.0, rel=1e-15)
    assert ph.unit_focus_extension_mm(math.inf, 50.0) == 0.0
    assert ph.unit_focus_object_distance_mm(5.0, 50.0) == pytest.approx(550.0, rel=1e-15)
    assert math.isinf(ph.unit_focus_object_distance_mm(0.0, 50.0))
    s = np.array([120.0, 700.0, 1e5])
    np.testing.assert_allclose(ph.unit_focus_object_distance_mm(ph.unit_focus_extension_mm(s, 50.0, 65.0), 50.0, 65.0),
                               s, rtol=1e-13)
    with pytest.raises(LensrtError):
        ph.unit_focus_extension_mm(40.0, 50.0)


def test_formats_multiplier_and_coc() -> None:
    """R = d1/d2 (p. 19) and the CoC table (p. 22)."""
    assert set(ph.SENSOR_FORMATS) == {"full-frame", "aps-c", "mft", "1-inch", "2/3-inch", "1/1.7-inch",
                                      "1/2.5-inch"}
    ff = ph.sensor_format("full-frame")
    assert ff.crop_factor == 1.0 and ff.coc_mm == 0.030
    aps = ph.sensor_format("APS-C")
    assert aps.crop_factor == pytest.approx(math.hypot(36, 24) / math.hypot(23.6, 15.7), rel=1e-15)
    assert aps.crop_factor == pytest.approx(1.5264, abs=5e-5)
    assert ph.sensor_format("m43").crop_factor == pytest.approx(1.9994, abs=5e-5)
    assert ph.equivalent_focal_length_mm(25.0, ph.sensor_format("mft").crop_factor) == pytest.approx(49.98, abs=5e-3)
    assert [f.coc_mm for f in ph.SENSOR_FORMATS.values()] == [0.030, 0.020, 0.015, 0.011, 0.008, 0.006, 0.005]
    for f in ph.SENSOR_FORMATS.values():  # the table follows c = 0.030 mm / R within its rounding
        assert ph.coc_diameter_mm(f.diagonal_mm) == pytest.approx(f.coc_mm, rel=0.1)
    custom = ph.sensor_format("6.4x4.8")
    assert (custom.width_mm, custom.height_mm) == (6.4, 4.8)
    assert custom.coc_mm == pytest.approx(0.030 * 8.0 / math.hypot(36, 24), rel=1e-15)
    with pytest.raises(LensrtError, match="unknown sensor format"):
        ph.sensor_format("vistavision")


def test_hyperfocal_and_depth_of_field_worked_example() -> None:
    """50 mm f/8, c = 0.03 mm, focused at 3 m (s_EP = 0): h = f^2/(cN) = 31250/3 mm (p. 24)."""
    assert ph.hyperfocal_distance_mm(50.0, 8.0, 0.03) == pytest.approx(31250 / 3 + 50, rel=1e-15)
    assert ph.hyperfocal_distance_mm(50.0, 8.0, 0.03, s_ep_mm=10.0) == pytest.approx(31250 / 3 + 40, rel=1e-15)
    dof = ph.depth_of_field_mm(3000.0, 50.0, 8.0, 0.03)
    assert dof.near_mm == pytest.approx(93750000 / 40100, rel=1e-14)  # 2337.905 mm
    assert dof.far_mm == pytest.approx(93750000 / 22400, rel=1e-14)  # 4185.268 mm
    assert dof.total_mm == pytest.approx(93750000 / 22400 - 93750000 / 40100, rel=1e-14)
    at_h = ph.depth_of_field_mm(dof.hyperfocal_mm, 50.0, 8.0, 0.03, 0.0)
    assert at_h.near_mm == pytest.approx(dof.hyperfocal_mm / 2, rel=1e-14) and math.isinf(at_h.far_mm)
    inf = ph.depth_of_field_mm(math.inf, 50.0, 8.0, 0.03)
    assert inf.near_mm == pytest.approx(31250 / 3, rel=1e-15) and math.isinf(inf.total_mm)


def test_depth_of_field_limits_blur_exactly_one_coc_through_a_real_lens(library_dir) -> None:
    """Trace the axial points at the near and far limits through the double Gauss: blur = c (with s_EP)."""
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    z_ep0 = first_order(lens).entrance_pupil_z_mm
    u = 1500.0  # focus distance from the entrance pupil
    fo = first_order(lens, object_distance_mm=u - z_ep0)
    assert abs(fo.entrance_pupil_distance_mm) > 10.0  # the pupil term matters for this lens
    c = 0.03
    dof = ph.depth_of_field_mm(u, fo.front_focal_length_mm, fo.f_number, c, fo.entrance_pupil_distance_mm)
    sysm = paraxial_system(lens)
    pup = pupils(sysm)
    sensor = fo.image_distance_mm
    for u_x in (dof.near_mm, dof.far_mm):
        ray = marginal_ray(sysm, u_x - pup.entrance_z_mm, pup.entrance_z_mm, fo.entrance_pupil_diameter_mm)
        assert 2 * abs(ray.height_at(sensor)) == pytest.approx(c, rel=1e-9)
    # ignoring the pupil term misplaces the limits: the blur there is not c
    wrong = ph.depth_of_field_mm(u, fo.front_focal_length_mm, fo.f_number, c)
    ray = marginal_ray(sysm, wrong.far_mm - pup.entrance_z_mm, pup.entrance_z_mm, fo.entrance_pupil_diameter_mm)
    assert abs(2 * abs(ray.height_at(sensor)) / c - 1) > 1e-3
    hyper = ph.hyperfocal_distance_mm(fo.front_focal_length_mm, fo.f_number, c, fo.entrance_pupil_distance_mm)
    at_h = ph.depth_of_field_mm(hyper, fo.front_focal_length_mm, fo.f_number, c, fo.entrance_pupil_distance_mm)
    assert math.isinf(at_h.far_mm) and at_h.near_mm == pytest.approx(hyper / 2, rel=1e-12)


def test_camera_equation_exposure_and_t_number() -> None:
    """E = (pi/4) L T cos^4 / Nw^2, H = E t (p. 31-33); T# = N / sqrt(T) (p. 34)."""
    assert ph.image_illuminance_lux(1000.0, 2.0) == pytest.approx(math.pi / 4 * 1000 / 4, rel=1e-15)
    assert ph.image_illuminance_lux(1000.0, 2.0, 0.9, math.radians(30)) == pytest.approx(
        math.pi / 4 * 1000 * 0.9 * 0.5625 / 4, rel=1e-14)
    assert ph.exposure_lux_s(200.0, 1 / 125) == pytest.approx(1.6, rel=1e-15)
    assert ph.t_number(2.0, 0.81) == pytest.approx(2.0 / 0.9, rel=1e-15)


def test_eighteen_percent_grey_meters_to_the_iso_midtone_exposure() -> None:
    """Meter t/N^2 = K/(<L> S), K = 10/0.65 (p. 75); with q = (pi/4) T cos^4 = 0.65 the sensor gets H = 10/S."""
    lux = 10000.0
    grey = 0.18 * lux / math.pi  # luminance of an 18 % Lambertian grey card, cd/m^2
    for iso in (100.0, 400.0):
        t = ph.meter_exposure_time_s(grey, 8.0, iso)
        assert t == pytest.approx(10 / 0.65 * 64 / (grey * iso), rel=1e-15)
        T = 0.65 * 4 / math.pi  # q = 0.65 on axis
        H = ph.exposure_lux_s(ph.image_illuminance_lux(grey, 8.0, T), t)
        assert H == pytest.approx(10.0 / iso, rel=1e-14)


def test_exposure_value_and_apex() -> None:
    """EV = log2(N^2/t); Av + Tv = Bv + Sv for a metered exposure (p. 78)."""
    assert ph.exposure_value(1.0, 1.0) == 0.0
    assert ph.exposure_value(4.0, 1 / 16) == pytest.approx(8.0, abs=1e-14)
    assert ph.apex_av(4.0) == pytest.approx(4.0, abs=1e-15)
    assert ph.apex_tv(1 / 16) == pytest.approx(4.0, abs=1e-15)
    assert ph.apex_sv(100.0) == pytest.approx(5.0, abs=1e-15)
    L, iso, N = 750.0, 200.0, 5.6
    t = ph.meter_exposure_time_s(L, N, iso)
    assert ph.apex_av(N) + ph.apex_tv(t) == pytest.approx(ph.apex_bv(L) + ph.apex_sv(iso), abs=1e-12)
    assert ph.exposure_value(N, t) == pytest.approx(ph.apex_av(N) + ph.apex_tv(t), abs=1e-12)
