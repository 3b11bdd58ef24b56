"""Error against run time (``lensrt converge``): the closed-form references, the study itself, the CLI.

Oracles: the float64 reference tracer (the stigmatic lens really is stigmatic; its defocused spot's
RMS radius by quadrature over traced rays), the cos^4 law's foreshortened pupil, and a synthetic
quantity whose variance is known exactly (plain and stratified sampling of a 1-D integral). Monte
Carlo checks are z-tests or chi-square ranges with fixed seeds.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from lensrt.studies.convergence.study import Reference, converge, default_counts, repeat_seed
from lensrt.studies.convergence.quantities import (PsfRms, RelIllum, cos_pupil_ratio_applies,
                                                    stigmatic_defocus_rms_mm)
from lensrt.analysis.fields import FieldSpec
from lensrt.analysis.psf.setup import make_setup
from lensrt.cli import main
from lensrt.errors import LensrtError
from lensrt.loading import load_lens
from lensrt.stats import Estimate
from lensrt.trace.reference import trace_reference

STIG = str(Path(__file__).resolve().parents[1] / "data" / "plano_hyperbolic_f5.toml")
AXIS = FieldSpec(0.0, 0.0, "axis")


@pytest.fixture(scope="module")
def stig():
    return load_lens(STIG)


# ---- closed forms ---------------------------------------------------------------------------------

def test_plano_hyperbolic_lens_is_stigmatic(stig):
    """Every axial ray of the reference tracer crosses the axis at the paraxial focus (z = 105 mm)."""
    for h in (0.5, 3.0, 6.0, 9.9):
        r = trace_reference(stig, (0.0, h, -1.0), (0.0, 0.0, 1.0), 587.6)
        assert r.status == 0
        z_cross = r.z_mm - r.y_mm * r.N / r.M
        assert z_cross == pytest.approx(105.0, abs=1e-9)


def test_defocus_closed_form_against_reference_tracer_quadrature(stig):
    """The closed form's RMS radius equals a Gauss-Legendre quadrature over rays of the reference tracer."""
    value, why = stigmatic_defocus_rms_mm(stig, [587.6], stig.image_z_mm, AXIS)
    assert value is not None and "stigmatic" in why
    x, w = np.polynomial.legendre.leggauss(40)
    radius = 10.0
    h = 0.5 * radius * (x + 1.0)
    r = np.array([abs(trace_reference(stig, (0.0, hh, -1.0), (0.0, 0.0, 1.0), 587.6).y_mm) for hh in h])
    ms = float(np.sum(0.5 * radius * w * r * r * 2.0 * h) / radius ** 2)
    assert value == pytest.approx(math.sqrt(ms), rel=1e-12)
    # near the thin-lens estimate R dz / (f' sqrt 2), not equal to it (the sag shortens the cone)
    assert value == pytest.approx(10.0 * 2.0 / 100.0 / math.sqrt(2.0), rel=0.01) and value < 0.1414


def test_closed_forms_say_why_not(stig):
    dg = load_lens("dgauss_50mm_f2")
    v, why = stigmatic_defocus_rms_mm(dg, [587.6], dg.image_z_mm, AXIS)
    assert v is None and "curved" in why
    v, why = stigmatic_defocus_rms_mm(stig, [587.6], stig.image_z_mm, FieldSpec(0.0, 0.5, "0.5"))
    assert v is None and "off the axis" in why
    ok, why = cos_pupil_ratio_applies(dg, 0.3, 587.6, "cpu")
    assert not ok and "flat first" in why
    # the hyperboloid's clear aperture clips a 10 deg beam once it is shrunk to the stop's size
    tight = stig.replace_surface(1, semi_diameter_mm=10.0)
    ok, why = cos_pupil_ratio_applies(tight, math.radians(10.0), 587.6, "cpu")
    assert not ok and "clips" in why


def test_monte_carlo_rms_radius_agrees_with_the_closed_form(stig):
    setup = make_setup(stig, focus="image", device="cpu", rays=1 << 16, batches=16, pixels=64, ee_fractions=(),
                       mtf_freqs_cpmm=())
    q = PsfRms(setup, AXIS, "cpu")
    ref, _ = q.closed_form()
    assert ref.kind == "closed form" and ref.stderr == 0.0
    for sampler in ("random", "sobol"):
        e = q.run(1 << 17, sampler, "float64", seed=5)
        assert abs(e.value - ref.value) < 4.0 * e.stderr, sampler


def test_relative_illumination_closed_form_is_cos_theta_times_mapping(stig):
    q = RelIllum(stig, 1.0, device="cpu")
    ref, why = q.closed_form()
    assert ref is not None and "cos(theta)" in why
    theta = math.radians(10.0)
    assert ref.value == pytest.approx(math.cos(theta) * q.mapping, rel=1e-15)
    assert ref.value == pytest.approx(math.cos(theta) ** 4, rel=0.03)  # cos^4 up to the lens's distortion
    e = q.run(1 << 15, "random", "float64", seed=3)
    assert abs(e.value - ref.value) < 4.0 * e.stderr and e.samples == 2 * (1 << 15)


# ---- the study on a quantity whose variance is known ----------------------------------------------

class _Integral:
    """int_0^1 x^2 dx = 1/3 from N uniform samples in 16 batches; 'stratified' jitters each batch's
    samples over N/16 equal strata. Plain MC: var = (1/5 - 1/9) / N; stratified: O(N^-3)."""

    name, label, unit, display_unit, display_scale, sample_unit = "x2", "int x^2", "", "", 1.0, "samples"
    samplers, precisions = ("random", "stratified"), ("float64",)
    min_samples, reference_sampler, reference_precision = 32, "stratified", "float64"

    def __init__(self, closed: bool = True) -> None:
        self.closed = closed

    def run(self, samples, sampler, precision, seed):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed)
        m = samples // 16
        u = rng.random((16, m))
        if sampler == "stratified":
            u = (np.arange(m) + u) / m
        b = (u ** 2).mean(axis=1)
        return Estimate(b.mean(), b.std(ddof=1) / 4.0, 16 * m, time.perf_counter() - t0 + 1e-9 * samples,
                        "batch means over 16 batches")

    def closed_form(self):
        return (Reference(1.0 / 3.0, 0.0, 0, 0.0, "closed form", "1/3"), "exact") if self.closed else (None, "none")


def test_study_measures_slopes_honest_errors_and_the_gain_of_stratification():
    d = converge(_Integral(), [256, 1024, 4096, 16384], repeats=24, seed=1)
    assert d["reference"]["kind"] == "closed form"
    slopes = {s["sampler"]: s for s in d["slopes"]}
    assert -0.62 < slopes["random"]["error_vs_samples"] < -0.38           # N^-1/2
    assert -1.65 < slopes["stratified"]["error_vs_samples"] < -1.35       # N^-3/2 in 1-D
    assert -0.55 < slopes["random"]["stderr_vs_samples"] < -0.45
    for r in d["runs"]:
        # 24 repeats: the RMS error over the RMS reported stderr lies in sqrt(chi2_24 / 24) (99 %: 0.60 .. 1.40)
        assert 0.6 < r["error_ratio"] < 1.4, r
        assert not r["reference_limited"]
        if r["sampler"] == "random":
            assert r["rms_stderr"] == pytest.approx(math.sqrt((1 / 5 - 1 / 9) / r["samples"]), rel=0.1)
    gain = {g["sampler"]: g for g in d["gains"]}
    assert gain["random"]["variance_ratio"] == pytest.approx(1.0)
    assert gain["stratified"]["variance_ratio"] > 1000.0


def test_high_sample_reference_and_reference_limited_points():
    d = converge(_Integral(closed=False), [256, 1024], ["random"], repeats=4, seed=2, reference=2048)
    ref = d["reference"]
    assert ref["kind"] == "high-sample run" and ref["samples"] == 2048 and ref["stderr"] > 0
    assert "stratified" in ref["description"]
    d = converge(_Integral(closed=False), [256, 1024], ["stratified"], repeats=4, seed=2, reference=1024)
    assert all(r["reference_limited"] for r in d["runs"][1:])  # as many samples as the reference: limited
    with pytest.raises(LensrtError, match="no closed form"):
        converge(_Integral(closed=False), [256], repeats=1, reference="closed")
    with pytest.raises(LensrtError, match="largest count"):
        converge(_Integral(), [256, 1024], repeats=1, reference=512)


def test_counts_and_seeds():
    assert default_counts(1 << 20, 1 << 14, 7) == [1 << k for k in range(14, 21)]
    assert default_counts(1000, 1000) == [512]
    assert repeat_seed(0, 1, 2) != repeat_seed(0, 2, 1) and repeat_seed(3, 4) == repeat_seed(3, 4)


# ---- the command ----------------------------------------------------------------------------------

def test_cli_psf_rms_closed_form(tmp_path, capsys):
    assert main(["converge", STIG, "--field", "0", "--samples", "32768", "--min-samples", "8192", "--points", "3",
                 "--repeats", "3",
                 "--samplers", "random,sobol", "--device", "cpu", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "closed form" in text and "fitted log-log slopes" in text and "sobol" in text
    d = json.loads((tmp_path / "converge.json").read_text())
    assert d["quantity"] == "psf-rms" and d["counts"] == [8192, 16384, 32768] and d["repeats"] == 3
    assert {(s["sampler"], s["precision"]) for s in d["slopes"]} == {(a, b) for a in ("random", "sobol")
                                                                      for b in ("float32", "float64")}
    assert "--samples 32768" in d["command"]
    assert (tmp_path / "converge.png").stat().st_size > 10_000


@pytest.mark.parametrize("argv,key", [
    (["--quantity", "rel-illum", "dgauss_50mm_f2", "--samples", "8192", "--min-samples", "2048"], "high-sample run"),
    (["--quantity", "mtf", "dgauss_50mm_f2", "--samples", "8192", "--min-samples", "2048", "--precisions",
      "float64"], "high-sample run"),
    (["--quantity", "render", "--width", "24", "--window", "6,10,10,14", "--samples", "32", "--min-samples", "8"],
     "high-sample run"),
])
def test_cli_other_quantities(argv, key, capsys):
    assert main(["converge", *argv, "--points", "2", "--repeats", "2", "--samplers", "random,stratified",
                 "--device", "cpu", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["reference"]["kind"] == key and len(d["runs"]) == 2 * len(d["precisions"]) * 2
    for r in d["runs"]:
        assert r["samples"] > 0 and r["seconds"] > 0 and r["rms_stderr"] > 0 and len(r["values"]) == 2


def test_cli_bokeh_region(capsys):
    assert main(["converge", "--quantity", "bokeh", "--samples", "16384", "--min-samples", "8192", "--points", "2",
                 "--repeats", "2", "--samplers", "sobol", "--precisions", "float32", "--pixel-um", "20",
                 "--reference", "65536", "--device", "cpu", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["unit"] == "lux" and d["reference"]["samples"] == 65536
    assert all(r["value_mean"] > 0 and r["rms_stderr"] < r["value_mean"] for r in d["runs"])


@pytest.mark.parametrize("argv,message", [
    (["dgauss_50mm_f2", "--reference", "closed"], "no closed form"),
    (["--quantity", "render", "--precisions", "float64"], "bad --precisions"),
    (["--samplers", "halton"], "bad --samplers"),
    (["--quantity", "rel-illum", "--field", "0"], "off the axis"),
    (["--samples", "1e3"], "must satisfy"),
])
def test_cli_errors(argv, message, capsys):
    assert main(["converge", *argv, "--device", "cpu"]) == 2
    assert message in capsys.readouterr().err
