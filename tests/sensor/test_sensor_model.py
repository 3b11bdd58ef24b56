"""Sensor model: CFA layouts, gain/ISO/read-noise formulas, QE and photon counting (Field Guide p. 38-51)."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from lensrt.errors import LensrtError
from lensrt.sensor import (PRESETS, Switches, electrons_to_raw, expose, get_preset, load_response, mean_photoelectrons, parse_cfa,
                           sensor_from_spec)
from lensrt.sensor.spectral import integration_weights_nm, ir_cut_transmission
from lensrt.units import LIGHT_SPEED_M_S, PLANCK_J_S


@pytest.fixture(scope="module")
def ff():
    return get_preset("fullframe_24mp")


@pytest.mark.parametrize("phase", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_bayer_phases(phase):
    cfa = parse_cfa(phase)
    m = cfa.channel_map(4, 6)
    letters = "RGB"
    assert "".join(letters[c] for c in (m[0, 0], m[0, 1], m[1, 0], m[1, 1])) == phase
    assert np.array_equal(m[:2, :2], m[2:4, 2:4])  # period 2
    assert cfa.is_bayer and np.allclose(cfa.fractions(), [0.25, 0.5, 0.25])
    assert parse_cfa(cfa.pattern) == cfa


def test_xtrans_layout():
    cfa = parse_cfa("X-Trans")
    t = cfa.tile_array()
    assert t.shape == (6, 6)
    assert (t == 1).sum() == 20 and (t == 0).sum() == 8 and (t == 2).sum() == 8
    for axis in (0, 1):  # every row and column holds R, G and B (p. 38)
        assert all({0, 1, 2} <= set(line) for line in np.moveaxis(t, axis, 0).tolist())
    assert not cfa.is_bayer


def test_custom_cfa_and_errors():
    cfa = parse_cfa("RGB/GBR/BRG")
    assert cfa.shape == (3, 3) and np.allclose(cfa.fractions(), 1 / 3)
    for bad in ["RGX/GBR", "RG/GBR", "RR/GG", ""]:
        with pytest.raises(LensrtError):
            parse_cfa(bad)


def test_gain_doubles_per_iso_doubling_and_unity_gain(ff):
    # p. 42-43: G_ISO doubles with each ISO doubling; g = g_base base/ISO; unity gain U where g = 1
    g = [ff.g_e_per_dn(ff.base_iso * 2 ** k) for k in range(6)]
    assert np.allclose(np.array(g[:-1]) / np.array(g[1:]), 2.0)
    assert ff.g_base_e_per_dn == pytest.approx(1 / (ff.conversion_gain_uv_per_e * 1e-3 * ff.adc_gain_dn_per_mv))
    assert ff.g_e_per_dn(ff.unity_gain_iso) == pytest.approx(1.0)
    assert ff.analog_gain(3200) == ff.iso_less_iso / ff.base_iso and ff.digital_gain(3200) == 3200 / ff.iso_less_iso


def test_read_noise_falls_to_isoless_then_flat(ff):
    isos = [100, 200, 400, 800, 1600, 3200, 6400]
    rn = [ff.read_noise_e(i) for i in isos]
    assert all(a > b for a, b in zip(rn[:4], rn[1:4]))  # falls up to ISO-less (800)
    assert np.allclose(rn[3:], rn[3])  # flat after it (p. 50)
    assert rn[0] == pytest.approx(math.hypot(ff.read_noise_upstream_e, ff.read_noise_downstream_e))
    assert rn[3] == pytest.approx(math.hypot(ff.read_noise_upstream_e, ff.read_noise_downstream_e / 8))


def test_raw_dynamic_range_formula(ff):
    for iso in (100, 800, 6400):
        clip = ff.white_level_dn(iso) - ff.bias_dn
        assert ff.raw_dynamic_range_stops(iso) == pytest.approx(math.log2(clip / (ff.read_noise_e(iso) / ff.g_e_per_dn(iso))))
    # above ISO-less every ISO doubling costs exactly one stop (p. 51)
    assert ff.raw_dynamic_range_stops(1600) - ff.raw_dynamic_range_stops(3200) == pytest.approx(1.0)


def test_iso_out_of_range(ff):
    with pytest.raises(LensrtError):
        ff.g_e_per_dn(50)


def test_qe_is_ff_times_peak_times_curve(ff):
    wl = np.array([450.0, 530.0, 610.0])
    q = ff.qe(wl)
    expect = ff.fill_factor * np.asarray(ff.peak_qe) * ff.response.at(wl)
    assert np.allclose(q, expect)
    assert np.isclose(ff.qe(ff.response.wavelength_nm).max(axis=0), ff.fill_factor * np.asarray(ff.peak_qe)).all()
    cut = dataclasses.replace(ff, ir_cut_nm=650.0, ir_cut_width_nm=10.0)
    assert np.allclose(cut.qe(wl), q * ir_cut_transmission(wl, 650.0, 10.0)[:, None])
    assert ir_cut_transmission(np.array([650.0]), 650.0)[0] == pytest.approx(0.5)


def test_photon_count_formula_monochromatic(ff):
    # p. 40: n_e = (lambda / hc) A_p E t QE
    wl, E, t = 540.0, 0.02, 0.004  # nm, W/m^2 in a 1 nm band, s
    mean_e = mean_photoelectrons(ff, np.array([E]), np.array([wl]), t, bin_width_nm=1.0, shape=(4, 4))
    qe = ff.qe(np.array([wl]))[0]
    n_ph = wl * 1e-9 / (PLANCK_J_S * LIGHT_SPEED_M_S) * (ff.pixel_pitch_um * 1e-6) ** 2 * E * t
    cmap = ff.cfa.channel_map(4, 4)
    assert np.allclose(mean_e, n_ph * qe[cmap], rtol=1e-6)


def test_cube_labels_and_uniform_agree(ff):
    wl = np.linspace(400, 700, 31)
    rng = np.random.default_rng(3)
    spectra = rng.uniform(0, 0.01, (3, wl.size))
    labels = rng.integers(0, 3, (10, 12))
    cube = spectra[labels]
    a = mean_photoelectrons(ff, cube, wl, 0.01)
    b = mean_photoelectrons(ff, spectra, wl, 0.01, labels=labels)
    assert np.allclose(a, b, rtol=1e-5)
    c = mean_photoelectrons(ff, spectra[0], wl, 0.01, shape=(10, 12))
    assert np.allclose(c, mean_photoelectrons(ff, np.broadcast_to(spectra[0], (10, 12, wl.size)), wl, 0.01), rtol=1e-5)


def test_integration_weights():
    wl = np.array([400.0, 410.0, 430.0])
    assert np.allclose(integration_weights_nm(wl), [5.0, 15.0, 10.0])
    assert np.allclose(integration_weights_nm(wl, 10.0), 10.0)
    # trapezoid of a linear spectrum is exact
    assert integration_weights_nm(wl) @ (2 * wl) == pytest.approx(430 ** 2 - 400 ** 2)


@pytest.mark.parametrize("bad", ["nan", "negative", "shape"])
def test_bad_irradiance_is_an_error(ff, bad):
    wl = np.array([500.0, 600.0])
    E = np.full((4, 4, 2), 0.01)
    if bad == "nan":
        E[1, 1, 0] = np.nan
    elif bad == "negative":
        E[0, 0, :] = -1
    else:
        E = E[..., :1]
    with pytest.raises(LensrtError):
        expose(ff, E, wl, 0.01, rng=np.random.default_rng(0))


def test_noiseless_quantisation_formula(ff):
    # p. 43, 49: n_DN = INT(n_e / g) + bias
    mean_e = np.array([[0.0, 4.9, 5.0, 12345.6]], dtype=np.float32)
    for iso in (100, 400):
        raw = electrons_to_raw(ff, mean_e, 0.01, rng=np.random.default_rng(0), iso=iso,
                               switches=Switches.noiseless(quantize=True))
        g = ff.g_e_per_dn(iso)
        assert raw.dn.dtype == np.uint16
        assert np.array_equal(raw.dn, (np.floor(mean_e.astype(np.float64) / g) + ff.bias_dn).astype(np.uint16))


def test_presets_are_valid_and_documented():
    assert len(PRESETS) == 3
    for name in PRESETS:
        s = get_preset(name)
        assert s.sources and all(k in s.sources for k in ("full_well_e", "peak_qe", "read_noise_upstream_e", "adc_bits"))
        assert 10 < s.raw_dynamic_range_stops(s.base_iso) < 16
        assert s.white_level_dn(s.base_iso) <= s.adc_max_dn


def test_sensor_from_spec(tmp_path):
    s = sensor_from_spec({"preset": "apsc_16mp", "cfa": "XTRANS", "peak_qe": [0.3, 0.4, 0.3], "iso_less_iso": 800})
    assert s.cfa.name == "XTRANS" and s.peak_qe == (0.3, 0.4, 0.3) and s.sources["cfa"] == "user"
    with pytest.raises(LensrtError, match="unknown sensor key"):
        sensor_from_spec({"iso": 400})
    with pytest.raises(LensrtError, match="out of range"):
        sensor_from_spec({"fill_factor": 1.5})


def test_load_response_csv_json(tmp_path):
    csv = tmp_path / "qe.csv"
    csv.write_text("# my camera\nwavelength_nm,r,g,b\n400,0,0.1,0.8\n500,0.1,0.9,0.3\n600,0.8,0.2,0\n")
    r = load_response(csv)
    assert r.at(np.array([450.0]))[0] == pytest.approx([0.05, 0.5, 0.55])
    js = tmp_path / "qe.json"
    js.write_text(json.dumps({"wavelength_nm": [400, 500, 600], "r": [0, 0.1, 0.5], "g": [0.1, 0.5, 0.1],
                              "b": [0.5, 0.2, 0], "absolute": True}))
    r2 = load_response(js)
    assert r2.absolute
    s = sensor_from_spec({"response": str(js)})
    assert np.allclose(s.qe(np.array([500.0]))[0], s.fill_factor * np.array([0.1, 0.5, 0.2]))
    bad = tmp_path / "bad.csv"
    bad.write_text("wavelength_nm,r,g\n400,1,1\n500,1,1\n")
    with pytest.raises(LensrtError, match="missing column"):
        load_response(bad)
