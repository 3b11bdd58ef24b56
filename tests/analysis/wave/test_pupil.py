"""Pupil grids, aperture shapes, Zernike fits, and the scattered-ray -> pupil-grid glue."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.wave.propagation import PupilFunction, psf_fft
from lensrt.analysis.wave.pupil_grid import (aperture_from_iris, circular_aperture, defocus_opd_mm, enclosing_na, fit_zernike,
                                   iris_aperture, noll_to_nm, pupil_coordinates,
                                   pupil_coordinates_from_directions, pupil_from_rays, vignetted_aperture,
                                   zernike, zernike_surface)
from lensrt.errors import LensrtError
from lensrt.prescription.model import Iris


def cell_area(n: int) -> float:
    return (2.0 / n) ** 2


def test_pupil_coordinates_orientation_and_spacing():
    px, py = pupil_coordinates(8)
    assert px[0, 0] == pytest.approx(-7 / 8) and px[0, -1] == pytest.approx(7 / 8)
    assert py[0, 0] == pytest.approx(7 / 8) and py[-1, 0] == pytest.approx(-7 / 8)  # row 0 is +py
    assert np.allclose(np.diff(px[0]), 0.25)
    assert px.sum() == pytest.approx(0.0) and py.sum() == pytest.approx(0.0)


def test_aperture_areas_match_closed_forms():
    n = 128
    assert circular_aperture(n).sum() * cell_area(n) == pytest.approx(math.pi, rel=2e-4)
    assert circular_aperture(n, 0.3).sum() * cell_area(n) == pytest.approx(math.pi * (1 - 0.09), rel=5e-4)
    for blades in (5, 7, 9):  # regular polygon inscribed in the unit circle
        area = 0.5 * blades * math.sin(2 * math.pi / blades)
        assert iris_aperture(n, blades).sum() * cell_area(n) == pytest.approx(area, rel=5e-4)
    assert iris_aperture(n, 7, roundness=1.0).sum() * cell_area(n) == pytest.approx(math.pi, rel=2e-4)
    # cat's eye: the unit circle cut by a unit circle centred at (0, 0.5)
    d = 0.5
    lens = 2 * math.acos(d / 2) - 0.5 * d * math.sqrt(4 - d * d)
    assert vignetted_aperture(n, [(0.0, d, 1.0)]).sum() * cell_area(n) == pytest.approx(lens, rel=5e-4)


def test_iris_orientation_follows_the_lens_model():
    n = 200
    rot = 0.3
    mask = aperture_from_iris(n, Iris(blades=6, rotation_rad=rot), supersample=1)
    px, py = pupil_coordinates(n)

    def at(x: float, y: float) -> float:
        i = np.argmin((px - x) ** 2 + (py - y) ** 2)
        return mask.ravel()[i]
    r = 0.97  # a vertex at rot is clear out to the circle; the middle of a blade is not
    assert at(r * math.cos(rot), r * math.sin(rot)) == 1.0
    mid = rot + math.pi / 6
    assert at(r * math.cos(mid), r * math.sin(mid)) == 0.0
    assert at(0.85 * math.cos(mid), 0.85 * math.sin(mid)) == 1.0  # cos(30 deg) = 0.866


def test_noll_indices_and_orthonormality():
    table = [(0, 0), (1, 1), (1, -1), (2, 0), (2, -2), (2, 2), (3, -1), (3, 1), (3, -3), (3, 3), (4, 0)]
    assert [noll_to_nm(j) for j in range(1, 12)] == table
    px, py = pupil_coordinates(400)
    rho, th = np.hypot(px, py), np.arctan2(py, px)
    inside = rho <= 1
    zs = np.array([zernike(j, rho, th)[inside] for j in range(1, 16)])
    gram = zs @ zs.T / inside.sum()
    assert np.allclose(gram, np.eye(15), atol=0.02)


def test_zernike_fit_recovers_coefficients_from_scattered_points():
    rng = np.random.default_rng(3)
    r, t = np.sqrt(rng.random(3000)), 2 * math.pi * rng.random(3000)
    x, y = r * np.cos(t), r * np.sin(t)
    true = np.zeros(21)
    true[[3, 6, 7, 10, 15]] = [0.5, -0.2, 0.1, 0.3, 0.05]
    c = fit_zernike(x, y, zernike_surface(true, x, y), 21)
    assert np.allclose(c, true, atol=1e-10)


def test_directions_to_pupil_coordinates_sign_and_scale():
    # a converging beam from an exit pupil 50 mm in front of the image point (0, 0, 0)
    na = 0.125
    h = 50.0 * math.tan(math.asin(na))
    pupil_pts = np.array([[h, 0.0, -50.0], [0.0, -h, -50.0], [0.0, 0.0, -50.0]])
    d = -pupil_pts / np.linalg.norm(pupil_pts, axis=1, keepdims=True)
    px, py = pupil_coordinates_from_directions(d, (0.0, 0.0, 1.0), na)
    assert px[0] == pytest.approx(1.0) and py[0] == pytest.approx(0.0)  # +x side of the pupil -> px = +1
    assert py[1] == pytest.approx(-1.0) and px[2] == 0.0
    # a pupil larger than the nominal NA is caught, and enclosing_na sizes the grid to hold it
    with pytest.raises(LensrtError, match="outside the pupil grid"):
        pupil_from_rays(*pupil_coordinates_from_directions(d, (0, 0, 1), 0.9 * na), np.zeros(3), np.ones(3, bool), 8)
    na2 = enclosing_na(d, (0.0, 0.0, 1.0), margin=0.0)
    assert na2 == pytest.approx(na)


def test_exact_defocus_matches_paraxial_for_small_na():
    px, py = pupil_coordinates(16)
    w = defocus_opd_mm(px, py, 0.01, 0.2)
    assert np.allclose(w, -0.2 * 0.01 ** 2 * (px ** 2 + py ** 2) / 2, rtol=1e-3, atol=1e-12)


def _scattered(rng: np.random.Generator, m: int):
    x, y = rng.uniform(-1.1, 1.1, m), rng.uniform(-1.1, 1.1, m)
    valid = (np.hypot(x, y) <= 1) & (np.hypot(x, y - 0.5) <= 1)  # cat's eye

    def w_mm(a, b):  # 2 waves of coma-like and 1.5 waves spherical at 550 nm, in mm
        rho2 = a * a + b * b
        return 550e-6 * (2.0 * (3 * rho2 - 2) * b + 1.5 * (6 * rho2 * rho2 - 6 * rho2 + 1))
    return x, y, valid, w_mm


@pytest.mark.parametrize("method,tol_waves", [("linear", 0.02), ("zernike", 1e-6)])
def test_pupil_from_scattered_rays(method, tol_waves):
    rng = np.random.default_rng(7)
    x, y, valid, w_mm = _scattered(rng, 40_000)
    n = 64
    amp, opd, info = pupil_from_rays(x, y, w_mm(x, y), valid, n, method=method)
    assert info["valid_rays"] == int(valid.sum())
    ref_mask = vignetted_aperture(n, [(0.0, 0.5, 1.0)], supersample=8)
    # the outline: the cells that disagree are edge cells only, and the area is right
    assert np.mean(amp != (ref_mask >= 0.5)) < 0.03
    assert amp.sum() == pytest.approx(ref_mask.sum(), rel=0.02)
    px, py = pupil_coordinates(n)
    inner = (ref_mask == 1.0) & (amp == 1.0)
    assert np.abs(opd - w_mm(px, py))[inner].max() < tol_waves * 550e-6
    assert np.all(opd[amp == 0] == 0)


def test_gridded_rays_give_the_same_psf_as_the_pupil_they_sample():
    rng = np.random.default_rng(11)
    x, y, valid, w_mm = _scattered(rng, 40_000)
    n = 64
    amp, opd, _ = pupil_from_rays(x, y, w_mm(x, y), valid, n, aperture=vignetted_aperture(n, [(0.0, 0.5, 1.0)]))
    px, py = pupil_coordinates(n)
    mask = vignetted_aperture(n, [(0.0, 0.5, 1.0)])
    truth = PupilFunction(mask, np.where(mask > 0, w_mm(px, py), 0.0), 550.0, 4.0, intensity=mask)
    got = PupilFunction(amp, opd, 550.0, 4.0, intensity=mask)
    a, _, _ = psf_fft(truth, 3)
    b, _, _ = psf_fft(got, 3)
    assert np.abs(a - b).max() < 0.01 * a.max()


def test_bad_ray_data_are_refused():
    with pytest.raises(LensrtError, match="valid rays"):
        pupil_from_rays(np.zeros(5), np.zeros(5), np.zeros(5), np.zeros(5, bool), 16)
    with pytest.raises(LensrtError, match="same length"):
        pupil_from_rays(np.zeros(5), np.zeros(4), np.zeros(5), np.ones(5, bool), 16)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1, 1, 100), rng.uniform(-1, 1, 100)
    with pytest.raises(LensrtError, match="method"):
        pupil_from_rays(x, y, np.zeros(100), np.ones(100, bool), 16, method="spline")
