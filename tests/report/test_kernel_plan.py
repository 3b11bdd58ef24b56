"""The report's kernel plan (lensrt.report.kernel_plan, lensrt.trace.preload): the Warp modules it
lists are the ones the report launches.

Oracle of the slow test: a small report on the CPU with spies on ``warp.launch`` (the modules
Warp actually loads and launches) and on the kernel choice of every trace and stream call (what
each call asks for: precision, rays, sampler, spectrum table, channels).
"""
from __future__ import annotations

import sys

import pytest

from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.report import ReportOptions
from lensrt.report.kernel_plan import report_needs, report_plan, start_preload
from lensrt.trace.preload import KernelNeed, plan_modules
from lensrt.trace.variants import GPU_MIN_RAYS


@pytest.fixture(scope="module")
def dg():
    return load_lens(None)


def test_the_cpu_plan_lists_the_generic_instances_of_the_lens_variant_only(dg):
    names = [p.name for p in report_plan(dg, ReportOptions(device="cpu", ray_fraction=1 / 64), "cpu")]
    assert len(names) == len(set(names))
    assert not any(n.endswith("_general") for n in names)  # a rotationally symmetric lens
    assert "lensrt.trace.kernels.boxes" in names
    # float64 aiming/compare and the float32 Monte Carlo streams; no float32 store kernel is launched
    assert not any("store_float32" in n for n in names)


def test_on_a_gpu_the_big_streams_plan_the_specialised_kernel_and_small_runs_the_generic_one(dg):
    full = report_needs(ReportOptions(device="cuda"))
    psf = [n for n in full if n.why.startswith("PSF map")][0]
    assert psf.rays >= GPU_MIN_RAYS  # 49 fields x 2^18 rays
    big = [p.name for p in report_plan(dg, ReportOptions(device="cuda"), "cuda:0")]
    small = [p.name for p in report_plan(dg, ReportOptions(device="cuda", ray_fraction=1 / 64), "cuda:0")]
    assert any(n.startswith("lensrt_fast_stream_float32") for n in big)
    assert "lensrt.trace.kernels.generic.stream_float32" not in big
    assert not any(n.startswith("lensrt_fast") for n in small)
    assert "lensrt.trace.kernels.generic.stream_float32" in small


def test_skipped_sections_leave_their_kernels_out(dg):
    opts = ReportOptions(device="cpu")
    assert report_needs(opts, skip=["lens", "first_order", "aberrations", "image_quality", "zoom", "psf", "mtf",
                                    "bokeh"]) == []
    f32 = [n for n in report_needs(opts, skip=["psf", "mtf", "bokeh"]) if n.precision == "float32"]
    assert f32 == []


def test_a_bad_need_is_one_clear_error_and_a_failed_plan_means_compile_on_use(dg, monkeypatch):
    with pytest.raises(LensrtError, match="unknown kernel need"):
        plan_modules(dg, "cpu", [KernelNeed("splat")])
    import lensrt.report.kernel_plan as kp

    def broken(*args, **kwargs):
        raise RuntimeError("planner bug")

    monkeypatch.setattr(kp, "report_plan", broken)
    assert start_preload(dg, ReportOptions(device="cpu"), "cpu") == ([], None)
    monkeypatch.setenv("LENSRT_COMPILE_WORKERS", "many")  # bad input: one clear error, not a silent fallback
    with pytest.raises(LensrtError, match="LENSRT_COMPILE_WORKERS"):
        start_preload(dg, ReportOptions(device="cpu"), "cpu")
    monkeypatch.setenv("LENSRT_PRELOAD", "0")
    assert start_preload(dg, ReportOptions(device="cpu"), "cpu") == ([], None)


def _spy_calls(monkeypatch) -> tuple[list[dict], set[str]]:
    """Record every trace/stream call's kernel request and every launched kernel's module."""
    import lensrt.trace.api as api
    import lensrt.trace.stream as st
    import lensrt.trace.variants as va
    wp = sys.modules["warp"]
    calls: list[dict] = []
    launched: set[str] = set()
    real_choose, real_launch = va.choose_kernel, wp.launch

    def choose(kernel, device, shape, rays, *, possible=True):
        loc = sys._getframe(1).f_locals  # the calling trace() or stream(): what it asks for
        call = {"fn": sys._getframe(1).f_code.co_name, "precision": loc["precision"], "rays": rays,
                "clip": bool(loc["clip"])}
        if call["fn"] == "stream":
            spectra = st._spectra_of(loc["lens"], loc["spectrum"], loc["sources"])
            call.update(sampler=loc["code"], histogram=bool(loc["histogram"]), channels=loc["channels"] is not None,
                        table=st._spectrum_tables(loc["lens"], spectra)[0] == st.SPECTRUM_DISCRETE)
        calls.append(call)
        return real_choose(kernel, device, shape, rays, possible=possible)

    def spy_launch(kernel, *args, **kwargs):
        launched.add(kernel.module.name)
        return real_launch(kernel, *args, **kwargs)

    monkeypatch.setattr(st, "choose_kernel", choose)
    monkeypatch.setattr(api, "choose_kernel", choose)
    monkeypatch.setattr(wp, "launch", spy_launch)
    return calls, launched


@pytest.mark.slow
def test_the_plan_is_what_a_small_report_launches(dg, tmp_path, monkeypatch):
    from lensrt.report import build_report
    from lensrt.trace.sampling import sampler_code
    opts = ReportOptions(device="cpu", ray_fraction=1 / 64)
    calls, launched = _spy_calls(monkeypatch)
    rep = build_report(dg, tmp_path, opts, quiet=True)
    assert not rep.failed
    plan = [p.name for p in report_plan(dg, opts, "cpu")]
    assert set(plan) == launched  # exactly the modules Warp loaded and launched, no more, no fewer
    assert [m["module"] for m in rep.kernel_modules] == plan
    assert all(m["error"] is None for m in rep.kernel_modules)
    # every stream call is one of the plan's needs (same precision, sampler, spectrum table, channels, and
    # the same kernel choice on a GPU at the preset's full ray counts), and every planned stream is made
    needs = [n for n in report_needs(opts) if n.kind == "stream"]
    big = lambda rays: rays / opts.ray_fraction >= GPU_MIN_RAYS  # noqa: E731 - Monte Carlo counts scale
    matched = set()
    for c in (c for c in calls if c["fn"] == "stream"):
        hits = [i for i, n in enumerate(needs)
                if (n.precision, sampler_code(n.sampler), n.table, n.channels, n.histogram, n.clip)
                == (c["precision"], c["sampler"], c["table"], c["channels"], c["histogram"], c["clip"])
                and big(n.rays) == big(c["rays"])]
        assert hits, f"a stream call the plan does not describe: {c}"
        matched.update(hits)
    assert matched == set(range(len(needs)))
    # store traces are float64 and too small for the specialised kernel on a GPU (the plan's generic one)
    stores = [c for c in calls if c["fn"] == "trace"]
    assert stores and all(c["precision"] == "float64" and c["rays"] < GPU_MIN_RAYS for c in stores)


@pytest.mark.slow
def test_a_planned_specialised_module_is_the_one_the_stream_call_launches(dg, monkeypatch):
    """The GPU plan's float32 stream module for a discrete spectrum (PSF map, MTF) is the very Warp module a
    stream call with those options launches. Run on the CPU with ``kernel="specialised"``: for float32 the GPU
    tuning is the default one, so the CPU builds the same module."""
    from lensrt.analysis.raysets import object_field_point
    from lensrt.trace.sampling import spectrum_discrete
    from lensrt.trace.specialised import DEFAULT_TUNING, GPU_TUNING
    from lensrt.trace.stream import Grid, stream, stream_sources
    assert GPU_TUNING["float32"] == DEFAULT_TUNING
    need = KernelNeed("stream", "float32", GPU_MIN_RAYS, table=True, why="PSF-like")
    (planned, util) = plan_modules(dg, "cuda:0", [need])
    assert planned.name.startswith("lensrt_fast_stream_float32")
    sources = stream_sources(dg, [object_field_point(dg, 0.0)], wavelengths_nm=[587.56], device="cpu")
    _, launched = _spy_calls(monkeypatch)  # the stream call's launches only
    res = stream(dg, sources, Grid(8, 8, 0.01), 4096, spectrum=spectrum_discrete([587.56], [1.0]), sampler="sobol",
                 batches=2, precision="float32", device="cpu", kernel="specialised")
    assert res.extra["kernel"] == "specialised"
    assert launched == {planned.name, util.name}


def test_the_psf_maps_device_analysis_is_planned_where_it_runs(dg, monkeypatch):
    from lensrt.analysis.psf import device_sums
    opts = ReportOptions(device="cpu", ray_fraction=1 / 64)
    names = lambda dev: [p.name for p in report_plan(dg, opts, dev)]  # noqa: E731
    # its two launches' kernels, each a module of its own (so they compile side by side, each once)
    passes = {device_sums._first_pass.module.name, device_sums._second_pass.module.name}
    assert len(passes) == 2
    assert passes <= set(names("cuda:0"))  # on a GPU the map's passes run there
    assert not passes & set(names("cpu"))  # on the CPU NumPy's do (the default)
    assert not passes & {p.name for p in report_plan(dg, opts, "cuda:0", skip=["psf"])}
    monkeypatch.setenv("LENSRT_PSF_ANALYSIS", "device")
    assert passes <= set(names("cpu"))


def test_with_a_thread_per_module_the_plan_compiles_the_first_sections_modules_then_the_longest_first(dg):
    from lensrt.report.kernel_plan import expected_compile_s
    for dev in ("cuda:0", "cpu"):
        opts = ReportOptions(device="cuda" if dev != "cpu" else "cpu")
        in_need_order = [p.name for p in report_plan(dg, opts, dev, workers=1)]  # fewer threads than modules
        names = [p.name for p in report_plan(dg, opts, dev, workers=len(in_need_order))]
        assert sorted(names) == sorted(in_need_order) and len(names) == len(set(names))  # the same modules
        # the plan's own order is the sections' (report_needs'), the PSF map's device analysis last
        traced = [p.name for p in plan_modules(dg, dev, report_needs(opts))]
        assert in_need_order[:len(traced)] == traced
        # the lens section's store kernel, then the first-order section's pupil boxes
        assert names[:2] == ["lensrt.trace.kernels.generic.store_float64", "lensrt.trace.kernels.boxes"]
        costs = [expected_compile_s(n) for n in names[2:]]
        assert costs == sorted(costs, reverse=True)
    gpu = [p.name for p in report_plan(dg, ReportOptions(device="cuda"), "cuda:0", workers=12)]
    assert gpu[2] == "lensrt.analysis.psf.device_sums.second_pass"  # the longest compile of the GPU plan
