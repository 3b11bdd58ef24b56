"""Pinhole preview: absolute luminance of a uniform scene, and where things land in the image."""
from __future__ import annotations

import numpy as np
import pytest

import lensrt.colour as sp
from lensrt.render.preview import preview_pinhole
from lensrt.render.scene.load import loads_scene

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

HEAD = """
[scene]
units = "m"
[sensor]
pixels = [60, 40]
"""


def test_uniform_background_gives_its_xyz(device):
    s = loads_scene(HEAD + '[background]\nspectrum = "FL2"\nluminance_cd_m2 = 250\n')
    est = preview_pinhole(s, 60, samples_per_pixel=4, device=device)
    xyz_ref = sp.spectral_to_xyz(s.background.values, s.grid)
    assert xyz_ref[1] == pytest.approx(250.0, rel=1e-9)
    mean = est.value.reshape(-1, 3).mean(axis=0)
    # a jittered comb of 16 wavelengths per ray integrates the peaky FL2 spectrum without bias
    se = est.value.reshape(-1, 3).std(axis=0, ddof=1) / np.sqrt(60 * 40)
    assert np.all(np.abs(mean - xyz_ref) < 4 * se + 1e-6 * xyz_ref), (mean, xyz_ref, se)
    assert est.samples == 60 * 40 * 4


def test_pinhole_projection_places_an_emitter(device):
    # an emissive 0.1 m square at (0.4, -0.2, -3) m on black: image centre at f X / |Z|, upright
    s = loads_scene(HEAD + """
[[plane]]
center = [0.4, -0.2, -3.0]
size = [0.1, 0.1]
emission = { spectrum = "D65", luminance_cd_m2 = 100 }
""")
    w = 120
    est = preview_pinhole(s, w, focal_length_mm=50.0, samples_per_pixel=4, device=device)
    y = est.value[..., 1]
    h = y.shape[0]
    rows, cols = np.nonzero(y > 0)
    wts = y[rows, cols]
    x_mm = ((np.sum(cols * wts) / wts.sum() + 0.5) / w - 0.5) * 36.0
    y_mm = (0.5 - (np.sum(rows * wts) / wts.sum() + 0.5) / h) * 24.0
    assert x_mm == pytest.approx(50.0 * 0.4 / 3.0, abs=0.3)     # +x right in the upright image
    assert y_mm == pytest.approx(50.0 * -0.2 / 3.0, abs=0.3)    # +y up
    # inside the square's image the luminance is the emitter's (a pinhole has no falloff of L)
    assert np.max(y) == pytest.approx(100.0, rel=0.02)
