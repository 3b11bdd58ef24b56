"""Noise statistics of the sensor chain, tested statistically with fixed seeds (Field Guide p. 46-50).

Tolerances are z-scores against the sampling error of the estimator: for n independent samples
the sample mean has standard error sigma / sqrt(n) and the sample variance has relative standard
error sqrt(2 / (n - 1)) (Gaussian; Poisson's excess kurtosis 1/mu adds a negligible term at
these means). |z| < 4 fails a correct model with probability ~6e-5 per check.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lensrt.errors import LensrtError
from lensrt.sensor import (Switches, average_frames, dark_frame, electrons_to_raw, fixed_pattern_maps, get_preset,
                           subtract_dark)

N = 200_000
SHAPE = (400, 500)


@pytest.fixture(scope="module")
def sensor():
    return get_preset("fullframe_24mp")


def _z_mean(x, mu, sigma):
    return (x.mean() - mu) / (sigma / math.sqrt(x.size))


def _z_var(x, var):
    return (x.var(ddof=1) / var - 1) / math.sqrt(2 / (x.size - 1))


@pytest.mark.parametrize("mean_e", [3.0, 50.0, 1000.0, 20000.0])
def test_shot_noise_is_poisson(sensor, mean_e):
    # only shot noise; unquantised, so DN = n_e / g + bias exactly
    sw = Switches(shot_noise=True, dark_current=False, read_noise=False, fixed_pattern=False, quantize=False)
    raw = electrons_to_raw(sensor, np.full(SHAPE, mean_e, np.float32), 0.01, rng=np.random.default_rng(11), switches=sw)
    e = (raw.dn.astype(np.float64) - sensor.bias_dn) * raw.g_e_per_dn
    assert abs(_z_mean(e, mean_e, math.sqrt(mean_e))) < 4
    assert abs(_z_var(e, mean_e)) < 4  # variance = mean (p. 46)
    assert np.allclose(e, np.round(e), atol=1e-2 * max(1, mean_e / 1000))  # whole electrons


@pytest.mark.parametrize("exposure_s", [0.5, 4.0, 30.0])
def test_dark_current_mean_and_shot_noise_grow_with_time(sensor, exposure_s):
    s = dataclasses.replace(sensor, dark_current_e_per_s=2.0)
    sw = Switches(read_noise=False, fixed_pattern=False, quantize=False)
    raw = electrons_to_raw(s, np.zeros(SHAPE, np.float32), exposure_s, rng=np.random.default_rng(5), switches=sw)
    e = (raw.dn.astype(np.float64) - s.bias_dn) * raw.g_e_per_dn
    mu = 2.0 * exposure_s
    assert abs(_z_mean(e, mu, math.sqrt(mu))) < 4
    assert abs(_z_var(e, mu)) < 4


@pytest.mark.parametrize("iso", [100, 400, 800, 3200])
def test_read_noise_in_dn(sensor, iso):
    sw = Switches(shot_noise=False, dark_current=False, fixed_pattern=False, quantize=False)
    raw = electrons_to_raw(sensor, np.zeros(SHAPE, np.float32), 0.01, rng=np.random.default_rng(7), iso=iso, switches=sw)
    dn = raw.dn.astype(np.float64) - sensor.bias_dn
    sigma = sensor.read_noise_dn(iso)
    assert abs(_z_mean(dn, 0.0, sigma)) < 4
    assert abs(_z_var(dn, sigma ** 2)) < 4


def test_quantisation_adds_one_twelfth(sensor):
    # floor() of a Gaussian wider than ~1 DN: variance sigma^2 + 1/12 DN^2, mean shifted by -1/2 DN
    s = dataclasses.replace(sensor, read_noise_upstream_e=10.0, read_noise_downstream_e=0.0)
    sw = Switches(shot_noise=False, dark_current=False, fixed_pattern=False, quantize=True)
    raw = electrons_to_raw(s, np.full(SHAPE, 1000.0, np.float32), 0.01, rng=np.random.default_rng(8), switches=sw)
    dn = raw.dn.astype(np.float64)
    sigma = 10.0 / s.g_e_per_dn(100)
    assert abs(_z_var(dn, sigma ** 2 + 1 / 12)) < 4
    assert abs(_z_mean(dn, 1000 / 5 + s.bias_dn - 0.5, sigma)) < 4


def test_full_well_and_adc_clipping(sensor):
    raw = electrons_to_raw(sensor, np.full((50, 50), 1e6, np.float32), 0.01, rng=np.random.default_rng(1))
    assert raw.dn.max() == sensor.adc_max_dn
    small = dataclasses.replace(sensor, full_well_e=30000.0)
    sw = Switches(read_noise=False, fixed_pattern=False, dark_current=False)
    raw = electrons_to_raw(small, np.full((50, 50), 1e6, np.float32), 0.01, rng=np.random.default_rng(1), switches=sw)
    assert np.all(raw.dn == int(30000 / small.g_e_per_dn(100)) + small.bias_dn)
    assert raw.white_level_dn == 30000 / 5 + small.bias_dn


def test_fixed_pattern_is_deterministic_per_seed(sensor):
    a = fixed_pattern_maps(sensor, 64, 80)
    b = fixed_pattern_maps(dataclasses.replace(sensor), 64, 80)
    c = fixed_pattern_maps(dataclasses.replace(sensor, seed=99), 64, 80)
    assert np.array_equal(a["prnu_gain"], b["prnu_gain"])
    assert not np.array_equal(a["prnu_gain"], c["prnu_gain"])
    g = fixed_pattern_maps(sensor, *SHAPE)
    assert abs(_z_mean(g["prnu_gain"].astype(float), 1.0, sensor.prnu)) < 4
    assert abs(_z_var(g["prnu_gain"].astype(float), sensor.prnu ** 2)) < 4
    assert abs(_z_var(g["dsnu_offset_e"].astype(float), sensor.dsnu_e ** 2)) < 4
    d = g["dark_current_scale"].astype(float)
    assert d.min() > 0 and abs(d.mean() - 1) < 0.01 and abs(d.std() / sensor.dark_current_nonuniformity - 1) < 0.03


def test_same_generator_seed_same_frame(sensor):
    m = np.full((32, 32), 500.0, np.float32)
    a = electrons_to_raw(sensor, m, 0.01, rng=np.random.default_rng(3))
    b = electrons_to_raw(sensor, m, 0.01, rng=np.random.default_rng(3))
    assert np.array_equal(a.dn, b.dn)
    with pytest.raises(TypeError):
        electrons_to_raw(sensor, m, 0.01, rng=3)


def test_frame_averaging_divides_variance(sensor):
    # p. 46: averaging N frames reduces temporal noise variance by N
    sw = Switches(fixed_pattern=False, dark_current=False, quantize=False)
    m = np.full((200, 250), 2000.0, np.float32)
    rng = np.random.default_rng(4)
    one = electrons_to_raw(sensor, m, 0.01, rng=rng, switches=sw)
    avg = average_frames([electrons_to_raw(sensor, m, 0.01, rng=rng, switches=sw) for _ in range(8)])
    assert avg.n_frames == 8 and avg.dn.dtype == np.float32
    ratio = one.dn.var() / avg.dn.var()
    assert abs(ratio / 8 - 1) < 4 * math.sqrt(2 * 2 / m.size)
    with pytest.raises(LensrtError):
        average_frames([])


def test_dark_subtraction_removes_dsnu_and_dark_mean(sensor):
    # p. 47: a master dark removes the fixed pattern; what remains is temporal noise only
    s = dataclasses.replace(sensor, dsnu_e=20.0, dark_current_e_per_s=50.0, dark_current_nonuniformity=0.5)
    rng = np.random.default_rng(9)
    shape = (200, 200)
    raw = electrons_to_raw(s, np.zeros(shape, np.float32), 2.0, rng=rng)
    master = dark_frame(s, shape, 2.0, rng=rng, n_frames=32)
    out = subtract_dark(raw, master)
    assert out.black_level_dn == 0.0
    assert abs(out.dn.mean()) < 0.05
    # temporal variance of one frame (dark shot + read) times (1 + 1/32), in DN^2
    g = s.g_e_per_dn(100)
    temporal = (100.0 + s.read_noise_e(100) ** 2) / g ** 2 + 1 / 12
    assert abs(out.dn.var() / (temporal * (1 + 1 / 32)) - 1) < 0.05
    before = raw.dn.astype(float) - s.bias_dn
    assert before.var() > 3 * out.dn.var()  # the fixed pattern was the larger part
