"""The lens-specialised kernels (lensrt.trace.specialised) against the reference tracer and the
generic kernels: same statuses, the same numbers to rounding, the same Monte Carlo rays."""
from __future__ import annotations

import math

import numpy as np
import pytest

from trace_cases import all_cases, library_lens, max_reference_error
from test_trace_kernels import FLOAT32_BOUND_MM, _random_rays, _status_cases

from lensrt.errors import LensrtError
from lensrt.prescription.model import Iris
from lensrt.trace import RayBatch, trace
from lensrt.trace.pack import pack_arrays
from lensrt.trace.reference import trace_reference
from lensrt.trace.sampling import spectrum_continuous
from lensrt.trace.shape import IRIS_POLYGON, Layout, constants, lens_shape
from lensrt.trace.stream import Grid, stream, stream_source
from lensrt.trace.variants import choose_kernel

CASES = all_cases()
#: a spread of shapes: aspheres, a conic-free f/1, |R| = 1e7 mm, a fisheye, model and catalog glasses
NAMES = ["asphere", "f1", "flat_1e7", "library:nikkor_28mm_f1.4_asph", "library:fisheye_10mm_f4",
         "library:dgauss_50mm_f2", "library:cooke_triplet_50mm_f5"]


@pytest.mark.parametrize("name", NAMES)
def test_specialised_float64_equals_reference(name, device):
    lens = CASES[name]
    rays = _random_rays(lens, 200, seed=11)
    res = trace(lens, rays, "float64", device, kernel="specialised")
    assert res.kernel == "specialised"
    assert max_reference_error(lens, rays, res) <= 1e-10
    assert res.counts["OK"] > 0


@pytest.mark.parametrize("name", ["library:dgauss_50mm_f2", "library:nikkor_28mm_f1.4_asph"])
def test_specialised_float32_within_bound(name, device):
    lens = CASES[name]
    rays = _random_rays(lens, 1000, seed=5, aim="real")
    r64 = trace(lens, rays, "float64", device, kernel="generic")
    r32 = trace(lens, rays, "float32", device, kernel="specialised")
    same = r64.status == r32.status
    assert same.mean() >= 0.995
    ok = same & (r64.status == 0) & ~r64.grazing
    assert ok.sum() > 20
    assert np.max(np.abs(r32.position_mm[ok] - r64.position_mm[ok])) < FLOAT32_BOUND_MM
    assert np.max(np.abs(r32.opl_mm[ok] - r64.opl_mm[ok])) < FLOAT32_BOUND_MM


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_specialised_statuses_match_reference(precision, device):
    for lens, o, d, expected in _status_cases():
        ref = trace_reference(lens, o, d, 587.5618)
        res = trace(lens, RayBatch(np.array([o], float), np.array([d], float), 587.5618), precision, device,
                    kernel="specialised")
        assert (res.status[0], res.surface[0]) == (ref.status, ref.surface) == (expected, ref.surface)
        assert np.all(np.isfinite(res.position_mm)) and np.all(np.isfinite(res.direction))


def test_specialised_never_nan(device):
    lens = library_lens("codev_dblgauss_100mm_f2")
    rng = np.random.default_rng(2)
    n = 2000
    o = rng.normal(0, 60, (n, 3))
    d = rng.normal(0, 1, (n, 3))
    d[:5] = 0.0
    o[5:10] = np.nan
    res = trace(lens, RayBatch(o, d, rng.uniform(380, 1000, n)), "float32", device, kernel="specialised")
    fine = ~np.isnan(o).any(axis=1)
    for arr in (res.position_mm, res.direction, res.opl_mm):
        assert np.all(np.isfinite(arr[fine]))
    assert np.all(res.status[:10] != 0)


def test_iris_polygon_by_blade_normals_matches_reference(device):
    """The N-gon test by blade normals (and roundness, obstruction) against the reference's angle formula."""
    lens = library_lens("dgauss_50mm_f2").replace(iris=Iris(blades=5, rotation_rad=0.3, roundness=0.4,
                                                            obstruction_ratio=0.2))
    packed = pack_arrays(lens)
    shape = lens_shape(*packed)
    assert shape.iris == IRIS_POLYGON and shape.rounded and shape.obstruction
    assert len(constants(shape, *packed)) == Layout(shape).size
    rays = _random_rays(lens, 400, seed=1)
    res = trace(lens, rays, "float64", device, kernel="specialised")
    ref = [trace_reference(lens, rays.origin_mm[i], rays.direction[i], rays.wavelength_nm[i]) for i in range(len(rays))]
    assert np.array_equal(res.status, [r.status for r in ref])
    assert np.array_equal(res.surface, [r.surface for r in ref])
    assert (res.surface == lens.stop_index).sum() > 10  # the iris did clip


def test_stream_specialised_equals_generic(device):
    """Same samples, same rays: float64 counts and histogram equal, moments to rounding."""
    lens = library_lens("dgauss_50mm_f2").replace(iris=Iris(blades=7, rotation_rad=math.radians(10.0)))
    src = stream_source(lens, 0.0, 1.0, device=device)
    spec = spectrum_continuous([400.0, 700.0], [1.0])
    kw = dict(spectrum=spec, sampler="sobol", seed=1, batches=8, precision="float64", device=device)
    g = stream(lens, [src], Grid(48, 48, 0.004), 1 << 15, kernel="generic", **kw)
    s = stream(lens, [src], Grid(48, 48, 0.004), 1 << 15, kernel="specialised", **kw)
    assert (g.extra["kernel"], s.extra["kernel"]) == ("generic", "specialised")
    assert np.array_equal(g.batch_counts, s.batch_counts)
    assert np.array_equal(g.histogram, s.histogram)
    np.testing.assert_allclose(s.batch_stats, g.batch_stats, rtol=1e-9, atol=1e-12)
    # deterministic, and a different launch split traces the same rays
    s2 = stream(lens, [src], Grid(48, 48, 0.004), 1 << 15, kernel="specialised", rays_per_launch=3000, **kw)
    assert np.array_equal(s.histogram, s2.histogram) and np.array_equal(s.batch_counts, s2.batch_counts)
    # without the histogram: the same counts and moments, a zero histogram
    h = stream(lens, [src], Grid(48, 48, 0.004), 1 << 15, kernel="specialised", histogram=False, **kw)
    assert np.array_equal(h.batch_counts, s.batch_counts) and np.array_equal(h.batch_stats, s.batch_stats)
    assert not h.histogram.any()


def test_kernel_choice():
    lens = library_lens("dgauss_50mm_f2")
    shape = lens_shape(*pack_arrays(lens))
    assert choose_kernel("auto", "cpu", shape, 10**9) == "generic"
    assert choose_kernel("auto", "cuda:0", shape, 10**9) == "specialised"
    assert choose_kernel("auto", "cuda:0", shape, 1000) == "generic"
    assert choose_kernel("specialised", "cpu", shape, 10) == "specialised"
    with pytest.raises(LensrtError):
        choose_kernel("specialised", "cpu", shape, 10, possible=False)
    with pytest.raises(LensrtError):
        choose_kernel("fast", "cpu", shape, 10)
    # records and early ends run the generic kernel under "auto"
    rays = _random_rays(lens, 10, seed=0)
    assert trace(lens, rays, "float64", "cpu", record=True).kernel == "generic"
