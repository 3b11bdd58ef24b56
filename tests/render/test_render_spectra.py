"""Spectra on the render grid: photometry, XYZ/sRGB against colour-science, wavelength sampling."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

colour = pytest.importorskip("colour")

from lensrt.errors import LensrtError  # noqa: E402
import lensrt.colour as sp  # noqa: E402
from lensrt.render.spectra import WavelengthSampler  # noqa: E402
from lensrt.units import LUMINOUS_EFFICACY_LM_PER_W as KM  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

G = sp.DEFAULT_GRID
CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]


def _sd(values: np.ndarray, grid: sp.WavelengthGrid = G):
    return colour.SpectralDistribution(dict(zip(grid.nm, values)))


def test_grid_basics_and_errors():
    assert G.n == 81 and G.nm[0] == 380 and G.nm[-1] == 780
    assert G.weights_nm.sum() == pytest.approx(400.0)
    with pytest.raises(LensrtError, match="does not divide"):
        sp.WavelengthGrid(380, 780, 7)
    with pytest.raises(LensrtError):
        sp.WavelengthGrid(780, 380, 5)


def test_luminance_of_a_line_at_555nm_is_km():
    # 1 W/(m^2 sr) concentrated in a narrow triangle at 555 nm: L_v = K_m V(555) = K_m
    g = sp.WavelengthGrid(550, 560, 0.01)
    v = np.maximum(0.0, 1.0 - np.abs(g.nm - 555.0) / 0.05) / 0.05       # unit area, 0.1 nm wide
    assert sp.integrate(v, g) == pytest.approx(1.0, rel=1e-9)
    assert sp.luminous_value(v, g) == pytest.approx(KM * 1.0, rel=1e-4)


@pytest.mark.parametrize("name", ["D65", "A", "FL2", "LED-B3"])
def test_scale_to_luminance_matches_colour_luminous_flux(name):
    rel = sp.spectrum(name, G)
    radiance = sp.scale_to_luminous(rel, 1000.0, G)
    # colour-science's own photometric integral (trapezoid over the SD's samples, its V(lambda))
    lv = colour.luminous_flux(_sd(radiance), K_m=KM)
    assert lv == pytest.approx(1000.0, rel=1e-6)
    # and Y of its CIE 1931 XYZ with k = K_m is the same luminance (y-bar = V(lambda))
    xyz = colour.sd_to_XYZ(_sd(radiance), CMFS.copy().align(G.shape()), k=KM, method="Integration")
    assert xyz[1] == pytest.approx(1000.0, rel=2e-3)


def test_luminance_on_a_fine_grid_agrees_with_the_coarse_one():
    fine = sp.WavelengthGrid(380, 780, 1)
    rel = sp.spectrum("D65", G)
    radiance = sp.scale_to_luminous(rel, 100.0, G)
    assert sp.luminous_value(np.interp(fine.nm, G.nm, radiance), fine) == pytest.approx(100.0, rel=5e-3)


def test_blackbody_is_planck_radiance_per_nm():
    t = 3000.0
    lam_m = 560e-9
    h, c, kb = 6.62607015e-34, 299792458.0, 1.380649e-23
    planck = 2 * h * c ** 2 / lam_m ** 5 / math.expm1(h * c / (lam_m * kb * t)) * 1e-9    # W/(m^2 sr nm)
    v = sp.planck_radiance(t, G)[np.searchsorted(G.nm, 560.0)]
    assert v == pytest.approx(planck, rel=2e-4)      # colour uses c2 = 1.4388e-2 m K (ITS-90)


def test_unknown_illuminant_suggests():
    with pytest.raises(LensrtError, match="unknown illuminant") as err:
        sp.spectrum("D56", G)
    assert "D65" in str(err.value) or "D55" in str(err.value)
    assert np.allclose(sp.spectrum("F2", G), sp.spectrum("FL2", G))


@pytest.mark.parametrize("patch", ["dark skin", "blue", "white 9.5 (.05 D)"])
@pytest.mark.parametrize("illum", ["D65", "A"])
def test_reflectance_xyz_matches_colour_sd_to_xyz(patch, illum):
    cc = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][patch]
    refl = sp.colorchecker_reflectances(G, "ColorChecker N Ohta")[sp.colorchecker_names().index(patch)]
    assert np.allclose(refl, cc.values)                                  # same data on the same grid
    ill = sp.spectrum(illum, G)
    ours = sp.reflectance_to_xyz(refl, ill, G)
    ref = colour.sd_to_XYZ(cc, CMFS.copy().align(G.shape()), _sd(ill), method="Integration")
    # trapezoid (ours) vs rectangle (colour 'Integration') differ only by the half end weights
    assert np.allclose(ours, ref, rtol=2e-3, atol=2e-3)
    # and the ASTM E308 tables on colour's own grid agree to within a colour-science tolerance
    astm = colour.sd_to_XYZ(cc, CMFS, colour.SDS_ILLUMINANTS[illum])
    assert np.allclose(ours, astm, rtol=1e-2, atol=0.2)


def test_emissive_xyz_absolute_and_srgb_white():
    # D65 at 100 cd/m^2 -> Y = 100 and linear sRGB (1, 1, 1) * 100 (sRGB white is D65)
    d65 = sp.scale_to_luminous(sp.spectrum("D65", G), 100.0, G)
    xyz = sp.spectral_to_xyz(d65, G)
    assert xyz[1] == pytest.approx(100.0, rel=1e-9)
    rgb = sp.xyz_to_linear_srgb(xyz)
    assert np.allclose(rgb / 100.0, 1.0, atol=3e-3)
    assert np.allclose(sp.linear_srgb_to_xyz(rgb), xyz, rtol=1e-3)      # colour's rounded IEC matrices
    ref = colour.sd_to_XYZ(_sd(d65), CMFS.copy().align(G.shape()), k=KM, method="Integration")
    assert np.allclose(xyz, ref, rtol=2e-3)


def test_mallett_basis_is_colour_sciences_recovery():
    rng = np.random.default_rng(0)
    for rgb in rng.uniform(0, 1, (5, 3)):
        ours = sp.linear_rgb_to_reflectance(rgb, G)
        ref = colour.recovery.RGB_to_sd_Mallett2019(rgb)
        assert np.allclose(ours, ref.values, atol=1e-12)
    refl = sp.linear_rgb_to_reflectance(rng.uniform(0, 1, (1000, 3)), G)
    assert refl.min() >= 0.0 and refl.max() <= 1.0 + 1e-9
    # the basis reproduces the colour: D65-lit reflectance of (r, g, b) -> linear sRGB (r, g, b)
    rgb = np.array([0.7, 0.3, 0.1])
    xyz = sp.reflectance_to_xyz(sp.linear_rgb_to_reflectance(rgb, G), sp.spectrum("D65", G), G) / 100.0
    assert np.allclose(sp.xyz_to_linear_srgb(xyz), rgb, atol=0.01)


def test_srgb_decode_encode_roundtrip():
    x = np.linspace(0, 1, 11)
    assert np.allclose(sp.srgb_encode(sp.srgb_decode(x)), x)
    assert sp.srgb_decode(np.array(0.5)) == pytest.approx(0.2140, abs=1e-4)


def test_sampler_chi_square_and_pdf():
    rng = np.random.default_rng(42)
    weight = sp.spectrum("FL11", G) * sp.cie_xyz_cmfs(G).sum(axis=0)
    s = WavelengthSampler.from_weight(G, weight, uniform_fraction=0.1)
    lam, pdf = s.sample(rng.random(200_000))
    assert lam.min() >= 380 and lam.max() <= 780
    counts = np.histogram(lam, bins=G.nm)[0]
    expected = s.probabilities * lam.size
    keep = expected > 5
    chi2 = ((counts[keep] - expected[keep]) ** 2 / expected[keep]).sum()
    assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-3
    assert np.allclose(pdf, s.pdf(lam))
    assert s.probabilities.min() >= 0.1 / (G.n - 1) - 1e-12                  # defensive uniform part
    assert np.sum(s.pdf(G.nm[:-1] + 0.5 * G.step_nm) * G.step_nm) == pytest.approx(1.0, rel=1e-12)


def test_importance_sampled_estimate_is_unbiased():
    rng = np.random.default_rng(7)
    f = sp.spectrum("LED-B3", G) * sp.cie_xyz_cmfs(G)[1]                 # a peaky integrand
    exact = sp.integrate(f, G)
    for sampler in (WavelengthSampler.uniform(G), WavelengthSampler.from_weight(G, f)):
        lam, pdf = sampler.sample(rng.random(100_000))
        est = G.interp(f, lam) / pdf
        z = (est.mean() - exact) / (est.std(ddof=1) / math.sqrt(est.size))
        # the piecewise-linear integrand integrates exactly to the trapezoid value
        assert abs(z) < 4.0, (sampler.label, est.mean(), exact)
