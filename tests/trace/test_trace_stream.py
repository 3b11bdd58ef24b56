"""The stream kernel: pupil sampling, estimates with standard errors, determinism, samplers."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sstats

from trace_cases import library_lens, pbrt_lens

from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Iris, Lens, Surface, Wavelengths
from lensrt.trace import RayBatch, trace
from lensrt.trace.aiming import FieldPoint, pupil_geometry
from lensrt.trace.kernels.generic import sample_unit_square
from lensrt.trace.sampling import SAMPLERS, spectrum_continuous, spectrum_discrete
from lensrt.trace.stream import Channels, Grid, stream, stream_source

DG = "codev_dblgauss_100mm_f2"


def _stop_first(blades: int = 0, rotation_deg: float = 0.0, object_mm: float = math.inf) -> Lens:
    """A stop in front of a biconvex lens: the entrance pupil is the stop itself."""
    glass = ConstantIndex(1.6)
    s = (Surface(thickness_mm=5.0, is_stop=True, semi_diameter_mm=5.0),
         Surface(curvature_per_mm=1 / 50.0, thickness_mm=5.0, material=glass, semi_diameter_mm=12.0),
         Surface(curvature_per_mm=-1 / 50.0, thickness_mm=40.0, semi_diameter_mm=12.0))
    fields = Fields("angle", (0.0,)) if math.isinf(object_mm) else Fields("object_height", (0.0,))
    return Lens(s, aperture=Aperture("float_by_stop", 0.0), fields=fields, wavelengths=Wavelengths((550.0,)),
                iris=Iris(blades=blades, rotation_rad=math.radians(rotation_deg)), object_distance_mm=object_mm)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_axial_pupil_area(precision, device):
    # on axis, the real entrance pupil of the EPD-50 double Gauss is the 25 mm circle (by the
    # definition of the real stop radius), at the primary wavelength
    lens = library_lens(DG)
    spec = spectrum_discrete([lens.wavelengths.primary_nm])
    src = stream_source(lens, 0.0, 0.0, wavelengths_nm=[lens.wavelengths.primary_nm], device=device)
    res = stream(lens, [src], Grid(32, 32, 0.01), 1 << 16, spectrum=spec, sampler="sobol", seed=4,
                 precision=precision, device=device)
    area, se = res.transmitted_area_mm2(0)
    assert 0 < se < 2.0
    assert abs(area - math.pi * 25.0**2) < 4 * se + 0.05
    counts = res.status_counts()
    assert sum(v for k, v in counts.items() if k != "OUTSIDE_GRID") == res.rays_total


@pytest.mark.parametrize("blades", [0, 5, 7])
def test_iris_pupil_area(blades, device):
    lens = _stop_first(blades, rotation_deg=10.0)
    src = stream_source(lens, device=device)
    res = stream(lens, [src], Grid(16, 16, 0.05), 1 << 15, sampler="r2", seed=1, precision="float32",
                 device=device)
    area, se = res.transmitted_area_mm2()
    exact = math.pi * 25.0 if blades == 0 else 0.5 * blades * 25.0 * math.sin(2 * math.pi / blades)
    assert abs(area - exact) < 4 * se + 1e-3 * exact


def test_cats_eye_area_matches_dense_grid(device):
    """At 20 deg the pbrt 50 mm double Gauss's pupil is a cat's eye; the stream must sample all of it."""
    lens = pbrt_lens("dgauss.50mm")
    wl = lens.wavelengths.primary_nm
    src = stream_source(lens, 0.0, 1.0, wavelengths_nm=[wl], device=device)
    b = src.box
    res = stream(lens, [src], Grid(8, 8, 0.2), 1 << 16, spectrum=spectrum_discrete([wl]), sampler="sobol",
                 seed=9, precision="float64", device=device)
    area, se = res.transmitted_area_mm2()
    # brute force: a fine grid over a region 20 % larger than the box
    n = 300
    pad_a, pad_b = 0.1 * (b.a1 - b.a0), 0.1 * (b.b1 - b.b0)
    ga = np.linspace(b.a0 - pad_a, b.a1 + pad_a, n)
    gb = np.linspace(b.b0 - pad_b, b.b1 + pad_b, n)
    A, B = (x.ravel() for x in np.meshgrid(ga, gb))
    pts = b.points(A, B)
    d = np.broadcast_to(np.asarray(src.field.direction), pts.shape)
    ok = trace(lens, RayBatch(pts, d, wl), "float64", device).ok
    cell = (ga[1] - ga[0]) * (gb[1] - gb[0])
    grid_area = ok.sum() * cell
    # no passing ray outside the box (the box holds the whole pupil)
    inside = (A >= b.a0) & (A <= b.a1) & (B >= b.b0) & (B <= b.b1)
    assert not np.any(ok & ~inside)
    axial = stream(lens, [stream_source(lens, device=device)], Grid(8, 8, 0.2), 1 << 14, sampler="sobol",
                   device=device).transmitted_area_mm2()[0]
    assert area < 0.5 * axial  # strongly vignetted: a cat's eye
    assert abs(area - grid_area) < 4 * se + 0.01 * grid_area


def test_moments_match_dense_store_trace(device):
    lens = library_lens(DG)
    wl = lens.wavelengths.primary_nm
    src = stream_source(lens, 0.0, 0.7, wavelengths_nm=[wl], device=device)
    res = stream(lens, [src], Grid(64, 64, 0.004), 1 << 16, spectrum=spectrum_discrete([wl]), sampler="sobol",
                 seed=2, precision="float64", device=device)
    (cx, cy), (sex, sey) = res.centroid()
    rms, se_rms = res.rms_radius()
    b = src.box
    n = 320
    A, B = (x.ravel() for x in np.meshgrid(np.linspace(b.a0, b.a1, n), np.linspace(b.b0, b.b1, n)))
    pts = b.points(A, B)
    r = trace(lens, RayBatch(pts, np.broadcast_to(np.asarray(src.field.direction), pts.shape), wl), "float64",
              device)
    p = r.position_mm[r.ok]
    mx, my = p[:, 0].mean(), p[:, 1].mean()
    rms_grid = math.sqrt(np.mean((p[:, 0] - mx) ** 2 + (p[:, 1] - my) ** 2))
    assert abs(cx - mx) < 4 * sex + 1e-6
    assert abs(cy - my) < 4 * sey + 2e-4 * rms_grid
    assert abs(rms - rms_grid) < 4 * se_rms + 0.005 * rms_grid
    # the histogram holds the weights of the rays that landed on it
    grid_w = res.batch_stats[0, :, 7].sum()
    assert res.histogram.sum() == pytest.approx(grid_w, rel=1e-6)


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_deterministic_and_chunk_invariant(sampler, device):
    lens = library_lens(DG)
    src = stream_source(lens, 0.0, 0.5, device=device)
    run = lambda seed, chunk: stream(lens, [src], Grid(24, 24, 0.01), 1 << 13, sampler=sampler, seed=seed,  # noqa: E731
                                     batches=8, precision="float32", device=device, rays_per_launch=chunk)
    a, b = run(5, None), run(5, None)
    assert np.array_equal(a.histogram, b.histogram)
    assert np.array_equal(a.batch_stats, b.batch_stats) and np.array_equal(a.batch_counts, b.batch_counts)
    c = run(5, 1000)  # many launches: the same rays, the same integer histogram
    assert c.launches > a.launches
    assert np.array_equal(a.histogram, c.histogram)
    assert np.array_equal(a.batch_counts, c.batch_counts)
    d = run(6, None)
    assert not np.array_equal(a.histogram, d.histogram)


def test_samplers_uniform_and_stratified(device):
    n = 1 << 14
    chi2 = {}
    for s in SAMPLERS:
        u = sample_unit_square(s, n, seed=3, precision="float32", device=device)
        assert u.min() >= 0.0 and u.max() < 1.0
        h, _, _ = np.histogram2d(u[:, 0], u[:, 1], bins=16, range=[[0, 1], [0, 1]])
        e = n / 256
        chi2[s] = float(((h - e) ** 2 / e).sum())
    # plain random: consistent with uniform (255 degrees of freedom); the others far more even
    assert sstats.chi2.sf(chi2["random"], 255) > 1e-3
    for s in ("stratified", "sobol", "r2"):
        assert chi2[s] < 30.0, (s, chi2[s])
    # Owen-scrambled Sobol' points are a (0, m, 2)-net: every elementary interval holds one point
    u = sample_unit_square("sobol", 256, seed=7, device=device)
    for kx in range(9):
        cells = (np.floor(u[:, 0] * 2**kx).astype(int) * 2 ** (8 - kx) + np.floor(u[:, 1] * 2 ** (8 - kx)).astype(int))
        assert len(np.unique(cells)) == 256


def test_spectrum_sampling_into_channels(device):
    lens = _stop_first()
    spec = spectrum_continuous([500.0, 550.0, 600.0], [1.0, 3.0])  # 25 % below 550 nm, 75 % above
    # channel weights interpolate linearly between table wavelengths: a fine table makes a sharp step
    grid_nm = np.arange(450.0, 651.0, 0.5)
    fine = np.stack([(grid_nm < 550.0).astype(float), (grid_nm >= 550.0).astype(float)])
    ch = Channels(fine, 450.0, 0.5)
    src = stream_source(lens, wavelengths_nm=[500.0, 600.0], device=device)
    res = stream(lens, [src], Grid(64, 64, 0.01), 1 << 14, spectrum=spec, channels=ch, sampler="sobol", seed=0,
                 precision="float32", device=device)
    totals = res.histogram.sum(axis=(0, 2, 3))
    frac = totals[1] / totals.sum()
    n_ok = res.status_counts()["OK"]
    assert abs(frac - 0.75) < 4 * math.sqrt(0.75 * 0.25 / n_ok) + 2.0 / 1024  # 1 bin of 0.5 nm at the step


@pytest.mark.parametrize("emitter", ["isotropic", "lambertian"])
def test_point_source_solid_angle(emitter, device):
    """An object point on axis at D in front of a stop of radius a: the weights integrate to the
    solid angle 2 pi (1 - cos alpha) (isotropic) or the projected solid angle pi sin^2 alpha (Lambertian)."""
    D, a = 40.0, 5.0
    lens = _stop_first(object_mm=D)
    fp = FieldPoint(False, None, (0.0, 0.0, -D))
    src = stream_source(lens, field=fp, emitter=emitter, device=device)
    res = stream(lens, [src], Grid(16, 16, 0.05), 1 << 15, sampler="sobol", seed=3, precision="float64",
                 device=device)
    dist = D + pupil_geometry(lens).ep_z_mm  # the aim plane passes through the entrance pupil (the stop)
    per_batch = res.batch_stats[0, :, 1] / (res.rays_per_source / res.batches) * res.pupil_area_mm2[0] / dist**2
    est, se = per_batch.mean(), per_batch.std(ddof=1) / math.sqrt(len(per_batch))
    alpha = math.atan(a / D)
    exact = 2 * math.pi * (1 - math.cos(alpha)) if emitter == "isotropic" else math.pi * math.sin(alpha) ** 2
    assert abs(est - exact) < 4 * se + 1e-4 * exact


def test_device_reduction_equals_host_reduction(device):
    """The GPU path sums per-thread slots with a kernel; run it here too (threads > 1 per batch)."""
    lens = library_lens(DG)
    src = stream_source(lens, 0.0, 0.3, device=device)
    kw = dict(sampler="random", seed=3, batches=4, precision="float32", device=device, threads_per_batch=8)
    a = stream(lens, [src], Grid(16, 16, 0.01), 1 << 12, device_reduce=False, **kw)
    b = stream(lens, [src], Grid(16, 16, 0.01), 1 << 12, device_reduce=True, **kw)
    assert np.array_equal(a.batch_counts, b.batch_counts)
    np.testing.assert_allclose(a.batch_stats, b.batch_stats, rtol=1e-12, atol=0)
    assert np.array_equal(a.histogram, b.histogram)


def test_batch_histograms_feed_the_psf_analysis(device):
    from lensrt.analysis.grid import ImageGrid
    from lensrt.analysis.psf.result import geometric_psf
    lens = library_lens(DG)
    wl = lens.wavelengths.primary_nm
    src = stream_source(lens, 0.0, 0.5, wavelengths_nm=[wl], device=device)
    grid = Grid(48, 40, 0.004)
    res = stream(lens, [src], grid, 1 << 14, spectrum=spectrum_discrete([wl]), batches=8, batch_histograms=True,
                 precision="float64", device=device)
    assert res.batch_histograms.shape == (1, 8, 1, 40, 48)
    assert np.allclose(res.batch_histograms.sum(axis=1), res.histogram)
    kw = res.psf_inputs(0)
    psf = geometric_psf(grid=ImageGrid.centred((40, 48), grid.pixel_mm * 1000.0, src.centre_mm), **kw)
    rms, se = res.rms_radius()
    # the analysis's RMS radius from the same moment sums agrees with the stream's own estimate
    assert abs(float(psf.estimates["rms_radius_mm"].value) - rms) < 1e-9 + 1e-6 * rms


def test_stratified_wavelength_steepens_the_convergence(device):
    """The stratified sampler stratifies the wavelength too (a jittered pupil grid per line): on a lens
    with longitudinal colour, the RMS radius converges faster than N^-1/2 and faster than random."""
    from lensrt.stats import fit_loglog_slope
    lens = library_lens("cooke_triplet_50mm_f5")
    src = stream_source(lens, 0.0, 0.0, device=device)
    slopes, last = {}, {}
    for sampler in ("random", "stratified"):
        ns, err = [], []
        for n in (1 << 10, 1 << 12, 1 << 14):
            r = stream(lens, [src], Grid(8, 8, 0.01), 32 * n, sampler=sampler, seed=1, batches=32,
                       precision="float32", device=device, histogram=False)
            s = r.batch_stats[0]
            w = s[:, 1]
            rms = np.sqrt(s[:, 4] / w - (s[:, 2] / w) ** 2 + s[:, 5] / w - (s[:, 3] / w) ** 2)
            ns.append(n)
            err.append(rms.std(ddof=1))
        slopes[sampler], last[sampler] = fit_loglog_slope(ns, err), err[-1]
    assert -0.65 < slopes["random"] < -0.35
    assert slopes["stratified"] < -0.6
    assert last["stratified"] < 0.5 * last["random"]


def test_sources_with_their_own_spectra_and_weights_in_one_launch(device):
    """Each source samples its own spectrum (one of the call's) and carries a weight factor: in one
    launch, the same rays as launches of one spectrum each (weights scale histogram and moments)."""
    from dataclasses import replace
    lens = library_lens(DG)
    a, b = (stream_source(lens, 0.0, hy, device=device) for hy in (0.0, 0.6))
    sa = spectrum_continuous([480.0, 560.0, 650.0], [1.0, 3.0])
    sb = spectrum_continuous([500.0, 520.0, 600.0, 640.0], [2.0, 1.0, 1.0])
    kw = dict(sampler="sobol", batches=4, precision="float32", device=device)
    grid = Grid(24, 24, 0.01)
    both = stream(lens, [replace(a, seed=7, rng_index=0, layer=0), replace(b, seed=8, rng_index=0, layer=1,
                                                                            spectrum=1, weight=0.25)],
                  grid, 1 << 12, spectrum=[sa, sb], **kw)
    one_a = stream(lens, [a], grid, 1 << 12, spectrum=sa, seed=7, **kw)
    one_b = stream(lens, [b], grid, 1 << 12, spectrum=sb, seed=8, **kw)
    assert np.array_equal(both.histogram[0], one_a.histogram[0])
    assert np.array_equal(both.batch_stats[0], one_a.batch_stats[0])
    assert np.array_equal(both.batch_counts[1], one_b.batch_counts[0])
    np.testing.assert_allclose(both.histogram[1], 0.25 * one_b.histogram[0], rtol=0, atol=2e-7 * 4096)
    np.testing.assert_allclose(both.batch_stats[1][:, 1:], 0.25 * one_b.batch_stats[0][:, 1:], rtol=1e-6)
    assert both.flux_per_ray(1) == pytest.approx(one_b.flux_per_ray(0))
    with pytest.raises(Exception, match="spectrum"):
        stream(lens, [replace(a, spectrum=2)], grid, 1 << 10, spectrum=[sa, sb], **kw)
