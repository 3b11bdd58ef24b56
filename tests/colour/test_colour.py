"""lensrt.colour: the one illuminant syntax, its deprecated spellings, and the colorimetry against oracles."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

colour = pytest.importorskip("colour")

import lensrt.colour as lc  # noqa: E402
from lensrt.errors import LensrtDeprecationWarning, LensrtError  # noqa: E402

G = lc.DEFAULT_GRID


@pytest.mark.parametrize("text,kind,name", [
    ("D65", "cie", "D65"), ("d65", "cie", "D65"), ("A", "cie", "A"), ("F2", "cie", "FL2"), ("FL11", "cie", "FL11"),
    ("LED-B3", "cie", "LED-B3"), ("E", "cie", "E"), ("planck:3200K", "planck", "planck:3200K"),
    ("Planck:3200", "planck", "planck:3200K"), ("daylight:5000K", "daylight", "daylight:5000K"),
    ("lines:486.1,587.6", "lines", "lines:486.1,587.6"),
])
def test_one_syntax_raises_no_warning(text, kind, name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ill = lc.parse_illuminant(text)
    assert ill.kind == kind and ill.name == name
    assert lc.parse_illuminant(ill) is ill                       # objects pass through
    assert lc.parse_illuminant(ill.name).name == ill.name        # the canonical name reads back


@pytest.mark.parametrize("old,new", [("blackbody:3200", "planck:3200K"), ("bb:2700K", "planck:2700K"),
                                     (3200, "planck:3200K"), (3200.0, "planck:3200K"), ("3200K", "planck:3200K"),
                                     ("5000K", "daylight:5000K"), (6500, "daylight:6500K")])
def test_old_spellings_work_with_a_deprecation_naming_the_new_one(old, new):
    with pytest.warns(LensrtDeprecationWarning, match=new):
        ill = lc.parse_illuminant(old)
    assert ill.name == new


def test_bare_wavelengths_where_bokeh_read_them():
    with pytest.warns(LensrtDeprecationWarning, match="lines:486.1,587.6"):
        ill = lc.parse_illuminant("486.1, 587.6", bare_numbers="nm")
    assert ill.lines_nm == (486.1, 587.6) and ill.line_weights == (1.0, 1.0)


@pytest.mark.parametrize("text,msg", [("D66", "did you mean D65"), ("planck:warm", "planck:3200K"),
                                      ("planck:50K", "outside 100-100000 K"), ("daylight:3000K", "outside 4000-25000"),
                                      ("lines:", "one or more"), ("lines:a,b", "lines:486.1"), ("", "unknown")])
def test_bad_names_are_one_clear_error(text, msg):
    with pytest.raises(LensrtError, match=msg):
        lc.parse_illuminant(text)


def test_daylight_6500_is_d65_and_daylight_5000_is_d50():
    # CIE 015: D65 and D50 are daylight at the nominal 6500 K and 5000 K (c2 = 1.4380e-2 m K)
    for t, cie in ((6500, "D65"), (5000, "D50")):
        d = lc.daylight(t).relative(G)
        ref = lc.cie_illuminant(cie).relative(G)
        assert np.max(np.abs(d - ref)) < 2e-3, (t, np.max(np.abs(d - ref)))


def test_planck_is_planck_law_and_differs_from_daylight():
    h, c, kb = 6.62607015e-34, 299792458.0, 1.380649e-23
    nm = np.array([450.0, 550.0, 650.0])
    t = 5000.0
    ref = 2 * h * c ** 2 / (nm * 1e-9) ** 5 / np.expm1(h * c / (nm * 1e-9 * kb * t)) * 1e-9
    assert np.allclose(lc.planck(t).values(nm), ref, rtol=2e-4)          # colour uses c2 = 1.4388e-2 m K
    # the grey-card bug: a 5000 K Planck radiator is not CIE daylight 5000 K (chromaticity apart)
    xy = [colour.XYZ_to_xy(lc.spectral_to_xyz(lc.spectrum(n, G), G)) for n in ("planck:5000K", "daylight:5000K")]
    assert np.hypot(*(xy[0] - xy[1])) > 0.005


def test_lines_have_no_density_and_tables_are_strict_on_request():
    with pytest.raises(LensrtError, match="line spectrum"):
        lc.spectrum("lines:550", G)
    with pytest.raises(LensrtError, match="tabulated over 380-780 nm"):
        lc.cie_illuminant("FL2").values(np.array([370.0, 500.0]), strict=True)
    assert lc.cie_illuminant("FL2").values(np.array([370.0]))[0] == 0.0
    t = lc.tabulated([400.0, 500.0, 600.0], [0.0, 1.0, 0.0], "tent")
    assert t.values(np.array([450.0, 700.0])).tolist() == [0.5, 0.0] and t.label == "tent"


def test_srgb_curves_match_the_iec_formula():
    x = np.linspace(0.0, 1.0, 2001)
    iec = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)      # IEC 61966-2-1
    assert np.allclose(lc.srgb_encode(x), iec, atol=1e-12)
    assert np.allclose(lc.srgb_decode(lc.srgb_encode(x)), x, atol=1e-12)


def test_white_maps_to_white():
    rng = np.random.default_rng(3)
    for white in (np.array([1.0985, 1.0, 0.3558]), np.array([0.9505, 1.0, 1.089]), rng.uniform(0.5, 1.5, 3)):
        m = lc.srgb_matrix_for_white(white)
        assert np.allclose(m @ white, 1.0, atol=1e-13)
    lab = lc.linear_srgb_to_lab(np.full(3, 0.18))
    assert abs(lab[1]) < 0.01 and abs(lab[2]) < 0.01       # the IEC matrix is rounded to 4 decimals


def test_cmfs_and_v_on_any_grid():
    cm = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    nm = np.array([360.0, 555.0, 600.5, 830.0, 900.0])
    got = lc.cie_xyz_cmfs(nm)
    assert got.shape == (3, 5) and got[:, -1].tolist() == [0.0, 0.0, 0.0]
    assert np.allclose(got[:, 1], cm[555]) and np.allclose(got[:, 2], 0.5 * (cm[600] + cm[601]))
    assert lc.photopic_v(np.array([555.0]))[0] == pytest.approx(1.0, abs=1e-4)
    assert np.allclose(lc.cie_xyz_cmfs(G), lc.cie_xyz_cmfs(G.nm))       # grid and array agree


def test_chart_is_one_copy_with_names():
    names = lc.colorchecker_names()
    refl = lc.colorchecker_reflectances(lc.STANDARD_WAVELENGTHS_NM)
    assert len(names) == 24 == refl.shape[0] and names[18].startswith("white")
    ohta = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    assert np.allclose(refl[0], ohta[names[0]].values[:81]) or np.allclose(
        refl[0], np.interp(lc.STANDARD_WAVELENGTHS_NM, ohta[names[0]].wavelengths, ohta[names[0]].values))
    with pytest.raises(LensrtError, match="unknown ColorChecker"):
        lc.colorchecker_names("ColorChecker 1976x")


def test_illuminance_lux_is_the_trapezoid_of_v():
    nm = lc.STANDARD_WAVELENGTHS_NM
    e = lc.spectrum("D65", nm)
    assert float(lc.illuminance_lux(e, nm)) == pytest.approx(float(lc.luminous_value(e, G)), rel=1e-12)
    assert math.isclose(float(lc.illuminance_lux(np.zeros_like(nm), nm)), 0.0)
