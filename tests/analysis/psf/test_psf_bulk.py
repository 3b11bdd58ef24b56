"""The analysis of many fields' histograms at once (lensrt.analysis.psf.bulk) against the per-field reference.

The reference is the per-field code without ``sums`` (``geometric_psf``, ``add_mtf_estimates``): every pass
over the per-batch histograms made field by field. The bulk path makes those passes for a stack of fields;
where its arithmetic is the same (all sums of ray counts, the ring geometry, the jackknife) it must give the
same bits, where it sums in another order (the MTF's Fourier sums through BLAS, the per-pixel standard error
scaled after the deviations) the same numbers to 1e-12 relative.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.psf import jackknife
from lensrt.analysis.psf.bulk import field_sums
from lensrt.analysis.psf.geometric import add_mtf_estimates
from lensrt.analysis.psf.result import geometric_psf
from lensrt.analysis.psf.setup import make_setup
from lensrt.trace.stream import Grid, stream, stream_sources

#: estimates whose bulk arithmetic sums in another order than the reference's (module docstring)
REORDERED = {"mtf_sagittal", "mtf_tangential", "mtf_curve_sagittal", "mtf_curve_tangential"}


@pytest.fixture(scope="module")
def traced():
    """Three real fields of the double Gauss (axis, 0.7, corner), each its own bin size, 8 batches."""
    lens = library_lens("dgauss_50mm_f2")
    setup = make_setup(lens, focus="image", device="cpu", rays=1 << 13, batches=8, pixels=24,
                       mtf_freqs_cpmm=(10.0, 40.0), mtf_curve_cpmm=(5.0, 20.0, 60.0, 400.0))
    srcs = stream_sources(lens, [(0.0, 0.0), (0.0, 0.7), (0.5, 1.0)], device="cpu")
    srcs = [replace(s, pixel_mm=p) for s, p in zip(srcs, (0.002, 0.003, 0.006))]
    res = stream(lens, srcs, Grid(24, 24, 0.003), 1 << 13, batches=8, batch_histograms=True, device="cpu")
    inputs, grids = [], []
    for j in range(len(srcs)):
        b = res.bins(j)
        grids.append(ImageGrid.centred(b["shape"], 1e3 * b["pixel_mm"], b["centre_mm"]))
        inp = res.psf_inputs(j)
        inp["hist"] = np.asarray(inp["hist"], dtype=np.float64)
        inputs.append(inp)
    return setup, inputs, grids


def _analyse(setup, inp: dict, grid: ImageGrid, sums=None):
    r = geometric_psf(grid=grid, **inp, sums=sums)
    add_mtf_estimates(r, inp["hist"], setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm, sums=sums)
    return r


def _bulk(setup, inputs, grids):
    return field_sums(np.stack([i["hist"] for i in inputs]), np.stack([i["off_grid"] for i in inputs]), grids,
                      [i["reference_mm"] for i in inputs], setup)


def _compare(ref, new, rtol: float) -> int:
    """Assert ``new`` equals ``ref`` (bits, or ``rtol`` for REORDERED); the number of numbers compared."""
    assert ref.estimates.keys() == new.estimates.keys()
    n = 0
    for k, e in ref.estimates.items():
        for part in ("value", "stderr"):
            a, b = np.asarray(getattr(e, part), float), np.asarray(getattr(new.estimates[k], part), float)
            if k in REORDERED:
                np.testing.assert_allclose(b, a, rtol=rtol, atol=0, err_msg=f"{k} {part}")
            else:
                assert np.array_equal(a, b), (k, part, a, b)
            n += a.size
    assert np.array_equal(ref.psf, new.psf)
    np.testing.assert_allclose(new.psf_stderr, ref.psf_stderr, rtol=1e-12, atol=0)
    assert ref.metadata == new.metadata
    return n


def test_bulk_sums_give_the_per_field_analysis(traced, monkeypatch):
    setup, inputs, grids = traced
    refs = [_analyse(setup, i, g) for i, g in zip(inputs, grids)]

    # the bulk path must take every Fourier sum from the stack's sums (none recomputed field by field)
    def no_otf(*a, **k):
        raise AssertionError("a Fourier sum was recomputed per field")
    monkeypatch.setattr(jackknife, "_otf_sums", no_otf)
    sums = _bulk(setup, inputs, grids)
    compared = 0
    for ref, inp, g, s in zip(refs, inputs, grids, sums):
        compared += _compare(ref, _analyse(setup, inp, g, s), 1e-12)
    # every estimate was there to compare: centroid, RMS, EE, geometric radius, MTF at 2 + 3 frequencies
    assert compared > 20 * len(refs)
    assert refs[2].metadata["mtf_beyond_grid_nyquist_cpmm"] == [400.0]


def test_a_fields_sums_do_not_depend_on_the_rest_of_the_stack(traced):
    setup, inputs, grids = traced
    together = _bulk(setup, inputs, grids)
    for k in range(len(inputs)):
        alone = _bulk(setup, inputs[k:k + 1], grids[k:k + 1])[0]
        for name in ("H", "s_b", "sx_b", "sy_b", "lit_n", "psf_stderr"):
            assert np.array_equal(getattr(alone, name), getattr(together[k], name)), name
        assert alone.otf.keys() == together[k].otf.keys()
        assert all(np.array_equal(alone.otf[q], together[k].otf[q]) for q in alone.otf)
        assert np.array_equal(alone.rings.dmin, together[k].rings.dmin)
        assert np.array_equal(alone.rings.dmax, together[k].rings.dmax)


def test_bulk_agrees_on_weighted_histograms_to_1e_12(traced):
    """Non-integer weights (sums no longer exact): every estimate within 1e-12 relative of the reference."""
    setup, inputs, grids = traced
    rng = np.random.default_rng(7)
    weighted = [dict(i, hist=i["hist"] * rng.uniform(0.5, 1.5, i["hist"].shape),
                     off_grid=i["off_grid"] * 1.25) for i in inputs]
    sums = _bulk(setup, weighted, grids)
    for inp, g, s in zip(weighted, grids, sums):
        ref, new = _analyse(setup, inp, g), _analyse(setup, inp, g, s)
        for k, e in ref.estimates.items():
            for part in ("value", "stderr"):
                np.testing.assert_allclose(np.asarray(getattr(new.estimates[k], part), float),
                                           np.asarray(getattr(e, part), float), rtol=1e-12, atol=0,
                                           err_msg=f"{k} {part}")
