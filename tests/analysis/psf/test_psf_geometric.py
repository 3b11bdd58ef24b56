"""Geometric PSF statistics on numpy-sampled rays with closed forms (pure defocus = uniform disc / iris polygon)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lensrt.analysis.wave.propagation import PupilFunction, psf_fft
from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.psf.result import (MOMENT_KEYS, PsfResult, diffraction_result, geometric_psf, histogram_rays,
                                 ray_moment_sums)
from lensrt.analysis.wave.pupil_grid import circular_aperture
from lensrt.errors import LensrtError
from lensrt.io.table import dumps_json

R = 0.05  # blur-disc radius (mm)
CENTRE = (3.0, -2.0)  # image point (mm): off axis, as a real field point


def disc_rays(rng: np.random.Generator, n: int, radius: float = R, centre=CENTRE):
    r, t = radius * np.sqrt(rng.random(n)), 2 * math.pi * rng.random(n)
    return centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)


def polygon_rays(rng: np.random.Generator, n: int, blades: int, radius: float = R, centre=CENTRE):
    """Uniform points in a regular polygon inscribed in a circle (a vertex on +x), by rejection."""
    out_x, out_y = [], []
    while sum(len(v) for v in out_x) < n:
        x, y = rng.uniform(-1, 1, 2 * n), rng.uniform(-1, 1, 2 * n)
        sector = 2 * math.pi / blades
        phi = np.mod(np.arctan2(y, x), sector)
        inside = np.hypot(x, y) <= math.cos(sector / 2) / np.cos(phi - sector / 2)
        out_x.append(x[inside])
        out_y.append(y[inside])
    x, y = np.concatenate(out_x)[:n], np.concatenate(out_y)[:n]
    return centre[0] + radius * x, centre[1] + radius * y


def run(x, y, grid: ImageGrid, batches: int = 32, moments: bool = True, seed: int = 0) -> PsfResult:
    hist, off = histogram_rays(x, y, None, grid, batches)
    sums = ray_moment_sums(x, y, None, CENTRE, batches) if moments else None
    return geometric_psf(hist, grid, moment_sums=sums, off_grid=off, reference_mm=CENTRE, wavelengths_nm=[587.6],
                         field_xy=(0.0, 0.2), samples=x.size, seconds=0.5, seed=seed)


@pytest.fixture(scope="module")
def disc() -> PsfResult:
    x, y = disc_rays(np.random.default_rng(1), 400_000)
    return run(x, y, ImageGrid.centred(128, 1.0, CENTRE))


def test_defocus_disc_rms_radius_matches_closed_form_within_its_standard_error(disc):
    rms = disc.estimates["rms_radius_mm"]
    assert abs(rms.value - R / math.sqrt(2)) < 3 * rms.stderr
    assert 0 < rms.stderr < 1e-3 * R
    assert rms.samples == 400_000 and rms.seconds == 0.5 and "jackknife" in rms.method
    for key in ("rms_tangential_mm", "rms_sagittal_mm"):  # R/2 in every direction
        e = disc.estimates[key]
        assert abs(e.value - R / 2) < 3 * e.stderr
    for key, c in (("centroid_x_mm", CENTRE[0]), ("centroid_y_mm", CENTRE[1])):
        e = disc.estimates[key]
        assert abs(e.value - c) < 3 * e.stderr


def test_defocus_disc_encircled_energy_and_geometric_radius(disc):
    for key, frac in (("ee50_radius_mm", 0.5), ("ee80_radius_mm", 0.8)):
        e = disc.estimates[key]
        assert abs(e.value - R * math.sqrt(frac)) < max(3 * e.stderr, 0.05 * disc.grid.pitch_mm)
    geo = disc.estimates["geometric_radius_mm"]
    assert abs(geo.value - R) <= disc.grid.pitch_mm
    assert disc.estimates["fraction_off_grid"].value == 0.0


def test_defocus_disc_is_uniform_with_unit_volume(disc):
    assert disc.energy_on_grid == pytest.approx(1.0)
    gx, gy = disc.grid.mesh_mm()
    r = np.hypot(gx - CENTRE[0], gy - CENTRE[1])
    inner, outer = r < 0.9 * R, r > R + disc.grid.pitch_mm
    level = 1.0 / (math.pi * R * R)  # unit volume over the disc (1/mm^2)
    vals, se = disc.psf[inner], disc.psf_stderr[inner]
    assert abs(vals.mean() - level) < 4 * math.sqrt(np.sum(se ** 2)) / vals.size
    # per-pixel batch-means errors are honest: they match the scatter between pixels
    assert 0.9 < vals.std() / math.sqrt(np.mean(se ** 2)) < 1.1
    assert np.all(disc.psf[outer] == 0)


def test_jackknife_errors_are_calibrated_over_seeds():
    grid = ImageGrid.centred(64, 2.0, CENTRE)
    keys = ("rms_radius_mm", "ee80_radius_mm", "centroid_x_mm")
    vals: dict[str, list] = {k: [] for k in keys}
    ses: dict[str, list] = {k: [] for k in keys}
    for seed in range(24):
        x, y = disc_rays(np.random.default_rng(100 + seed), 20_000)
        res = run(x, y, grid, batches=16, seed=seed)
        for k in keys:
            vals[k].append(res.estimates[k].value)
            ses[k].append(res.estimates[k].stderr)
    for k in keys:  # the scatter over seeds matches the reported standard error
        ratio = np.std(vals[k], ddof=1) / np.mean(ses[k])
        assert 0.65 < ratio < 1.5, (k, ratio)


@pytest.mark.parametrize("blades", [5, 7])
def test_iris_polygon_defocus_rms_and_shape(blades):
    x, y = polygon_rays(np.random.default_rng(blades), 300_000, blades)
    grid = ImageGrid.centred(128, 1.0, CENTRE)
    res = run(x, y, grid)
    rms = res.estimates["rms_radius_mm"]
    exact = R * math.sqrt((2 + math.cos(2 * math.pi / blades)) / 6)  # regular N-gon, circumradius R
    assert abs(rms.value - exact) < 3 * rms.stderr
    assert abs(exact - R / math.sqrt(2)) > 10 * rms.stderr  # it is not the disc's value
    # every lit bin lies within half a bin diagonal of the polygon (edge normals at (2k + 1) pi / N)
    gx, gy = grid.mesh_mm()
    u, v = (gx - CENTRE[0]) / R, (gy - CENTRE[1]) / R
    slack = math.sqrt(0.5) * grid.pitch_mm / R
    normals = (2 * np.arange(blades) + 1) * math.pi / blades
    dist = np.max([u * math.cos(a) + v * math.sin(a) for a in normals], axis=0) - math.cos(math.pi / blades)
    assert not np.any(res.psf[dist > slack] > 0)
    assert np.all(res.psf[dist < -slack] > 0)  # and the polygon is filled


def test_moments_from_the_histogram_alone():
    x, y = disc_rays(np.random.default_rng(2), 300_000)
    res = run(x, y, ImageGrid.centred(64, 2.0, CENTRE), moments=False)
    rms = res.estimates["rms_radius_mm"]
    assert "histogram" in rms.method
    assert abs(rms.value - R / math.sqrt(2)) < 3 * rms.stderr + 1e-4  # Sheppard-corrected bins


def test_light_off_the_grid_is_counted_not_renormalised():
    x, y = disc_rays(np.random.default_rng(3), 200_000)
    # the grid's bottom edge runs 0.03 mm below the disc centre: a circular segment falls off
    grid = ImageGrid((128, 128), 1.0, CENTRE[0] - 63.5e-3, CENTRE[1] - 0.03 + 127.5e-3)
    res = run(x, y, grid)
    h = CENTRE[1] - grid.extent_mm[2]
    assert h == pytest.approx(0.03)
    cut = (R * R * math.acos(h / R) - h * math.sqrt(R * R - h * h)) / (math.pi * R * R)
    f = res.estimates["fraction_off_grid"]
    assert abs(f.value - cut) < 4 * f.stderr and f.stderr > 0
    assert res.energy_on_grid == pytest.approx(1.0 - f.value)
    # the exact moment sums still see every ray
    assert abs(res.estimates["rms_radius_mm"].value - R / math.sqrt(2)) < 3 * res.estimates["rms_radius_mm"].stderr


def test_reference_accumulation_matches_direct_sums():
    rng = np.random.default_rng(4)
    x, y, w = rng.normal(1.0, 0.01, 1000), rng.normal(2.0, 0.01, 1000), rng.random(1000)
    b = rng.integers(0, 4, 1000)
    grid = ImageGrid.centred(16, 2.0, (1.0, 2.0))
    hist, off = histogram_rays(x, y, w, grid, 4, batch=b)
    assert hist.sum() + off.sum() == pytest.approx(w.sum())
    row, col = grid.pixel_of(x[0], y[0])
    r, c = int(math.floor(row + 0.5)), int(math.floor(col + 0.5))
    gx, gy = grid.position_of(r, c)
    assert abs(gx - x[0]) <= grid.pitch_mm / 2 and abs(gy - y[0]) <= grid.pitch_mm / 2
    s = ray_moment_sums(x, y, w, (1.0, 2.0), 4, batch=b)
    assert len(MOMENT_KEYS) == s.shape[1] == 6
    dx, dy = x - 1.0, y - 2.0
    m = b == 2
    assert np.allclose(s[2], [w[m].sum(), (w * dx)[m].sum(), (w * dy)[m].sum(), (w * dx * dx)[m].sum(),
                              (w * dx * dy)[m].sum(), (w * dy * dy)[m].sum()])


def test_ensquared_and_encircled_energy_of_a_gaussian():
    from scipy.special import erf

    from lensrt.analysis.psf.energy import encircled_energy, ensquared_energy

    grid = ImageGrid.centred(81, 0.5, (1.0, 1.0))
    gx, gy = grid.mesh_mm()
    s = 3e-3
    psf = np.exp(-((gx - 1.0) ** 2 + (gy - 1.0) ** 2) / (2 * s * s)) / (2 * math.pi * s * s)
    half = np.array([1.0, 2.0, 4.0, 8.0]) * 1e-3
    assert np.allclose(ensquared_energy(psf, grid, half), erf(half / (s * math.sqrt(2))) ** 2, atol=2e-3)
    assert np.allclose(encircled_energy(psf, grid, half, points=True), 1 - np.exp(-half ** 2 / (2 * s * s)),
                       atol=1e-4)
    assert np.allclose(encircled_energy(psf, grid, half), 1 - np.exp(-half ** 2 / (2 * s * s)), atol=3e-3)


def test_result_container_checks_and_serialises(disc):
    d = json.loads(dumps_json(disc.to_dict()))
    assert d["kind"] == "geometric" and d["samples"] == 400_000 and d["batches"] == 32
    assert d["grid"]["pitch_um"] == 1.0 and d["estimates"]["rms_radius_mm"]["stderr"] > 0
    assert disc.binned
    with pytest.raises(LensrtError, match="kind"):
        PsfResult(disc.psf, disc.grid, "magic", (550.0,), (1.0,))
    with pytest.raises(LensrtError, match="shape"):
        PsfResult(disc.psf[:-1], disc.grid, "geometric", (550.0,), (1.0,))
    grid = ImageGrid.centred(8, 1.0)
    with pytest.raises(LensrtError, match="no rays"):
        geometric_psf(np.zeros((4, 8, 8)), grid)
    with pytest.raises(LensrtError, match="batches"):
        geometric_psf(np.ones((1, 8, 8)), grid)


def test_diffraction_result_wraps_an_airy_pattern():
    from scipy.optimize import brentq
    from scipy.special import j0, j1

    n = 96
    mask = circular_aperture(n)
    psf, grid, rep = psf_fft(PupilFunction(mask, np.zeros((n, n)), 550.0, 4.0, intensity=mask), 4)
    res = diffraction_result(psf, grid, "diffraction-fft", wavelengths_nm=[550.0], samples=n * n,
                             metadata={"sampling": rep})
    lam_n = 550e-6 * 4.0
    v80 = brentq(lambda v: 1 - j0(v) ** 2 - j1(v) ** 2 - 0.8, 1.0, 4.0)
    r80 = v80 * lam_n / math.pi  # of the whole light; the grid holds ~99.5 % of it
    e = res.estimates["ee80_radius_mm"]
    assert e.stderr == 0.0 and e.method == "deterministic"
    assert e.value == pytest.approx(r80, rel=0.01)
    assert not res.binned and res.seed is None
    assert json.loads(dumps_json(res.to_dict()))["metadata"]["sampling"]["pitch_um"] == pytest.approx(0.55)


def test_linearised_ee_jackknife_agrees_with_full_recomputation():
    # EE radii's leave-one-out values are linearised (one pixel-fraction vector for all batches, the
    # centroid shift through the gradient); a brute-force jackknife recomputes each by bisection
    from lensrt.analysis.psf.energy import radius_for_energy
    from lensrt.analysis.psf.result import _ee_radius_jackknife
    from lensrt.stats import jackknife
    x, y = disc_rays(np.random.default_rng(3), 50_000)
    x = x + 0.4 * (y - CENTRE[1]) ** 2 / R  # an asymmetric (comatic) blur: the centroid moves
    grid = ImageGrid.centred(64, 2.0, CENTRE)
    h, off = histogram_rays(x, y, None, grid, 16)
    for frac in (0.5, 0.8):
        value, se = _ee_radius_jackknife(h, off, grid, frac)

        def radius(t, o):
            return radius_for_energy(t / ((t.sum() + o) * grid.pixel_area_mm2), grid, frac, relative=False,
                                     supersample=4, tol_mm=1e-5 * grid.pitch_mm)
        v2, se2 = jackknife((h, off), radius)
        assert abs(value - v2) < 0.01 * grid.pitch_mm
        assert 0.8 < se / se2 < 1.2
