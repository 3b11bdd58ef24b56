"""Raw conversion: tone curves, demosaicing, white balance, colour matrix, SOS, end-to-end ColorChecker."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lensrt.errors import LensrtError
from lensrt.colour import STANDARD_WAVELENGTHS_NM, srgb_decode, srgb_encode, srgb_matrix_for_white
from lensrt.colour import spectrum as illuminant_spd
from lensrt.isp import (Isp, IspSettings, SCurve, calibrate, demosaic, exposure_gain_for_iso, image_dynamic_range_stops,
                        quantize, sos_iso, tone_curve, white_balance_from_illuminant)
from lensrt.isp.colour import camera_responses, delta_e2000_srgb, xyz_of_reflectances
from lensrt.isp.metrics import neutral_output
from lensrt.sensor import Switches, expose, get_preset, parse_cfa, sensor_from_spec
from lensrt.sensor.exposure import (focal_plane_exposure_lux_s, illuminance_lux, metered_exposure_time_s,
                                    spectral_irradiance_from_illuminance)
from lensrt.sensor.targets import colorchecker_scene


@pytest.fixture(scope="module")
def ff():
    return get_preset("fullframe_24mp")


def test_srgb_encoding_matches_colour_science():
    import colour
    x = np.linspace(0, 1, 1001)
    assert np.allclose(srgb_encode(x), colour.cctf_encoding(x, "sRGB"), atol=2e-6)
    assert np.allclose(srgb_decode(srgb_encode(x)), x, atol=1e-5)


def test_image_dynamic_range_of_srgb_is_computed():
    # p. 70: the linear input reaching DOL 1 is (1/255)/12.92, so DR = log2(255 * 12.92) ~ 11.7 stops
    assert image_dynamic_range_stops("srgb", 8) == pytest.approx(math.log2(255 * 12.92), rel=1e-9)
    assert 11.6 < image_dynamic_range_stops("srgb", 8) < 11.8
    assert image_dynamic_range_stops("srgb", 16) == pytest.approx(math.log2(65535 * 12.92), rel=1e-9)
    # an S-curve's toe lifts the input that reaches DOL 1, so it records fewer stops than plain sRGB
    c = SCurve(1.5)
    lo = float(c.inverse(srgb_decode(np.array(1 / 255))))
    assert image_dynamic_range_stops(c) == pytest.approx(math.log2(1.0 / lo), rel=1e-9)
    assert 6 < image_dynamic_range_stops(c) < image_dynamic_range_stops("srgb")


def test_scurve_fixed_points_and_inverse():
    c = SCurve(contrast=1.5, mid_grey=0.18)
    assert float(c(np.array(0.18))) == pytest.approx(0.18, rel=1e-6)
    assert float(c(np.array(1.0))) == pytest.approx(1.0, rel=1e-6)
    x = np.linspace(0.001, 1, 200)
    y = c(x)
    assert np.all(np.diff(y) > 0)
    assert np.allclose(c.inverse(y), x, rtol=1e-4)
    # steeper than identity at mid-grey (more mid-tone contrast), flatter near white (shoulder)
    d = lambda f, v: (f(np.array(v * 1.01)) - f(np.array(v * 0.99))) / (0.02 * v)  # noqa: E731
    assert d(c, 0.18) > 1.0 and d(c, 0.95) < 1.0
    with pytest.raises(LensrtError):
        SCurve(contrast=1.2, mid_grey=1.5)


def test_quantize_levels():
    assert np.array_equal(quantize(np.array([0.0, 0.5, 1.0, 1.7]), 8), [0, 128, 255, 255])
    assert quantize(np.array([1.0]), 16)[0] == 65535
    assert tone_curve(np.array([2.0, -1.0]), "linear").tolist() == [1.0, 0.0]


@pytest.mark.parametrize("phase", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_normalized_demosaic_is_bilinear_on_bayer(phase):
    # the X-Trans method, run on a Bayer mosaic, must reproduce colour-demosaicing's bilinear
    rng = np.random.default_rng(2)
    mosaic = rng.uniform(0, 1, (24, 30)).astype(np.float32)
    cfa = parse_cfa(phase)
    a = demosaic(mosaic, cfa, "normalized")
    b = demosaic(mosaic, cfa, "bilinear")
    assert np.allclose(a[1:-1, 1:-1], b[1:-1, 1:-1], atol=1e-5)


@pytest.mark.parametrize("cfa_name,method", [("RGGB", "bilinear"), ("GBRG", "malvar2004"), ("BGGR", "menon2007"),
                                             ("XTRANS", "normalized"), ("RGB/GBR/BRG", "bilinear")])
def test_demosaic_of_a_flat_colour_is_that_colour(cfa_name, method):
    cfa = parse_cfa(cfa_name)
    colour = np.array([0.2, 0.5, 0.8], np.float32)
    mosaic = colour[cfa.channel_map(36, 48)]
    out = demosaic(mosaic, cfa, method)
    assert np.allclose(out[3:-3, 3:-3], colour, atol=1e-4)


def test_bayer_only_methods_refuse_xtrans():
    with pytest.raises(LensrtError, match="Bayer"):
        demosaic(np.zeros((12, 12)), parse_cfa("XTRANS"), "malvar2004")


def test_white_balance_makes_illuminant_neutral(ff):
    wl = STANDARD_WAVELENGTHS_NM
    for ill in ("D65", "A", 3200.0):
        wb = white_balance_from_illuminant(ff, ill)
        resp = camera_responses(ff, illuminant_spd(ill, wl), wl)[0] * wb
        assert wb[1] == 1.0 and np.allclose(resp, resp[1])
    # tungsten needs more blue gain than daylight (p. 62-64)
    assert white_balance_from_illuminant(ff, "A")[2] > white_balance_from_illuminant(ff, "D65")[2]


@pytest.mark.parametrize("illuminant", ["D65", "A"])
def test_colour_matrix_constraints(ff, illuminant):
    cal = calibrate(ff, illuminant)
    assert np.allclose(cal.camera_to_srgb.sum(axis=1), 1.0, atol=1e-12)  # rows sum to 1 (p. 61-63)
    assert np.allclose(cal.camera_to_xyz @ np.ones(3), cal.white_xyz, atol=1e-12)  # white preserved
    assert cal.fit_delta_e2000.mean() < 1.5  # noise-free fit quality on the 24 patches
    assert calibrate(ff, illuminant, "de2000").fit_delta_e2000.mean() <= cal.fit_delta_e2000.mean() + 1e-6


def test_constrained_lstsq_recovers_an_exact_matrix():
    from lensrt.isp.colour import white_preserving_lstsq
    rng = np.random.default_rng(0)
    M = rng.normal(size=(3, 3))
    C = rng.uniform(0, 1, (24, 3))
    M2 = white_preserving_lstsq(C, C @ M.T, np.ones(3), M @ np.ones(3))
    assert np.allclose(M2, M)


def _chart_run(sensor, illuminant="D65", iso=None, demosaic_method="bilinear", level=0.7, seed=1, wb="illuminant"):
    sc = colorchecker_scene(24, illuminant)
    white_e = float((sc.spectra[18] / sc.reflectance[18]) @ sensor.electron_weights(sc.wavelength_nm)[:, 1])
    iso = iso or sensor.base_iso
    clip_e = (sensor.white_level_dn(iso) - sensor.bias_dn) * sensor.g_e_per_dn(iso)
    t = level * clip_e / white_e
    raw = expose(sensor, sc.spectra, sc.wavelength_nm, t, labels=sc.labels, iso=iso, rng=np.random.default_rng(seed))
    settings = IspSettings(illuminant=illuminant, demosaic=demosaic_method, exposure_gain=1 / level,
                           white_balance=wb, grey_region=sc.boxes[21])
    out = Isp(sensor, settings).develop(raw)
    got = np.array([out.linear[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0) for r0, r1, c0, c1 in sc.boxes])
    X, white = xyz_of_reflectances(sc.reflectance, illuminant, sc.wavelength_nm)
    # the ISP's target: Bradford from the adopted white to the sRGB white, then linear sRGB with white -> (1, 1, 1)
    return delta_e2000_srgb(got, X @ srgb_matrix_for_white(white).T), out


@pytest.mark.parametrize("method", ["bilinear", "malvar2004"])
def test_end_to_end_colorchecker_d65_bayer(ff, method):
    # measured: mean dE2000 1.10 (max 4.1, cyan) at ISO 100, white at 70 % of clipping; the matrix fit alone gives 1.09
    de, out = _chart_run(ff, demosaic_method=method)
    assert de.mean() < 1.5, de.round(2)
    assert de.max() < 5.0
    assert out.to_uint16().dtype == np.uint16 and out.to_uint8().shape == (96, 144, 3)


def test_end_to_end_xtrans_tungsten_high_iso(ff):
    s = sensor_from_spec({"preset": "fullframe_24mp", "cfa": "XTRANS"})
    de, _ = _chart_run(s, illuminant="A", iso=800, demosaic_method="normalized")
    assert de.mean() < 2.0, de.round(2)


def test_grey_patch_white_balance_matches_illuminant(ff):
    de_grey, out = _chart_run(ff, wb="grey")
    assert np.allclose(out.wb_multipliers, white_balance_from_illuminant(ff, "D65"), rtol=0.01)
    assert de_grey.mean() < 1.5


def test_exposure_photometry_round_trip():
    wl = STANDARD_WAVELENGTHS_NM
    E = spectral_irradiance_from_illuminance(250.0, "D65", wl)
    assert float(illuminance_lux(E, wl)) == pytest.approx(250.0)
    # p. 75: metering sets t = K N^2 / (L S), so the sensor-plane exposure is H = q K / S
    t = metered_exposure_time_s(luminance_cd_m2=400.0, f_number=8.0, iso=200)
    assert focal_plane_exposure_lux_s(400.0, 8.0, t) == pytest.approx(0.65 * 12.5 / 200)


def test_sos_iso_scales_with_iso_and_gain(ff):
    isp = Isp(ff)
    s100, s400 = sos_iso(isp, 100), sos_iso(isp, 400)
    assert s400 / s100 == pytest.approx(4.0, rel=1e-9)
    gain = exposure_gain_for_iso(isp, 100)
    calibrated = isp.with_settings(exposure_gain=gain)
    assert sos_iso(calibrated, 100) == pytest.approx(100.0, rel=1e-9)
    # by definition, H_SOS = 10 / S renders the neutral at DOL 118 (p. 77)
    rgb = neutral_output(calibrated, 100, 10.0 / 100)
    assert np.allclose(quantize(srgb_encode(rgb), 8), 118)


def test_sos_point_matches_a_simulated_frame(ff):
    # the noise-free neutral model agrees with a simulated, noisy, developed flat field
    isp = Isp(ff).with_settings(exposure_gain=exposure_gain_for_iso(Isp(ff), 100))
    wl = STANDARD_WAVELENGTHS_NM
    E = spectral_irradiance_from_illuminance(10.0, "D65", wl)  # 10 lux for H = 0.1 lux s
    raw = expose(ff, E, wl, 0.01, shape=(64, 64), rng=np.random.default_rng(0))
    out = isp.develop(raw)
    assert abs(out.to_uint8()[4:-4, 4:-4].mean() - 118) < 1.0


def test_noiseless_switch_matches_mean(ff):
    wl = STANDARD_WAVELENGTHS_NM
    E = spectral_irradiance_from_illuminance(50.0, "D65", wl)
    a = expose(ff, E, wl, 0.01, shape=(8, 8), rng=np.random.default_rng(0), switches=Switches.noiseless())
    assert a.dn.dtype == np.float32 and np.ptp(a.dn[::2, ::2]) == 0
