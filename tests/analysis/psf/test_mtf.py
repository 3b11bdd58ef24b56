"""MTF machinery: closed forms, the linear-systems product, S/T directions, binned PSFs, focus."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.psf import otf as M
from lensrt.analysis.wave.propagation import PupilFunction, psf_fft, through_focus_psfs
from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.psf.result import histogram_rays
from lensrt.analysis.wave.pupil_grid import circular_aperture
from lensrt.errors import LensrtError


def test_diffraction_mtf_closed_form_values():
    cut = M.diffraction_cutoff_cpmm(500.0, 4.0)
    assert cut == pytest.approx(500.0)
    v = M.diffraction_mtf([0.0, 0.5 * cut, cut, 1.5 * cut], 500.0, 4.0)
    half = 2 / math.pi * (math.acos(0.5) - 0.5 * math.sqrt(0.75))
    assert np.allclose(v, [1.0, half, 0.0, 0.0])
    assert half == pytest.approx(0.3910, abs=1e-4)
    assert M.airy_psf(0.0, 500.0, 4.0) == pytest.approx(math.pi / (4 * (500e-6 * 4) ** 2))


def test_detector_mtf_zero_at_one_over_aperture():
    f = np.linspace(0, 400, 4001)
    m = M.detector_mtf(f, 0.0, 5.0)  # 5 um aperture: zero at 200 cycles/mm
    assert m[f == 200.0][0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(m[(f > 0) & (f < 200)] > 0) and m[0] == 1.0
    assert M.detector_mtf(0.0, 250.0, 5.0, 4.0) == pytest.approx(0.0, abs=1e-12)  # dy = 4 um
    assert M.detector_mtf(100.0, 0.0, 5.0) == pytest.approx(2 / math.pi)  # sinc(1/2)


def test_olpf_zero_at_one_over_twice_the_separation_and_nyquist():
    assert M.nyquist_cpmm(5.0) == pytest.approx(100.0)
    assert M.olpf_mtf(100.0, 0.0, 5.0) == pytest.approx(0.0, abs=1e-12)  # 1/(2 s) = Nyquist for s = pitch
    assert M.olpf_mtf(50.0, 50.0, 5.0) == pytest.approx(0.5)
    f = np.linspace(0, 99.9, 500)
    assert np.all(M.olpf_mtf(f, 0.0, 5.0) > 0)


def _airy(pitch_um: float = 0.25, n: int = 64) -> tuple[np.ndarray, ImageGrid]:
    mask = circular_aperture(n)
    q = 500e-3 * 4.0 / pitch_um  # lambda N_w / pitch
    psf, grid, _ = psf_fft(PupilFunction(mask, np.zeros((n, n)), 500.0, 4.0, intensity=mask), q)
    return psf, grid


def test_system_mtf_is_the_product_of_its_parts():
    """Convolve lens PSF, 4-spot OLPF and pixel box in space; the MTF is the product of the three."""
    lens, grid = _airy()
    p = grid.pitch_um
    k = 8  # OLPF spots at (+-k, +-k) samples: separation s = 2 k p = 4 um
    olpf = sum(np.roll(np.roll(lens, sy * k, axis=0), sx * k, axis=1) for sx in (-1, 1) for sy in (-1, 1)) / 4
    m = 16  # pixel box of 16 x 16 samples = 4 um
    system = sum(np.roll(np.roll(olpf, i, axis=0), j, axis=1) for i in range(m) for j in range(m)) / m ** 2
    f = np.linspace(0, 240, 49)
    for angle in (0.0, 0.5 * math.pi, 0.4):
        fx, fy = f * math.cos(angle), f * math.sin(angle)
        product = M.system_mtf(M.mtf_along(lens, grid, f, angle), M.olpf_mtf(fx, fy, 2 * k * p),
                               M.detector_mtf(fx, fy, m * p))
        measured = M.mtf_along(system, grid, f, angle)
        # the sampled box's transfer is sin(pi m p nu)/(m sin(pi p nu)), not quite sinc: < 0.3 % here
        assert np.abs(measured - product).max() < 5e-3
    # the zeros are where the parts put them
    assert M.mtf_along(system, grid, [125.0], 0.0)[0] < 5e-3  # OLPF: 1/(2 s)
    assert M.mtf_along(system, grid, [250.0], 0.5 * math.pi)[0] < 5e-3  # detector: 1/dx


def test_olpf_and_detector_mtf_from_their_psfs():
    grid = ImageGrid.centred(64, 0.5)
    four = np.zeros(grid.shape)
    r, c = 32, 32  # centred even grid: pixel (32, 32) is at (+0.25, -0.25) um
    four[[r - 3, r - 3, r + 3, r + 3], [c - 3, c + 3, c - 3, c + 3]] = 1.0  # 3 um separation
    f = np.linspace(0, 400, 81)
    assert np.allclose(M.mtf_along(four, grid, f, 0.0), M.olpf_mtf(f, 0.0, 3.0), atol=1e-12)
    assert M.mtf_along(four, grid, [1 / (2 * 3e-3)], 0.5 * math.pi)[0] < 1e-12


def _gaussian(grid: ImageGrid, centre: tuple[float, float], s_r: float, s_t: float) -> np.ndarray:
    """Elliptical Gaussian elongated along the radial direction of ``centre``."""
    gx, gy = grid.mesh_mm()
    t = math.atan2(centre[1], centre[0])
    u = (gx - centre[0]) * math.cos(t) + (gy - centre[1]) * math.sin(t)
    v = -(gx - centre[0]) * math.sin(t) + (gy - centre[1]) * math.cos(t)
    return np.exp(-0.5 * (u / s_r) ** 2 - 0.5 * (v / s_t) ** 2)


def test_sagittal_and_tangential_directions():
    centre = (3.0, 3.0)
    grid = ImageGrid.centred(96, 0.5, centre)
    s_r, s_t = 6e-3, 2e-3
    psf = _gaussian(grid, centre, s_r, s_t)
    f = np.linspace(0, 150, 31)
    sag, tan = M.sagittal_tangential(psf, grid, f, centre)
    # radial (tangential) blur lowers the tangential MTF: exp(-2 pi^2 sigma^2 nu^2)
    assert np.allclose(tan, np.exp(-2 * math.pi ** 2 * s_r ** 2 * f ** 2), atol=1e-6)
    assert np.allclose(sag, np.exp(-2 * math.pi ** 2 * s_t ** 2 * f ** 2), atol=1e-6)
    assert M.tangential_angle_rad((0.0, 0.0)) == pytest.approx(0.5 * math.pi)  # on axis: y
    assert M.tangential_angle_rad((-2.0, 0.0)) == pytest.approx(math.pi)
    field = M.mtf_vs_field([psf, psf], [grid, grid], [centre, centre], [10.0, 40.0])
    assert field["sagittal"].shape == (2, 2) and field["image_height_mm"][0] == pytest.approx(math.hypot(3, 3))
    assert field["tangential"][0, 1] < field["sagittal"][0, 1]


def test_reference_frequencies_scale_with_the_format():
    assert np.allclose(M.reference_frequencies_cpmm(), [10, 20, 40])
    aps_c = math.hypot(23.6, 15.6)
    assert np.allclose(M.reference_frequencies_cpmm(aps_c), np.array([10, 20, 40]) * 43.2666 / aps_c, rtol=1e-4)
    with pytest.raises(LensrtError):
        M.reference_frequencies_cpmm(0.0)


def test_binned_histogram_mtf_divides_out_the_bins():
    rng = np.random.default_rng(5)
    sigma = 2.5e-3
    x, y = rng.normal(0, sigma, 400_000), rng.normal(0, sigma, 400_000)
    grid = ImageGrid.centred(64, 2.0)
    hist, off = histogram_rays(x, y, None, grid, 16)
    f = np.array([20.0, 50.0, 100.0, 150.0, 200.0])  # bins' own MTF sinc(2 um f): 0.997 ... 0.76
    exact = np.exp(-2 * math.pi ** 2 * sigma ** 2 * f ** 2)
    est = M.mtf_estimate(hist, grid, f, 0.0, binned=True, samples=400_000, seconds=0.1)
    z = (est.value - exact) / est.stderr
    assert np.all(np.abs(z) < 4), z
    raw = M.mtf_along(hist.sum(axis=0), grid, f, 0.0, binned=False)
    assert raw[2] < exact[2] - 10 * est.stderr[2]  # without the correction the bins blur it
    assert est.samples == 400_000 and "jackknife" in est.method


def test_through_focus_mtf_peaks_at_focus():
    n = 48
    mask = circular_aperture(n)
    pup = PupilFunction(mask, np.zeros((n, n)), 550.0, 4.0, intensity=mask)
    grid = ImageGrid.centred(64, 0.5)
    z = np.linspace(-0.03, 0.03, 13)
    shift = 0.004  # a PSF focused 4 um behind the reference plane
    stack = through_focus_psfs(pup.with_defocus(-shift), grid, z)
    tf = M.through_focus_mtf(stack, grid, z, [50.0, 100.0])
    assert tf["sagittal"].shape == (13, 2)
    assert np.allclose(tf["best_focus_mm"]["sagittal"], shift, atol=1.5e-3)
    assert np.allclose(tf["best_focus_mm"]["tangential"], shift, atol=1.5e-3)
    i = int(np.argmin(np.abs(z - shift)))
    assert tf["tangential"][i, 1] == pytest.approx(M.diffraction_mtf(100.0, 550.0, 4.0), abs=0.03)


def test_frequencies_beyond_the_grid_nyquist_are_refused():
    psf, grid = _airy(pitch_um=1.0)
    with pytest.raises(LensrtError, match="Nyquist"):
        M.mtf_along(psf, grid, [600.0], 0.0)
