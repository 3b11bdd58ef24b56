"""EMVA 1288 characterisation recovers the simulated sensor's parameters.

Tolerances come from the estimators' sampling error at these sizes (128 x 128 frames, 8192 green
photosites, ~16 levels in the photon-transfer fit): the fit's own standard error of K is
~0.7-1 %, so K and QE are checked to 3 % (about 3-4 standard errors); the temporal dark noise
(one dark pair, relative error of sigma ~0.8 %, plus the 1/12 DN^2 quantisation correction) to
5 %; DSNU and PRNU (16-frame stacks) to 12 %; the saturation capacity, which EMVA defines as
the level of maximum variance and so lies a little below the true clipping point, to within
-15 %/+2 % of the clipping point (the gap grows as the clip level falls
and the shot noise at it widens). The fixed seeds make each run reproducible.
"""
from __future__ import annotations

import numpy as np
import pytest

from lensrt.sensor import electrons_to_raw, get_preset, sensor_from_spec
from lensrt.sensor.emva import characterize, expected_emva, two_frame_gain

SIM = dict(n_levels=30, shape=(128, 128), n_stack=16)


@pytest.mark.parametrize("preset,iso", [("fullframe_24mp", 100), ("fullframe_24mp", 1600), ("apsc_16mp", 400),
                                        ("phone_12mp", 800)])
def test_emva_recovers_parameters(preset, iso):
    sensor = get_preset(preset)
    r, e = characterize(sensor, rng=np.random.default_rng(12), iso=iso, **SIM)
    assert r.system_gain_dn_per_e == pytest.approx(e["system_gain_dn_per_e"], rel=0.03)
    assert abs(r.system_gain_dn_per_e - e["system_gain_dn_per_e"]) < 4 * r.system_gain_stderr
    assert r.quantum_efficiency == pytest.approx(e["quantum_efficiency"], rel=0.03)
    assert not r.dark_noise_quantization_limited
    assert r.temporal_dark_noise_e == pytest.approx(e["temporal_dark_noise_e"], rel=0.05)
    assert r.dsnu_e == pytest.approx(e["dsnu_e"], rel=0.12)
    assert r.prnu_percent == pytest.approx(e["prnu_percent"], rel=0.12)
    assert 0.85 * e["saturation_capacity_e"] < r.saturation_capacity_e < 1.02 * e["saturation_capacity_e"]
    assert r.linearity_error_percent < 0.5
    # DR and SNR follow from the measured quantities (EMVA definitions)
    assert r.dynamic_range_stops == pytest.approx(np.log2(r.saturation_photons / r.sensitivity_threshold_photons))
    assert 10 ** (r.snr_max_db / 20) == pytest.approx(np.sqrt(r.saturation_capacity_e), rel=0.1)


def test_quantisation_limited_dark_noise_is_flagged():
    # a phone sensor at base ISO with read noise ~0.18 DN: dark variance below 0.24 DN^2 (EMVA's limit)
    s = sensor_from_spec({"preset": "phone_12mp", "read_noise_upstream_e": 0.5, "read_noise_downstream_e": 1.0})
    r, _ = characterize(s, rng=np.random.default_rng(1), **SIM)
    assert r.dark_noise_quantization_limited


def test_field_guide_two_frame_gain_agrees():
    # p. 48: pairs of flat frames at several levels; variance of the difference / 2 against mean above bias,
    # slope 1/g. An independent exposure series from the EMVA one, analysed without the dark correction.
    sensor = get_preset("apsc_16mp")
    rng = np.random.default_rng(21)
    g_true = sensor.g_e_per_dn(200)
    means, variances = [], []
    for level_e in np.linspace(500, 15000, 12):
        m = np.full((100, 100), level_e, np.float32)
        a = electrons_to_raw(sensor, m, 0.01, rng=rng, iso=200).dn.astype(float)
        b = electrons_to_raw(sensor, m, 0.01, rng=rng, iso=200).dn.astype(float)
        means.append(0.5 * (a.mean() + b.mean()) - sensor.bias_dn)
        variances.append(0.5 * np.var(a - b))
    g, read_dn = two_frame_gain(np.array(means), np.array(variances))
    assert g == pytest.approx(g_true, rel=0.02)
    r, _ = characterize(sensor, rng=np.random.default_rng(22), iso=200, **SIM)
    assert g == pytest.approx(r.g_e_per_dn, rel=0.03)


def test_read_noise_in_electrons_falls_with_iso_then_flat():
    # p. 50: measured from dark pairs, sigma_read(e-) = g sqrt(var(A - B) / 2 - 1/12)
    sensor = sensor_from_spec({"preset": "fullframe_24mp", "dark_current_e_per_s": 0.0})
    rng = np.random.default_rng(31)
    isos = [100, 200, 400, 800, 1600, 3200]
    measured = []
    for iso in isos:
        z = np.zeros((160, 160), np.float32)
        a = electrons_to_raw(sensor, z, 0.001, rng=rng, iso=iso).dn.astype(float)
        b = electrons_to_raw(sensor, z, 0.001, rng=rng, iso=iso).dn.astype(float)
        measured.append(sensor.g_e_per_dn(iso) * np.sqrt(0.5 * np.var(a - b) - 1 / 12))
    measured = np.array(measured)
    model = np.array([sensor.read_noise_e(i) for i in isos])
    assert np.allclose(measured, model, rtol=0.03)
    assert np.all(np.diff(measured[:4]) < 0)  # falls up to the ISO-less setting (800)
    flat = measured[3:]
    assert np.ptp(flat) / flat.mean() < 0.04  # then flat within the 1-2 % sampling error
    assert measured[0] / measured[3] > 2.5


def test_expected_values_follow_the_model():
    s = get_preset("fullframe_24mp")
    e = expected_emva(s, iso=400, exposure_s=2.0)
    assert e["system_gain_dn_per_e"] == pytest.approx(1 / s.g_e_per_dn(400))
    assert e["temporal_dark_noise_e"] == pytest.approx(np.sqrt(s.read_noise_e(400) ** 2 + s.dark_current_e_per_s * 2.0))
