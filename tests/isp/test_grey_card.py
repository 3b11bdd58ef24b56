"""A grey card develops neutral under every illuminant (issue 24, item 4).

The chain is the one ``lensrt render`` runs for the colorchecker_d65 scene after the render:
the scene file's ``[illumination]`` -> the sensor-plane spectral irradiance of an 18 % grey
Lambertian card in the render's 10 nm bands -> :func:`lensrt.pipeline.sensor_stage` (the
scene's sensor preset, noise off, the ISP with the scene's illuminant as adopted white, SOS exposure
gain, Malvar demosaicing). Only the lens trace is left out: it carries no colour (T = 1) and its
Monte Carlo noise would hide the 0.5 limit behind spectral sampling noise.

Before the fix a 5000 K Planck radiator was white-balanced as CIE daylight (the ISP read the
display label "blackbody 5000 K" back as a colour temperature and took D5000): a* +0.30,
b* -0.81 in the issue's render; 'F2' was not a name the sensor knew.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lensrt.colour import linear_srgb_to_lab
from lensrt.errors import LensrtDeprecationWarning
from lensrt.pipeline import isp_illuminant, sensor_stage
from lensrt.render.scene.load import loads_scene

SCENES = Path(__file__).resolve().parents[2] / "scenes"
BAND_NM = 10.0          # the render's default output band (RenderOptions.band_width_nm)
GREY = 0.18


def _scene(spectrum_toml: str):
    text = (SCENES / "colorchecker_d65.toml").read_text(encoding="utf-8")
    text = text.replace('spectrum = "D65"', f"spectrum = {spectrum_toml}").replace("noise = true", "noise = false")
    return loads_scene(text, SCENES / "colorchecker_d65.toml")


def _grey_card_render(scene, shape=(24, 36)):
    """What a converged render of the grey card gives: band-averaged sensor-plane irradiance.

    A Lambertian card of reflectance rho under irradiance E has radiance rho E / pi; on axis at
    infinity focus the image irradiance is pi L / (4 N^2) (T = 1) -- the scale only sets the exposure.
    """
    g = scene.grid
    e_card = GREY * scene.illumination.values / (4.0 * scene.camera.f_number ** 2)   # W / (m^2 nm) on the grid
    edges = np.arange(g.min_nm, g.max_nm + 0.5 * BAND_NM, BAND_NM)
    fine = np.linspace(g.min_nm, g.max_nm, 8 * (g.n - 1) + 1)
    cum = np.concatenate([[0.0], np.cumsum(np.diff(fine) * 0.5 * (np.interp(fine[1:], g.nm, e_card)
                                                                    + np.interp(fine[:-1], g.nm, e_card)))])
    band = np.diff(np.interp(edges, fine, cum)) / BAND_NM
    irr = np.broadcast_to(band.astype(np.float32), shape + (band.size,)).copy()
    plan = SimpleNamespace(sensor_preset=scene.sensor.preset, spectral=True)
    return SimpleNamespace(plan=plan, shape=shape, irradiance=irr, wavelength_nm=0.5 * (edges[1:] + edges[:-1]),
                           band_width_nm=BAND_NM, samples_per_pixel=1)


@pytest.mark.parametrize("spectrum_toml", ['"D65"', '"A"', '"F2"', '"planck:3200K"', '"planck:5000K"',
                                           '"planck:6500K"', '"daylight:5000K"'])
def test_grey_card_develops_neutral(spectrum_toml):
    scene = _scene(spectrum_toml)
    _, raw, dev = sensor_stage(_grey_card_render(scene), scene)
    assert raw.dn.max() < raw.white_level_dn            # nothing clipped
    rgb = dev.linear[6:-6, 6:-6].reshape(-1, 3).astype(np.float64).mean(axis=0)
    L, a, b = linear_srgb_to_lab(rgb)
    assert abs(a) <= 0.5 and abs(b) <= 0.5, (spectrum_toml, L, a, b)
    assert 30.0 < L < 70.0                               # an 18 % card near mid-grey (SOS gain), not black or clipped


def test_old_blackbody_spelling_is_balanced_as_planck():
    # the case: { blackbody_K = 5000 } was balanced as CIE daylight 5000 K
    with pytest.warns(LensrtDeprecationWarning, match="planck:5000K"):
        scene = _scene("{ blackbody_K = 5000 }")
    ill = isp_illuminant(scene)
    assert ill.kind == "planck" and ill.kelvin == 5000.0           # the object itself, not a label parsed back
    _, _, dev = sensor_stage(_grey_card_render(scene), scene)
    _, a, b = linear_srgb_to_lab(dev.linear[6:-6, 6:-6].reshape(-1, 3).astype(np.float64).mean(axis=0))
    assert abs(a) <= 0.5 and abs(b) <= 0.5, (a, b)


def test_planck_and_daylight_of_one_temperature_need_different_white_balance():
    # the cause of the bug: the two spectra differ enough that balancing one as the other tints a grey
    from lensrt.isp import white_balance_from_illuminant
    from lensrt.sensor import get_preset
    ff = get_preset("fullframe_24mp")
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # the one syntax raises no deprecation
        p = white_balance_from_illuminant(ff, "planck:5000K")
        d = white_balance_from_illuminant(ff, "daylight:5000K")
    assert not np.allclose(p, d, rtol=0.01)
    assert math.isclose(p[1], 1.0) and math.isclose(d[1], 1.0)
