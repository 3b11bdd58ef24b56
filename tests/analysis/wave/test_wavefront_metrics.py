"""Wavefront outputs designers read first: RMS/PV, Strehl, Zernikes -- against closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.wave.metrics import (fit_zernike_fringe, fringe_to_nm, fringe_zernike, strehl_ratio,
                                          wavefront_metrics)
from lensrt.analysis.wave.pupil_grid import fit_zernike, noll_to_nm, zernike
from lensrt.analysis.wave.wavefront import RayWavefront, ReferenceSphere

LAM_NM = 550.0


def synthetic_wavefront(opd_waves, m: int = 161, na: float = 0.05) -> RayWavefront:
    """A uniformly filled circular pupil (rays on an m x m grid, |p| <= 1) with OPD ``opd_waves(px, py)``."""
    u = np.linspace(-1.0, 1.0, m)
    px, py = (a.ravel() for a in np.meshgrid(u, u))
    valid = np.hypot(px, py) <= 1.0
    scale = 1.0 / 1.02     # the traced grids' 2 % margin: the pupil edge at |p| = 1 / 1.02
    opd_mm = np.where(valid, opd_waves(px, py) * LAM_NM * 1e-6, 0.0)
    sphere = ReferenceSphere((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), 100.0, (0.0, 0.0, 1.0))
    return RayWavefront(LAM_NM, px * scale, py * scale, valid, opd_mm, np.ones(px.size), na * 1.02, na, sphere,
                        int(m * m), 0.01, 1e-4, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("w020", [0.1, 0.25, 0.4])
def test_pure_defocus_strehl_and_rms(w020):
    """W = W020 rho^2: Strehl sinc^2(pi W020 / lambda) (on axis, uniform amplitude), RMS W020 / (2 sqrt 3)."""
    m = wavefront_metrics(synthetic_wavefront(lambda x, y: w020 * (x * x + y * y)))
    x = math.pi * w020
    assert m.strehl == pytest.approx((math.sin(x) / x) ** 2, abs=0.005)
    assert m.rms_waves == pytest.approx(w020 / (2.0 * math.sqrt(3.0)), rel=0.02)
    assert m.pv_waves == pytest.approx(w020, rel=0.02)
    assert m.strehl_marechal == pytest.approx(math.exp(-(2 * math.pi * m.rms_waves_no_tilt) ** 2))
    # Noll Z4 = sqrt(3) (2 rho^2 - 1): W020 rho^2 = W020 / 2 + W020 / (2 sqrt 3) Z4
    assert m.zernike_noll_waves[3] == pytest.approx(w020 / (2 * math.sqrt(3)), rel=1e-6)
    assert m.zernike_fringe_waves[3] == pytest.approx(w020 / 2, rel=1e-6)   # Fringe Z4 = 2 rho^2 - 1


def test_tilt_changes_rms_but_not_strehl_and_references_remove_it():
    def tilted(x, y):
        return 0.3 * x + 0.1 * (x * x + y * y)
    chief = wavefront_metrics(synthetic_wavefront(tilted))
    assert chief.rms_waves > chief.rms_waves_no_tilt
    assert chief.rms_waves_no_tilt == pytest.approx(0.1 / (2 * math.sqrt(3)), rel=0.02)
    assert chief.strehl == pytest.approx((math.sin(0.1 * math.pi) / (0.1 * math.pi)) ** 2, abs=0.005)
    for ref in ("centroid", "best_fit"):
        m = wavefront_metrics(synthetic_wavefront(tilted), reference=ref)
        assert abs(m.zernike_noll_waves[1]) < 2e-3      # the tilt is gone
    best = wavefront_metrics(synthetic_wavefront(tilted), reference="best_fit")
    assert best.rms_waves < 1e-4                          # tilt and defocus are all there was (gridding: 7e-6)


def test_zernike_fits_recover_their_coefficients():
    rng = np.random.default_rng(4)
    rho = np.sqrt(rng.uniform(0, 1, 4000))
    th = rng.uniform(-math.pi, math.pi, 4000)
    x, y = rho * np.cos(th), rho * np.sin(th)
    c = rng.normal(size=28)
    w = sum(c[j - 1] * zernike(j, rho, th) for j in range(1, 29))
    assert np.abs(fit_zernike(x, y, w, 28) - c).max() < 1e-10
    wf = sum(c[j - 1] * fringe_zernike(j, rho, th) for j in range(1, 29))
    assert np.abs(fit_zernike_fringe(x, y, wf, 28) - c).max() < 1e-10


def test_fringe_and_noll_orderings():
    assert [fringe_to_nm(j) for j in range(1, 17)] == [
        (0, 0), (1, 1), (1, -1), (2, 0), (2, 2), (2, -2), (3, 1), (3, -1), (4, 0), (3, 3), (3, -3), (4, 2),
        (4, -2), (5, 1), (5, -1), (6, 0)]
    assert [noll_to_nm(j) for j in (1, 2, 3, 4, 11)] == [(0, 0), (1, 1), (1, -1), (2, 0), (4, 0)]


def test_strehl_of_a_perfect_pupil_is_one():
    from lensrt.analysis.wave.propagation import PupilFunction
    from lensrt.analysis.wave.pupil_grid import circular_aperture
    mask = circular_aperture(64)
    p = PupilFunction.from_waves(mask, np.zeros((64, 64)), LAM_NM, 8.0, intensity=mask)
    assert strehl_ratio(p) == pytest.approx(1.0, abs=1e-12)


def test_real_lens_defocus_rms_against_its_exact_wavefront():
    """The stigmatic plano-hyperbolic f/5 lens 0.05 mm behind its focus: the OPD is exactly dz (1 - cos U'),
    PV W = dz (1 - cos U'_max) with sin U'_max of the marginal ray; RMS W / (2 sqrt 3) to O(NA^2)."""
    from pathlib import Path
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.analysis.psf.spectrum import line_spectrum
    from lensrt.analysis.psf.wavefront_error import wavefront_error
    from lensrt.loading import load_lens
    lens = load_lens(Path(__file__).resolve().parents[2] / "data" / "plano_hyperbolic_f5.toml")
    s = lens.surfaces[1]
    h = 10.0
    z = float(s.sag(h))
    sin_u = h / math.hypot(h, 100.0 - z)          # F lies 100 mm behind the hyperboloid's vertex
    w = 0.05 * (1.0 - math.sqrt(1.0 - sin_u ** 2)) / (587.6e-6)
    setup = make_setup(lens, line_spectrum([587.6]), "paraxial+0.05", "cpu", method="diffraction")
    m = wavefront_error(setup, FieldSpec(0.0, 0.0, "axis"), device="cpu")[0]
    assert m.rms_waves == pytest.approx(w / (2 * math.sqrt(3)), rel=0.02)
    assert m.pv_waves == pytest.approx(w, rel=0.02)
    assert m.zernike_noll_residual_rms_waves < 1e-3 and len(m.zernike_noll_waves) == 37
    d = m.to_dict()
    assert {"rms_waves", "strehl", "zernike_noll_waves", "zernike_fringe_waves"} <= set(d)
