"""Triangles of a ray grid (grid_triangles, GridLinear) against qhull's Delaunay triangulation, matplotlib's
linear interpolator, and closed-form wavefronts: the grid path must be the Delaunay path but for ties and hull
slivers, and no less accurate than it."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from matplotlib.tri import LinearTriInterpolator, Triangulation

from lensrt.analysis.wave.metrics import wavefront_metrics
from lensrt.analysis.wave.pupil_grid import clear_fraction, pupil_coordinates, pupil_from_rays, zernike
from lensrt.analysis.wave.ray_mesh import GridLinear, grid_triangles
from lensrt.analysis.wave.wavefront import RayWavefront, ReferenceSphere, pupil_function_from_wavefront
from lensrt.errors import LensrtError

LAM_NM = 550.0


def bent_grid(m: int, jitter: float = 0.0, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """An m x m grid over [-1, 1]^2 bent as a lens bends a pupil (distortion, shear), optionally jittered
    (a fraction of a cell) so that no four points are cocircular."""
    u = np.linspace(-1.0, 1.0, m)
    a, b = np.meshgrid(u, u, indexing="ij")
    r2 = a * a + b * b
    x = 0.95 * a * (1 + 0.06 * r2) + 0.04 * b
    y = 0.95 * b * (1 - 0.04 * r2) + 0.02 * a * a
    if jitter:
        rng = np.random.default_rng(seed)
        step = 2.0 / (m - 1)
        x = x + rng.uniform(-jitter, jitter, x.shape) * step
        y = y + rng.uniform(-jitter, jitter, y.shape) * step
    return x, y


def as_set(triangles: np.ndarray) -> set:
    return {tuple(sorted(t)) for t in np.asarray(triangles).tolist()}


def test_grid_triangles_are_delaunay_triangles():
    """On a jittered (tie-free) bent grid every grid triangle is one of qhull's Delaunay triangles, and the
    Delaunay triangles the grid lacks are slivers along the hull (all three corners on the grid's rim)."""
    m = 24
    x, y = bent_grid(m, jitter=0.15)
    present = np.ones((m, m), dtype=bool)
    grid = as_set(grid_triangles(x, y, present))
    delaunay = as_set(Triangulation(x.ravel(), y.ravel()).triangles)
    assert len(grid) == 2 * (m - 1) ** 2
    assert grid <= delaunay
    i, j = np.divmod(np.arange(m * m), m)
    rim = (i == 0) | (i == m - 1) | (j == 0) | (j == m - 1)
    assert all(rim[list(t)].all() for t in delaunay - grid)


def test_grid_triangles_of_a_circular_pupil():
    """Rays inside a circle only: cells with four rays give two triangles, cells with three one; every grid
    triangle of the tie-free grid is Delaunay; what Delaunay adds is along the staircase rim."""
    m = 31
    x, y = bent_grid(m, jitter=0.15, seed=2)
    present = np.hypot(x, y) <= 0.9
    tris = grid_triangles(x, y, present)
    assert present.ravel()[tris].all()
    p = present.astype(int)
    corners = p[:-1, :-1] + p[1:, :-1] + p[1:, 1:] + p[:-1, 1:]
    assert len(tris) == 2 * np.sum(corners == 4) + np.sum(corners == 3)
    sel = np.nonzero(present.ravel())[0]
    delaunay = as_set(sel[Triangulation(x.ravel()[sel], y.ravel()[sel]).triangles])
    assert as_set(tris) <= delaunay


def test_grid_linear_equals_matplotlib_on_the_same_triangles():
    m = 40
    x, y = bent_grid(m)
    tris = grid_triangles(x, y, np.ones((m, m), dtype=bool))
    v = np.sin(2.0 * x.ravel()) + 0.3 * y.ravel() ** 3
    ref = LinearTriInterpolator(Triangulation(x.ravel(), y.ravel(), tris), v)
    rng = np.random.default_rng(1)
    qx, qy = rng.uniform(-1.2, 1.2, 5000), rng.uniform(-1.2, 1.2, 5000)
    got = GridLinear(m, np.arange(m * m), x.ravel(), y.ravel()).interp(v, qx, qy)
    want = np.ma.filled(ref(qx, qy), np.nan)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    assert np.isfinite(got).sum() > 3000 and np.isnan(got).sum() > 500   # inside and outside both exercised
    ok = np.isfinite(got)
    assert np.abs(got[ok] - want[ok]).max() < 1e-12


def test_subset_of_rays_equals_a_mesh_of_that_subset():
    """``interp(..., use=valid)`` from one point location gives what a mesh of the valid rays alone gives."""
    m = 36
    x, y = bent_grid(m, jitter=0.1)
    rng = np.random.default_rng(7)
    index = np.nonzero(rng.uniform(size=m * m) < 0.97)[0]          # some rays never placed
    px, py = x.ravel()[index], y.ravel()[index]
    valid = (np.hypot(px, py) <= 0.85) & (rng.uniform(size=index.size) < 0.98)  # a rim and scattered holes
    v = px * px - 0.5 * py + 0.2
    qx, qy = (a.ravel() for a in pupil_coordinates(96))
    both = GridLinear(m, index, px, py).interp(v, qx, qy, use=valid)
    alone = GridLinear(m, index[valid], px[valid], py[valid]).interp(v[valid], qx, qy)
    assert np.array_equal(np.isnan(both), np.isnan(alone))
    ok = np.isfinite(both)
    assert ok.sum() > 4000
    assert np.abs(both[ok] - alone[ok]).max() < 1e-13


def grid_wavefront(opd_waves, m: int = 121, na: float = 0.05) -> RayWavefront:
    """Rays on a bent m x m grid, valid inside the unit circle (2 % margin), OPD ``opd_waves(px, py)`` on the
    real beam's normalised coordinates; with its ray grid (the traced path) -- drop it for the Delaunay path."""
    x, y = bent_grid(m)
    px, py = x.ravel() / 1.02, y.ravel() / 1.02
    rho2 = px * px + py * py
    valid = rho2 <= 1.0 / 1.02 ** 2
    opd_mm = np.where(valid, opd_waves(px * 1.02, py * 1.02) * LAM_NM * 1e-6, 0.0)
    sphere = ReferenceSphere((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), 100.0, (0.0, 0.0, 1.0))
    return RayWavefront(LAM_NM, px, py, valid, opd_mm, np.ones(px.size), na * 1.02, na, sphere, int(m * m),
                        0.01, 1e-4, 0.0, 0.0, 0.0, m, np.arange(m * m))


def zernike_wave(c4: float, c8: float, c11: float):
    """W = c4 Z4 + c8 Z8 + c11 Z11 (Noll: defocus, coma, spherical), waves; RMS without piston and tilt
    sqrt(c4^2 + c8^2 + c11^2) over the unit disc."""
    def w(px, py):
        rho, th = np.hypot(px, py), np.arctan2(py, px)
        return c4 * zernike(4, rho, th) + c8 * zernike(8, rho, th) + c11 * zernike(11, rho, th)
    return w


def clear_cell_rms(w, pupil, n: int) -> float:
    """The exact W's RMS without piston and tilt over the pupil function's clear cells, weighted by their clear
    fractions as :func:`wavefront_metrics` weights them: the closed form with the same pupil pixels."""
    mask = clear_fraction(pupil.fine_mask, n)
    clear = mask > 0
    gx, gy = pupil_coordinates(n)
    x, y, wt = gx[clear] * 1.02, gy[clear] * 1.02, mask[clear]
    basis = np.stack([np.ones_like(x), x, y], axis=-1)
    sw = np.sqrt(wt)
    fit = np.linalg.lstsq(basis * sw[:, None], w(x, y) * sw, rcond=None)[0]
    r = w(x, y) - basis @ fit
    r = r - np.sum(wt * r) / np.sum(wt)
    return float(np.sqrt(np.sum(wt * r * r) / np.sum(wt)))


@pytest.mark.parametrize("coef", [(0.1, 0.0, 0.05), (0.05, 0.08, -0.06), (0.3, -0.1, 0.2)])
def test_grid_path_matches_the_closed_form_as_well_as_delaunay(coef):
    """Known Zernike wavefront: the RMS (no tilt) on either path within 1e-3 of the exact W's over the same
    clear cells; the pupil OPD at the wholly clear cells no further from the exact W than the Delaunay path's
    (its interpolation error), and the two paths closer to each other than that error."""
    w = zernike_wave(*coef)
    wf = grid_wavefront(w)
    old = dataclasses.replace(wf, grid_m=0, grid_index=None)
    n = 128
    m_new, m_old = wavefront_metrics(wf, n_terms=15, pupil_samples=n), wavefront_metrics(old, n_terms=15,
                                                                                          pupil_samples=n)
    p_new, _ = pupil_function_from_wavefront(wf, n)
    p_old, _ = pupil_function_from_wavefront(old, n)
    exact = clear_cell_rms(w, p_new, n)
    assert m_new.rms_waves_no_tilt == pytest.approx(exact, rel=1e-3)
    assert m_old.rms_waves_no_tilt == pytest.approx(exact, rel=1e-3)
    assert abs(m_new.rms_waves_no_tilt - m_old.rms_waves_no_tilt) < 1e-4 * exact
    assert abs(m_new.strehl - m_old.strehl) < 1e-4
    gx, gy = pupil_coordinates(n)
    truth = w(gx * 1.02, gy * 1.02)
    inner = (p_old.amplitude >= 0.999) & (p_new.amplitude >= 0.999)    # cells wholly clear on both paths
    err_new = np.abs(p_new.opd_waves - truth)[inner].max()
    err_old = np.abs(p_old.opd_waves - truth)[inner].max()
    assert err_new <= 1.05 * err_old + 1e-9
    assert np.abs(p_new.opd_waves - p_old.opd_waves)[inner].max() <= err_old


def test_ray_grid_input_errors_are_one_clear_error():
    x, y = bent_grid(8)
    with pytest.raises(LensrtError, match="same ray grid index"):
        GridLinear(8, np.zeros(64, dtype=int), x.ravel(), y.ravel())
    with pytest.raises(LensrtError, match="must lie in"):
        GridLinear(8, np.arange(64) + 1, x.ravel(), y.ravel())
    with pytest.raises(LensrtError, match="no cell of the ray grid"):
        GridLinear(8, np.array([0, 9, 18]), x.ravel()[[0, 9, 18]], y.ravel()[[0, 9, 18]])
    with pytest.raises(LensrtError, match="ray grid indices for"):
        pupil_from_rays(0.5 * x.ravel(), 0.5 * y.ravel(), np.zeros(64), np.ones(64, bool), 16,
                        ray_grid=(8, np.arange(60)))
    with pytest.raises(LensrtError, match="2-D shape"):
        grid_triangles(x.ravel(), y.ravel(), np.ones(64, bool))


def test_traced_wavefront_carries_its_ray_grid_and_both_paths_agree():
    """A real lens's off-axis wavefront: the rays know their grid cell, and the grid path's RMS and Strehl are
    the Delaunay path's within a small fraction of the ray grid's own interpolation error estimate."""
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.diffraction import WavefrontSet
    from lensrt.analysis.psf.geometric import prepare_field
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.analysis.psf.spectrum import line_spectrum
    from lensrt.loading import load_lens
    lens = load_lens(None)
    setup = make_setup(lens, line_spectrum([lens.wavelengths.primary_nm]), "paraxial", "cpu",
                       method="diffraction", pupil_samples=64, ray_grid=64, max_ray_grid=64)
    f = FieldSpec(0.0, 0.5, "half")
    wset = WavefrontSet(setup, prepare_field(setup, f, "cpu"), "cpu")
    wf = wset.wavefronts[0]
    assert wf.grid_m == 64 and wf.grid_index.size == wf.px.size
    assert np.all(np.diff(wf.grid_index) > 0) and wf.grid_index[-1] < 64 * 64
    new = wavefront_metrics(wf, n_terms=15, pupil_samples=64)
    old = wavefront_metrics(dataclasses.replace(wf, grid_m=0, grid_index=None), n_terms=15, pupil_samples=64)
    assert new.zernike_noll_waves == old.zernike_noll_waves          # fitted on the rays: no interpolation
    assert abs(new.rms_waves_no_tilt - old.rms_waves_no_tilt) < 0.1 * max(wf.interp_error_waves, 1e-3)
    assert abs(new.strehl - old.strehl) < 1e-3


def test_wavefront_and_mesh_pickle_after_use():
    """A wavefront that has built its mesh (which holds a lock) still pickles, and gives the same pupil."""
    import pickle
    wf = grid_wavefront(zernike_wave(0.1, 0.05, 0.02), m=41)
    p1, _ = pupil_function_from_wavefront(wf, 32)
    back = pickle.loads(pickle.dumps(wf))
    assert back.mesh is not None and wf.mesh is not None
    p2, _ = pupil_function_from_wavefront(back, 32)
    assert np.array_equal(p1.opd_mm, p2.opd_mm) and np.array_equal(p1.amplitude, p2.amplitude)
    mesh = pickle.loads(pickle.dumps(wf.mesh))
    q = np.linspace(-0.5, 0.5, 7)
    assert np.array_equal(mesh.interp(wf.px, q, q), wf.mesh.interp(wf.px, q, q))


def test_diffraction_mtf_of_a_real_lens_is_the_delaunay_paths():
    """The Cooke triplet off axis (auto picks the MFT): MTF at 10-80 cycles/mm on the grid path within 1e-4
    of the Delaunay path's (measured 5.5e-6), far below what a plot or a three-digit table shows."""
    from pathlib import Path
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.diffraction import WavefrontSet, choose_method, diffraction_psf_at
    from lensrt.analysis.psf.geometric import prepare_field
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.loading import load_lens
    lens = load_lens(Path(__file__).resolve().parents[2] / "data" / "cooke_triplet.toml")
    setup = make_setup(lens, None, "best", "cpu", method="auto", mtf_freqs_cpmm=(10.0, 20.0, 40.0, 80.0))
    f = FieldSpec(0.0, 0.7, "0.7")
    geom = prepare_field(setup, f, "cpu")
    wset = WavefrontSet(setup, geom, "cpu")
    method, reason = choose_method(setup, wset)
    assert method == "mft"
    old = WavefrontSet.of([dataclasses.replace(w, grid_m=0, grid_index=None) for w in wset.wavefronts],
                          wset.ray_grid, wset.interp_error_waves)
    new_r = diffraction_psf_at(setup, f, "cpu", geom, wset, method, reason)
    old_r = diffraction_psf_at(setup, f, "cpu", geom, old, method, reason)
    for key in ("mtf_sagittal", "mtf_tangential"):
        a, b = np.asarray(new_r.estimates[key].value), np.asarray(old_r.estimates[key].value)
        assert a.shape == (4,) and np.all(a > 0.01)
        assert np.abs(a - b).max() < 1e-4
