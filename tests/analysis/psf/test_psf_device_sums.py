"""The PSF map's passes over per-batch histograms on the device (lensrt.analysis.psf.device_sums) against the host.

The reference is the per-field host code without ``sums`` (``geometric_psf``, ``add_mtf_estimates`` on the
downloaded histograms). The kernels run on every device the ``device`` fixture gives (Warp's CPU always).
What they sum are fixed-point ray weights -- the all-batch histogram, per-batch weights, the light inside the
encircled-energy circles (all batches and each) -- exact in any order, so the PSF, the moments (from the
stream's own sums), the encircled-energy radii (the same brackets and bisection on the device) and the off-grid
fraction must be the same bits; the encircled-energy radii are found by the same bisection from the same
brackets, but those are pixel distances, sqrt(x^2 + y^2) on the device and numpy.hypot on the host (and a GPU
may fuse the multiply-adds): one ulp there moves every midpoint by as much, so the radii agree to 1e-12 (in the
report's psf.json 6 of 98 radii differ, by 3.4e-16 relative at most). Sums of products in
another order than NumPy's (first moments, Fourier sums, distances; a GPU may fuse a multiply-add) agree to
1e-12 relative; the jackknife errors that difference nearly equal sums of those (centroid left out batch by
batch) to 1e-9 relative.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.psf import jackknife
from lensrt.analysis.psf.bulk import analysis_on_device, shape_only
from lensrt.analysis.psf.device_sums import DeviceHistograms, device_field_sums
from lensrt.analysis.psf.geometric import add_mtf_estimates
from lensrt.analysis.psf.result import geometric_psf
from lensrt.analysis.psf.setup import make_setup
from lensrt.errors import LensrtError
from lensrt.trace.stream import Grid, stream, stream_sources

#: estimates summed in another order on the device: (value rtol, stderr rtol) (module docstring)
REORDERED = {"mtf_sagittal": (1e-12, 1e-12), "mtf_tangential": (1e-12, 1e-12),
             "mtf_curve_sagittal": (1e-12, 1e-12), "mtf_curve_tangential": (1e-12, 1e-12),
             "geometric_radius_mm": (1e-12, 1e-9), "ee50_radius_mm": (1e-12, 1e-9), "ee80_radius_mm": (1e-12, 1e-9)}


@pytest.fixture(scope="module")
def lens_and_setup():
    lens = library_lens("dgauss_50mm_f2")
    setup = make_setup(lens, focus="image", device="cpu", rays=1 << 13, batches=8, pixels=24,
                       mtf_freqs_cpmm=(10.0, 40.0), mtf_curve_cpmm=(5.0, 20.0, 60.0, 400.0))
    return lens, setup


def _traced(lens, device: str, keep: bool | str):
    """Three real fields (axis, 0.7, corner), each its own bin size, 8 batches; the corner's small bins leave
    most of its light off the grid (its EE80 cannot be estimated)."""
    srcs = stream_sources(lens, [(0.0, 0.0), (0.0, 0.7), (0.5, 1.0)], device=device)
    srcs = [replace(s, pixel_mm=p) for s, p in zip(srcs, (0.002, 0.003, 0.0004))]
    res = stream(lens, srcs, Grid(24, 24, 0.003), 1 << 13, batches=8, batch_histograms=keep, device=device)
    grids = []
    for j in range(len(srcs)):
        b = res.bins(j)
        grids.append(ImageGrid.centred(b["shape"], 1e3 * b["pixel_mm"], b["centre_mm"]))
    return res, grids


def _analyse(setup, inp: dict, grid: ImageGrid, sums=None):
    r = geometric_psf(grid=grid, **inp, sums=sums)
    add_mtf_estimates(r, inp["hist"], setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm, sums=sums)
    return r


def _device_sums(res, grids, setup, device, sources=None):
    d = res.extra["device_histograms"]
    _, hb, chan, ny, nx = d["shape"]
    dh = DeviceHistograms(d["array"], res.extra["layers_of_sources"], hb, chan, ny, nx, d["unit"], device)
    sources = list(range(len(grids))) if sources is None else sources
    off = np.stack([res.off_grid_weight(j) for j in sources])
    return device_field_sums(dh, sources, off, [grids[j] for j in sources],
                             [tuple(res.centre_mm[j]) for j in sources], setup)


def test_device_sums_give_the_host_analysis(lens_and_setup, device, monkeypatch):
    lens, setup = lens_and_setup
    host_res, grids = _traced(lens, device, True)
    dev_res, _ = _traced(lens, device, "device")
    assert dev_res.batch_histograms is None and dev_res.extra["device_histograms"]["array"].device == device
    refs = [_analyse(setup, dict(host_res.psf_inputs(j), hist=np.asarray(host_res.psf_inputs(j)["hist"], float)), g)
            for j, g in enumerate(grids)]

    # nothing may be recomputed from per-batch histograms on the host: they are not there
    def no_host_pass(*a, **k):
        raise AssertionError("a pass over per-batch histograms ran on the host")
    monkeypatch.setattr(jackknife, "_otf_sums", no_host_pass)
    sums = _device_sums(dev_res, grids, setup, device)
    compared = 0
    for j, (ref, g, s) in enumerate(zip(refs, grids, sums)):
        assert s.complete and s.lit_n is None and s.rings is None
        inp = dict(dev_res.psf_inputs(j), hist=shape_only(setup.batches, *g.shape))
        new = _analyse(setup, inp, g, s)
        assert ref.estimates.keys() == new.estimates.keys()
        for k, e in ref.estimates.items():
            for i, part in enumerate(("value", "stderr")):
                a, b = np.asarray(getattr(e, part), float), np.asarray(getattr(new.estimates[k], part), float)
                rtol = REORDERED.get(k, (0.0, 0.0))[i]
                if rtol == 0.0:
                    assert np.array_equal(a, b), (j, k, part, a, b)
                else:
                    np.testing.assert_allclose(b, a, rtol=rtol, atol=0, err_msg=f"field {j} {k} {part}")
                compared += a.size
        assert np.array_equal(ref.psf, new.psf)
        np.testing.assert_allclose(new.psf_stderr, ref.psf_stderr, rtol=1e-12, atol=0)
        assert ref.metadata == new.metadata
    # centroid, RMS, EE, geometric radius, off-grid fraction, MTF at 2 + 3 frequencies, for every field
    assert compared > 20 * len(refs)
    assert "ee80_radius_mm" in refs[0].estimates and "ee80_radius_mm" not in refs[2].estimates
    assert refs[1].metadata["mtf_beyond_grid_nyquist_cpmm"] == [400.0]


def test_a_fields_device_sums_do_not_depend_on_the_group(lens_and_setup, device):
    lens, setup = lens_and_setup
    res, grids = _traced(lens, device, "device")
    together = _device_sums(res, grids, setup, device)
    for k in range(len(grids)):
        alone = _device_sums(res, grids, setup, device, [k])[0]
        for name in ("H", "s_b", "sx_b", "sy_b", "psf_stderr", "geometric_radius"):
            assert np.array_equal(getattr(alone, name), getattr(together[k], name)), name
        assert alone.otf.keys() == together[k].otf.keys()
        assert all(np.array_equal(alone.otf[q], together[k].otf[q]) for q in alone.otf)
        assert alone.ee_radii == together[k].ee_radii


def test_the_choice_of_analysis_device(monkeypatch):
    monkeypatch.delenv("LENSRT_PSF_ANALYSIS", raising=False)
    assert analysis_on_device("cuda:0") and not analysis_on_device("cpu")
    monkeypatch.setenv("LENSRT_PSF_ANALYSIS", "device")
    assert analysis_on_device("cpu")
    monkeypatch.setenv("LENSRT_PSF_ANALYSIS", "host")
    assert not analysis_on_device("cuda:0")
    monkeypatch.setenv("LENSRT_PSF_ANALYSIS", "gpu")
    with pytest.raises(LensrtError, match="LENSRT_PSF_ANALYSIS"):
        analysis_on_device("cpu")


def test_stream_refuses_an_unknown_histogram_keeping(lens_and_setup):
    lens, _ = lens_and_setup
    srcs = stream_sources(lens, [(0.0, 0.0)], device="cpu")
    with pytest.raises(LensrtError, match="batch_histograms"):
        stream(lens, srcs, Grid(8, 8, 0.003), 64, batches=2, batch_histograms="gpu", device="cpu")


def test_a_map_gives_the_same_psfs_with_either_analysis(lens_and_setup, device, monkeypatch):
    """geometric_psfs end to end (the map's path): the device path against the host path on the same device."""
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.groups import geometric_psfs
    lens, setup = lens_and_setup
    fields = [FieldSpec(0.0, 0.0, "axis"), FieldSpec(0.3, 0.9, "corner")]
    out = {}
    for mode in ("host", "device"):
        monkeypatch.setenv("LENSRT_PSF_ANALYSIS", mode)
        out[mode] = geometric_psfs(setup, fields, [11, 12], device)
    for a, b in zip(out["host"], out["device"]):
        assert a.metadata["analysis_device"] == "host" and b.metadata["analysis_device"] == device
        assert np.array_equal(a.psf, b.psf) and a.estimates.keys() == b.estimates.keys()
        np.testing.assert_allclose(b.psf_stderr, a.psf_stderr, rtol=1e-12, atol=0)
        for k, e in a.estimates.items():
            for i, part in enumerate(("value", "stderr")):
                u, v = np.asarray(getattr(e, part), float), np.asarray(getattr(b.estimates[k], part), float)
                np.testing.assert_allclose(v, u, rtol=REORDERED.get(k, (0.0, 0.0))[i], atol=0, err_msg=f"{k} {part}")
