"""Diffraction PSFs against closed forms: Airy pattern, diffraction MTF, sampling, symmetry, Huygens."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.psf import otf as M
from lensrt.analysis.wave.propagation import (PupilFunction, fft_pitch_um, polychromatic_psf, psf_fft, psf_huygens,
                                         psf_mft, psf_points, sampling_report, through_focus_psfs)
from lensrt.analysis.psf.energy import centroid_mm, encircled_energy
from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.wave.pupil_grid import circular_aperture, iris_aperture, pupil_coordinates, zernike
from lensrt.errors import LensrtError

LAM, NW = 550.0, 4.0
LAM_NW_MM = LAM * 1e-6 * NW


def clear_pupil(n: int = 128, wavelength_nm: float = LAM, opd_waves: np.ndarray | None = None,
                **kw) -> PupilFunction:
    mask = circular_aperture(n)
    w = np.zeros((n, n)) if opd_waves is None else opd_waves
    return PupilFunction.from_waves(mask, w, wavelength_nm, NW, intensity=mask, **kw)


@pytest.fixture(scope="module")
def airy_fft():
    return psf_fft(clear_pupil(128), padding=4)


def test_airy_first_zero_within_one_grid_step(airy_fft):
    psf, grid, rep = airy_fft
    row, col = (int(round(v)) for v in grid.pixel_of(0.0, 0.0))
    assert psf[row, col] == psf.max()
    prof = psf[row, col:]
    # first local minimum of the radial profile along +x
    i = next(k for k in range(1, prof.size - 1) if prof[k] <= prof[k - 1] and prof[k] <= prof[k + 1])
    r0 = M.airy_first_zero_mm(LAM, NW)
    assert r0 == pytest.approx(1.21967 * LAM_NW_MM, rel=1e-5)
    assert abs(grid.x_mm[col + i] - r0) <= grid.pitch_mm
    assert prof[i] < 1e-3 * prof[0]
    # a finer MFT grid places it within one of its (10x finer) steps
    fine = ImageGrid((1, 201), grid.pitch_um / 10, x0_mm=0.0, y0_mm=0.0)
    line = psf_mft(clear_pupil(128), fine)[0]
    j = next(k for k in range(1, 200) if line[k] <= line[k - 1] and line[k] <= line[k + 1])
    assert abs(fine.x_mm[j] - r0) <= fine.pitch_mm


def test_airy_encircled_energy_at_first_zero(airy_fft):
    psf, grid, _ = airy_fft
    r0 = M.airy_first_zero_mm(LAM, NW)
    assert float(M.airy_encircled_energy(r0, LAM, NW)) == pytest.approx(0.8378, abs=1e-4)
    # point samples integrated through their Fourier interpolant (the default for diffraction PSFs)
    ee = encircled_energy(psf, grid, r0, centre_mm=(0.0, 0.0), points=True)
    assert ee == pytest.approx(0.838, rel=0.005)
    assert ee == pytest.approx(0.8378, abs=5e-4)
    # the pixel-fraction sum (meant for histograms) also passes at the dark ring
    assert encircled_energy(psf, grid, r0, centre_mm=(0.0, 0.0)) == pytest.approx(0.838, rel=0.005)
    # whole curve, against Rayleigh's closed form 1 - J0^2 - J1^2
    radii = np.array([0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 20.0]) * LAM_NW_MM
    assert np.allclose(encircled_energy(psf, grid, radii, (0.0, 0.0), points=True),
                       M.airy_encircled_energy(radii, LAM, NW), atol=1e-3)


def test_airy_pattern_values_and_unit_volume(airy_fft):
    psf, grid, rep = airy_fft
    gx, gy = grid.mesh_mm()
    airy = M.airy_psf(np.hypot(gx, gy), LAM, NW)
    assert np.abs(psf - airy).max() < 2e-4 * airy.max()
    # unit volume over the plane: the period holds all but the far wings (about 0.5 %)
    assert 0.99 < rep["energy_in_period"] <= 1.0
    assert psf.sum() * grid.pixel_area_mm2 == pytest.approx(rep["energy_in_period"])


@pytest.mark.parametrize("angle", [0.0, 0.5 * math.pi, 0.3, 2.0])
def test_mtf_of_airy_matches_diffraction_mtf(airy_fft, angle):
    psf, grid, _ = airy_fft
    cutoff = M.diffraction_cutoff_cpmm(LAM, NW)
    assert cutoff == pytest.approx(1.0 / LAM_NW_MM)
    f = np.linspace(0.0, 1.4 * cutoff, 90)  # beyond the cutoff too (grid Nyquist is 2 x cutoff)
    m = M.mtf_along(psf, grid, f, angle)
    assert m[0] == pytest.approx(1.0)
    assert np.abs(m - M.diffraction_mtf(f, LAM, NW)).max() < 0.01


def test_mtf_2d_of_airy_is_round(airy_fft):
    psf, grid, _ = airy_fft
    fx, fy, m2 = M.mtf_2d(psf, grid)
    FX, FY = np.meshgrid(fx, fy)
    assert np.abs(m2 - M.diffraction_mtf(np.hypot(FX, FY), LAM, NW)).max() < 0.01


@pytest.mark.parametrize("padding", [2, 3, 6])
def test_fft_pitch_formula_and_placement(padding):
    pup = clear_pupil(64)
    psf, grid, rep = psf_fft(pup, padding)
    # lambda N_w / Q, and the same as lambda R / (Q D) for an exit pupil D = 12.5 mm at R = 50 mm
    assert rep["pitch_um"] == pytest.approx(LAM * 1e-3 * NW / padding)
    assert fft_pitch_um(LAM, 50.0 / 12.5, padding) == pytest.approx(LAM * 1e-3 * 50.0 / (padding * 12.5))
    assert grid.pitch_um == rep["pitch_um"] and grid.shape == (64 * padding,) * 2
    assert rep["field_of_view_um"] == pytest.approx(64 * LAM * 1e-3 * NW)
    assert rep["image_sampling_ok"]
    # the samples sit where the grid says: the exact Debye integral there gives the same values
    assert np.allclose(psf, psf_mft(pup, grid), rtol=1e-9, atol=1e-9 * psf.max())
    gx, gy = grid.mesh_mm()
    near = np.hypot(gx, gy) < 6 * LAM_NW_MM
    airy = M.airy_psf(np.hypot(gx, gy), LAM, NW)
    assert np.abs(psf - airy)[near].max() < 3e-3 * airy.max()


def test_undersampling_is_refused_and_reported():
    with pytest.raises(LensrtError, match="Nyquist"):
        psf_fft(clear_pupil(32), padding=1.5)
    px, _ = pupil_coordinates(32)
    steep = clear_pupil(32, opd_waves=20.0 * px ** 2)
    rep = sampling_report(steep, padding=4)
    assert rep["max_phase_step_waves"] > 0.5 and not rep["pupil_sampling_ok"]
    assert sampling_report(clear_pupil(32), padding=4)["pupil_sampling_ok"]


def test_tilt_moves_the_psf_toward_plus_x_and_plus_y():
    """OPD sign: W = a lambda px (longer path at +px) puts the PSF at x = a lambda / NA = 2 a lambda N_w."""
    px, py = pupil_coordinates(64)
    for a, b in [(2.0, 0.0), (0.0, -1.5)]:
        pup = clear_pupil(64, opd_waves=a * px + b * py)
        line = ImageGrid.centred((201, 201), 0.1)
        psf = psf_mft(pup, line)
        r, c = np.unravel_index(np.argmax(psf), psf.shape)
        x, y = line.position_of(r, c)
        assert x == pytest.approx(2 * a * LAM_NW_MM, abs=line.pitch_mm)
        assert y == pytest.approx(2 * b * LAM_NW_MM, abs=line.pitch_mm)


def test_polychromatic_sum_on_common_grid_conserves_energy():
    wls, wts = [450.0, 550.0, 650.0], [1.0, 2.0, 1.0]
    pupils = [clear_pupil(96, wl) for wl in wls]
    grid = ImageGrid.centred(161, 0.25)
    poly = polychromatic_psf(pupils, wts, grid)
    w = np.array(wts) / sum(wts)
    radii = np.array([1.0, 2.0, 3.0, 6.0, 12.0]) * 1e-3
    expected = sum(wi * M.airy_encircled_energy(radii, wl, NW) for wl, wi in zip(wls, w))
    assert np.allclose(encircled_energy(poly, grid, radii, (0.0, 0.0), points=True), expected, atol=2e-3)
    # total on the grid lies between the weighted Airy energies of the inscribed and circumscribed circles
    half = 0.5 * grid.shape[0] * grid.pitch_mm
    lo = sum(wi * M.airy_encircled_energy(half, wl, NW) for wl, wi in zip(wls, w))
    hi = sum(wi * M.airy_encircled_energy(half * math.sqrt(2), wl, NW) for wl, wi in zip(wls, w))
    assert lo - 2e-3 < poly.sum() * grid.pixel_area_mm2 < hi + 2e-3
    # and equals the weighted sum of the monochromatic PSFs resampled onto that grid
    each = [psf_mft(p, grid) for p in pupils]
    assert np.allclose(poly, sum(wi * e for wi, e in zip(w, each)))
    # its MTF is the weighted diffraction MTF (on a window wide enough that the cut wings,
    # about 0.5 % of the light, do not lift the low frequencies)
    wide = ImageGrid.centred(401, 0.4)
    f = np.linspace(0, 550, 56)
    assert np.abs(M.mtf_along(polychromatic_psf(pupils, wts, wide), wide, f, 0.0)
                  - M.polychromatic_diffraction_mtf(f, wls, wts, NW)).max() < 0.015


def test_seven_blade_iris_gives_fourteen_spikes():
    n = 96
    mask = iris_aperture(n, 7, supersample=8)
    pup = PupilFunction(mask, np.zeros((n, n)), LAM, NW, intensity=mask)
    phi = np.linspace(0.0, 2 * math.pi, 560, endpoint=False)  # 40 samples per pi/7
    prof = sum(psf_points(pup, r * np.cos(phi), r * np.sin(phi)) for r in np.linspace(8, 14, 5) * LAM_NW_MM)
    # invariant under rotation by 2 pi / 7 (and pi / 7: the PSF of a real pupil is centrosymmetric)
    assert np.abs(np.roll(prof, -80) - prof).max() < 0.1 * prof.mean()
    assert np.abs(np.roll(prof, -40) - prof).max() < 0.1 * prof.mean()
    # 14-fold spikes in the wings, along the blade normals k pi / 7 (a vertex at 0 rad)
    c = np.fft.rfft(prof) / prof.size
    amp = np.abs(c)
    assert amp[14] > 0.3 * amp[0]
    assert abs(np.angle(c[14])) < 0.05  # maxima at phi = k pi / 7
    others = np.delete(amp[1:60], [13, 27, 41, 55])
    assert others.max() < 0.05 * amp[14]
    # a circular pupil has no azimuthal structure at all
    round_pupil = clear_pupil(96)
    ring = sum(psf_points(round_pupil, r * np.cos(phi), r * np.sin(phi)) for r in np.linspace(8, 14, 5) * LAM_NW_MM)
    assert np.ptp(ring) < 0.05 * ring.mean()
    assert np.abs(np.fft.rfft(ring)[1:60]).max() / ring.size < 0.05 * amp[14]


def _aberrated(n: int = 40, chief=(0.0, 0.0, 1.0)) -> PupilFunction:
    px, py = pupil_coordinates(n)
    rho, th = np.hypot(px, py), np.arctan2(py, px)
    w = 0.25 * zernike(7, rho, th) + 0.2 * zernike(5, rho, th) + 0.1 * zernike(11, rho, th)
    return clear_pupil(n, opd_waves=w, chief_direction=chief)


@pytest.mark.parametrize("chief", [(0.0, 0.0, 1.0), (0.2, -0.25, math.sqrt(1 - 0.2 ** 2 - 0.25 ** 2))])
def test_huygens_agrees_with_fourier_for_a_small_aberrated_case(chief):
    pup = _aberrated(chief=chief)
    grid = ImageGrid.centred(31, 0.5, (1.0, -2.0))
    mft = psf_mft(pup, grid, reference_mm=(1.0, -2.0))
    huy = psf_huygens(pup, grid, distance_mm=50.0, reference_mm=(1.0, -2.0))
    assert np.abs(mft - huy).max() < 1e-3 * mft.max()
    # through focus: Huygens on a moved plane = Fourier with the exact defocus OPD
    dz = 0.01
    moved = psf_huygens(pup, grid, distance_mm=50.0, reference_mm=(1.0, -2.0), dz_mm=dz)
    stack = through_focus_psfs(pup, grid, [0.0, dz], reference_mm=(1.0, -2.0))
    assert np.allclose(stack[0], mft)
    assert np.abs(stack[1] - moved).max() < 3e-3 * stack[1].max()
    assert stack[1].max() < 0.95 * mft.max()  # it really is defocused


def test_centroid_is_the_mean_wavefront_slope():
    """Diffraction PSF centroid = <|A|^2 dW/dp> / <|A|^2> / NA (ray and wave pictures agree; checks the sign).

    A Gaussian-apodised pupil keeps the PSF's wings weak, so the centroid of a
    finite window converges (a hard-edged pupil's 1/r^3 wings make it creep).
    """
    n = 64
    px, py = pupil_coordinates(n)

    def opd_waves(x, y):
        rho, th = np.hypot(x, y), np.arctan2(y, x)
        return 0.25 * zernike(7, rho, th) + 0.2 * zernike(5, rho, th) + 0.1 * zernike(11, rho, th) + 0.3 * zernike(8, rho, th)

    mask = circular_aperture(n)
    amp = mask * np.exp(-np.hypot(px, py) ** 2 / 0.45 ** 2)
    pup = PupilFunction.from_waves(amp, opd_waves(px, py), LAM, NW)
    psf, grid, _ = psf_fft(pup, 4)
    # the expectation from the analytic wavefront on a fine pupil grid
    fx, fy = pupil_coordinates(512)
    fine_w = np.exp(-2 * np.hypot(fx, fy) ** 2 / 0.45 ** 2) * (np.hypot(fx, fy) <= 1)
    h = 1e-6
    gx = (opd_waves(fx + h, fy) - opd_waves(fx - h, fy)) / (2 * h)
    gy = (opd_waves(fx, fy + h) - opd_waves(fx, fy - h)) / (2 * h)
    lam_mm = LAM * 1e-6
    expect = [float(np.sum(fine_w * g) / fine_w.sum()) * lam_mm / pup.na for g in (gx, gy)]
    cx, cy = centroid_mm(psf, grid)
    assert abs(expect[0]) > 0.3 * LAM_NW_MM and abs(expect[1]) > 0.3 * LAM_NW_MM
    assert cx == pytest.approx(expect[0], rel=0.02)
    assert cy == pytest.approx(expect[1], rel=0.02)


def test_bad_pupils_are_refused():
    with pytest.raises(LensrtError):
        PupilFunction(np.zeros((8, 8)), np.zeros((8, 8)), LAM, NW)
    with pytest.raises(LensrtError):
        PupilFunction(np.ones((8, 8)), np.zeros((8, 9)), LAM, NW)
    with pytest.raises(LensrtError):
        PupilFunction(np.ones((8, 8)), np.full((8, 8), np.nan), LAM, NW)


def test_clear_pupil_otf_is_the_closed_form_with_a_hard_edge():
    """The pupil autocorrelation of a clear circle against 2/pi (acos x - x sqrt(1 - x^2)): within 0.001 with
    the hard, supersampled edge; the soft (anti-aliased) edge alone apodises and lifts the MTF (+0.004)."""
    from lensrt.analysis.psf.diffraction import pupil_mtf_function
    from lensrt.analysis.wave.pupil_grid import aperture_fine_mask
    n = 128
    mask = circular_aperture(n)
    fine = aperture_fine_mask(n, lambda x, y: np.hypot(x, y) <= 1.0, 2)   # 256 sub-cells a side, as traced pupils
    hard = PupilFunction.from_waves(mask, np.zeros((n, n)), LAM, NW, intensity=mask, fine_mask=fine)
    soft = clear_pupil(n)
    f = np.linspace(0.0, 1.0, 41)[:-1] / LAM_NW_MM
    want = M.diffraction_mtf(f, LAM, NW)
    for angle in (0.0, 0.7, 0.5 * math.pi):
        got = pupil_mtf_function([hard], [1.0], 4, (0.0, 0.0))(f, angle)
        assert np.abs(got - want).max() < 1e-3
    lifted = pupil_mtf_function([soft], [1.0], 4, (0.0, 0.0))(f, 0.0) - want
    assert lifted[4] > 2e-3    # what the hard edge removes: the soft edge's apodisation at 0.1 of the cutoff


@pytest.mark.parametrize("method", ["fft", pytest.param("huygens", marks=pytest.mark.slow)])
def test_diffraction_limited_lens_mtf_never_exceeds_the_limit(method):
    """A diffraction-limited f/40 singlet on axis at best focus (lensrt mtf --method diffraction): the lens MTF
    stays within 0.002 of the diffraction limit from above, by pupil autocorrelation (FFT/MFT) and by the
    Huygens window (normalised by the power that entered the pupil, not by the window's sum)."""
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.diffraction import diffraction_psf_at
    from lensrt.analysis.psf.mtf_curves import mtf_curves
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.loading import complete_lens
    from lensrt.prescription.formats.native import loads_native
    lens = complete_lens(loads_native(F40_SINGLET))
    freqs = tuple(float(v) for v in np.linspace(0.0, 200.0, 52))   # lensrt mtf's default axis (2 x Nyquist)
    setup = make_setup(lens, focus="best", method="diffraction", device="cpu", mtf_curve_cpmm=freqs,
                       max_pitch_um=0.45e3 / 200.0)
    axis = FieldSpec(0.0, 0.0, "axis")
    if method == "huygens":
        setup = setup.with_(pixels=48)
    r = diffraction_psf_at(setup, axis, "cpu", method=method)
    c = mtf_curves(r, lens)
    lim = np.asarray(c["diffraction_limit"])
    for key in ("lens_sagittal", "lens_tangential"):
        v = np.asarray(c[key], dtype=np.float64)
        ok = np.isfinite(v)
        assert ok.sum() > 10
        assert np.max(v[ok] - lim[ok]) <= 2e-3, (method, key, np.max(v[ok] - lim[ok]))


F40_SINGLET = """
[lens]
name = "Plano-convex f/40 (diffraction limited on axis)"
[system]
object_distance_mm = inf
[aperture]
type = "epd"
value = 2.5
[fields]
type = "angle"
y = [0.0, 0.5]
[wavelengths]
nm = [587.6]
primary_nm = 587.6
[[surface]]
radius_mm = 51.68
thickness_mm = 3.0
material = { index = 1.5168 }
stop = true
[[surface]]
radius_mm = inf
thickness_mm = 98.0
material = "air"
"""


def test_pupil_mtf_with_spline_coefficients_once_equals_map_coordinates_prefiltering():
    """pupil_mtf_function filters each OTF once; the values are those of map_coordinates filtering per call
    (an aberrated two-wavelength pupil, several directions), to the bit."""
    from scipy.ndimage import map_coordinates
    from lensrt.analysis.psf.diffraction import pupil_mtf_function, pupil_otf
    from lensrt.analysis.wave.pupil_grid import pupil_coordinates
    n = 64
    mask = circular_aperture(n)
    gx, gy = pupil_coordinates(n)
    pupils = [PupilFunction.from_waves(mask, 0.4 * (gx ** 2 + gy ** 2) + 0.2 * gx ** 3, lam, NW)
              for lam in (LAM, 1.2 * LAM)]
    weights = [0.7, 0.3]
    fn = pupil_mtf_function(pupils, weights, 4, (0.0, 0.0))
    f = np.linspace(0.0, 0.9, 30) / LAM_NW_MM
    for angle in (0.0, 0.4, 2.0):
        want = np.zeros(f.size, dtype=np.complex128)
        for p, w in zip(pupils, np.asarray(weights) / np.sum(weights)):
            c, cell = pupil_otf(p)
            m = c.shape[0] // 2
            coords = np.vstack([f * math.sin(angle) / cell + m, f * math.cos(angle) / cell + m])
            want += w * (map_coordinates(c.real, coords, order=3, mode="constant")
                         + 1j * map_coordinates(c.imag, coords, order=3, mode="constant"))
        got = fn(f, angle)
        assert np.array_equal(got, np.clip(np.abs(want), 0.0, None))
        assert got[0] == pytest.approx(1.0) and got[-1] < got[0]
