"""--target-error on PSF, bokeh and render: the achieved error is within the target at the stated confidence.

Each test repeats a progressive run over fixed seeds and measures the error it really achieved
against a reference that it did not see: the closed-form RMS radius of a stigmatic lens's pure
defocus (PSF), and long runs (bokeh spot, render window) whose own variance is subtracted.

* PSF: the target is the RMS radius's relative standard error E; a run that stopped on it is within
  1.96 E of the truth with probability >= 0.95, so at least 10 of 12 runs must be (binomial: the
  test passes with probability > 0.98 when the errors are honest).
* bokeh and render: the target is an RMS over K pixels of per-pixel relative standard errors; the
  achieved RMS relative error over the same pixels exceeds E (1 + 1.645 sqrt(2 / K)) with probability
  <= 0.05 (chi-square with K degrees of freedom, normal approximation), so at least 6 of 8 runs
  must be within it (P > 0.99); and the mean achieved error must match the estimate to 15 %.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lensrt.analysis.bokeh.entry import bokeh_spot, focus_lens, spot_source
from lensrt.analysis.bokeh.trace import DISC_THRESHOLD
from lensrt.studies.convergence.quantities import stigmatic_defocus_rms_mm
from lensrt.analysis.fields import FieldSpec
from lensrt.analysis.psf.setup import make_setup
from lensrt.analysis.psf.geometric import geometric_psf_at, prepare_field
from lensrt.loading import load_lens

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

STIG = str(Path(__file__).resolve().parents[1] / "data" / "plano_hyperbolic_f5.toml")
AXIS = FieldSpec(0.0, 0.0, "axis")


def _achieved(y: np.ndarray, y_ref: np.ndarray, var_ref: np.ndarray, mask: np.ndarray) -> float:
    """RMS relative error of ``y`` against the reference over ``mask``, the reference's variance removed."""
    d2 = ((y[mask] - y_ref[mask]) ** 2 - var_ref[mask]) / y_ref[mask] ** 2
    return math.sqrt(max(float(np.mean(d2)), 0.0))


def test_psf_target_error_against_the_closed_form():
    lens = load_lens(STIG)
    setup = make_setup(lens, focus="image", device="cpu", rays=1 << 24, batches=16, pixels=48, ee_fractions=(),
                       mtf_freqs_cpmm=(), sampler="random", target_error=2.5e-4)
    truth, _ = stigmatic_defocus_rms_mm(lens, [587.6], setup.plane_z_mm, AXIS)
    geom = prepare_field(setup, AXIS, "cpu")
    hits, runs = 0, 12
    for seed in range(runs):
        r = geometric_psf_at(setup, AXIS, seed, "cpu", geom)
        e = r.estimates["rms_radius_mm"]
        assert r.metadata["stop_reason"] == "target_error" and r.metadata["rounds"] >= 3
        assert e.stderr <= 2.5e-4 * e.value
        hits += abs(e.value - truth) <= 1.96 * 2.5e-4 * truth
    assert hits >= 10


@pytest.fixture(scope="module")
def spot():
    lens = load_lens("dgauss_50mm_f2")
    focus = focus_lens(lens, 2000.0)
    return lens, focus, spot_source(lens, focus, 10000.0)


def test_bokeh_target_error_is_met(spot):
    lens, focus, src = spot
    target = 0.05
    ref = bokeh_spot(lens, focus, src, pixel_um=20.0, rays=1 << 22, seed=999, device="cpu")
    y_ref, var_ref = ref.sensor_xyz[1], ref.var_y
    disc = y_ref >= DISC_THRESHOLD * np.percentile(y_ref[y_ref > 0], 99.0)
    k = int(disc.sum())
    bound = target * (1.0 + 1.645 * math.sqrt(2.0 / k))
    achieved, estimated = [], []
    for seed in range(8):
        img = bokeh_spot(lens, focus, src, pixel_um=20.0, rays=1 << 24, seed=seed, device="cpu", target_error=target)
        s = img.sources[0]
        assert s["stop_reason"] == "target_error" and s["rounds"] >= 2 and s["rays"] < 1 << 24
        assert s["noise_rms"] <= target and img.noise["rel_stderr_rms_max"] == s["noise_rms"]
        achieved.append(_achieved(img.sensor_xyz[1], y_ref, var_ref, disc))
        estimated.append(s["noise_rms"])
    assert sum(a <= bound for a in achieved) >= 6, (achieved, bound)
    assert np.mean(achieved) == pytest.approx(np.mean(estimated), rel=0.15)


def test_bokeh_time_budget_stops_the_rounds(spot):
    lens, focus, src = spot
    img = bokeh_spot(lens, focus, src, pixel_um=20.0, rays=1 << 30, seed=1, device="cpu", target_error=1e-4,
                     time_budget_s=0.3)
    s = img.sources[0]
    assert s["stop_reason"] == "time_budget" and s["rays"] < 1 << 30 and s["rounds"] >= 1
    assert img.settings["time_budget_s"] == 0.3


def test_render_target_error_is_met():
    from lensrt.render.integrator import render
    from lensrt.render.setup import RenderOptions
    from lensrt.render.scene.load import load_scene
    scene = load_scene(None)
    win, target = (12, 28, 28, 44), 0.15
    fast = {"focus": "paraxial", "pupil_bins": 12, "device": "cpu"}  # a quick set-up: the passes are what matter
    ref = render(scene, options=RenderOptions(width=72, window=win, samples_per_pixel=2048, spp_per_pass=16, seed=999,
                                              **fast))
    y_ref, se_ref = ref.xyz[..., 1].astype(np.float64), ref.xyz_stderr[..., 1]
    lit = y_ref > 0.05 * np.percentile(y_ref[y_ref > 0], 99.0)
    k = int(lit.sum())
    bound = target * (1.0 + 1.645 * math.sqrt(2.0 / k))
    achieved, estimated = [], []
    for seed in range(8):
        r = render(scene, options=RenderOptions(width=72, window=win, spp_per_pass=8, target_rel_error=target,
                                                seed=seed, **fast))
        assert r.stop_reason == "target_error" and r.history[-1]["rel_error"] <= target
        achieved.append(_achieved(r.xyz[..., 1].astype(np.float64), y_ref, se_ref ** 2, lit))
        estimated.append(r.history[-1]["rel_error"])
    assert sum(a <= bound for a in achieved) >= 6, (achieved, bound)
    assert np.mean(achieved) == pytest.approx(np.mean(estimated), rel=0.15)


def test_bokeh_cli_and_map_targets(capsys):
    import json

    from lensrt.analysis.bokeh.entry import bokeh_map
    from lensrt.cli import main
    assert main(["bokeh", "--rays", "1e7", "--target-error", "0.15", "--pixel-um", "20", "--device", "cpu",
                 "--no-files", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)["sources"][0]
    assert s["stop_reason"] == "target_error" and s["noise_rms"] <= 0.15 and s["rays"] < 10_000_000
    assert main(["bokeh", "--map", "2x1", "--time-budget", "1", "--device", "cpu", "--no-files"]) == 2
    assert "--time-budget applies to one spot" in capsys.readouterr().err
    lens = load_lens("dgauss_50mm_f2")
    img = bokeh_map(lens, focus_lens(lens, 2000.0), grid=(2, 1), depths_mm=[10000.0], pixels=(120, 80),
                    rays=1 << 22, device="cpu", target_error=0.2)
    assert len(img.sources) == 2 and img.settings["target_error"] == 0.2
    for s in img.sources:  # maps: the Poisson estimate of each disc's noise
        assert s["stop_reason"] == "target_error" and s["noise_rms"] <= 0.2 and s["rounds"] >= 1
