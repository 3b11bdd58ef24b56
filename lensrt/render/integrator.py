"""The render integrator: a scene through a real lens onto the sensor, as spectral irradiance.

What it does (camera paths; docs/explanation/radiometry.md has the whole story):

* per path, a point in the pixel, a wavelength (the plan's importance sampler, or the one
  wavelength of a monochromatic scene), a point in the exit-pupil box of the pixel's radius
  (pbrt-v4's table, :mod:`lensrt.render.pupil_table`), the ray traced backward through the
  lens with the forward tracer's surface code (every aperture; vignetted rays carry nothing),
  then one bounce in the scene (:func:`lensrt.render.scene.kernels.scene_radiance`: emission,
  Lambertian surfaces lit by the uniform illumination and by one power-sampled light with a
  shadow ray);
* each path's weight makes the result the sensor-plane spectral irradiance
  E = int L cos(theta) d omega over the exit pupil, in W / (m^2 nm) (W / m^2 for a line
  spectrum) averaged over the pixel and over output bands of ``band_width_nm``; the camera
  equation (Field Guide p. 33) follows from it and is tested;
* progressive: passes of ``spp_per_pass`` paths per pixel until the sample count, a time budget
  or a target relative error is reached (:class:`lensrt.stats.StopRule`), with per-pixel
  standard errors by batch means over passes;
* on a :mod:`lensrt.parallel` executor: a fixed sample count as one Job of row-band tiles, each
  rendering all its passes on its device (:func:`lensrt.render.jobs.render_tiles_job`); a time
  budget or target error as rounds of one pass per device slot (each pass decides whether to go on);
* point-source-only scenes are splatted from the light side instead (:mod:`lensrt.render.splat`).

What it does not do: no inter-reflections (one bounce), no specular or refractive scene
surfaces, no lens coatings, Fresnel losses or absorption (T = 1), no flare or ghosts, no
diffraction (the plan may ask for it; it is reported as not applied), no motion blur.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from ..stats import Estimate, StopRule, batch_means
from .passes import PassSum, RenderSetup, device_pass, prepare_setup
from .plan import plan_render
from .progressive import history_row, regions, relative_error, stop_rule
from .setup import RenderOptions, RenderResult, band_note, prepare_render, scale_pixels
from ..core.telemetry import launch

__all__ = ["render", "ProgressFn"]

#: progress callback: (passes done, passes planned, seconds so far, estimated seconds left or None)
ProgressFn = Callable[[int, int, float, "float | None"], None]
#: largest image whose error measure is recomputed after every pass without a target error
ERROR_EVERY_PASS_MAX_PIXELS = 1_000_000
#: row-band tiles per device slot (or Dask worker) of a fixed-sample-count render on an executor:
#: a few per slot, so that a slow tile does not leave the other slots idle at the end
TILES_PER_SLOT = 3



def render(scene, lens=None, options: RenderOptions = RenderOptions(), *, executor: Any = None,
           progress: ProgressFn | None = None) -> RenderResult:
    """Render ``scene`` (a loaded :class:`~lensrt.render.scene.model.Scene`) through ``lens`` (default: its own).

    ``executor``: a :mod:`lensrt.parallel` executor to spread the work over devices or workers;
    ``None`` renders in this process on ``options.device``. With a fixed sample count (no time
    budget and no target error, from ``options`` or the scene) it runs one Job of row-band tiles
    (:data:`TILES_PER_SLOT` per device slot or worker, at most one per row), each rendering every
    pass of its tile on its device: the same image bits as one device, the same per-pass paths
    through the lens, region means equal to about 1e-15 relative (summed tile by tile), and one
    ``history`` row (at the end; the progress callback follows the tiles). A time budget or target
    error needs a decision after every pass, so those run as rounds of one pass per device slot
    (each pass's whole image comes back to the host). ``result.executor_items`` says which ran.
    """
    from ..device import resolve_device
    from ..loading import load_lens
    if options.width is not None:
        scene = scale_pixels(scene, options.width)
        options = replace(options, width=None)
    lens = load_lens(scene.camera.lens_source) if lens is None else lens
    plan = plan_render(scene, lens)
    # an ExtrapolationWarning where a glass's dispersion formula is extrapolated at the render's wavelengths
    lens.check_wavelengths([plan.grid.min_nm, plan.grid.max_nm] if plan.wavelength_nm is None else [plan.wavelength_nm])
    if plan.variant.splat:
        from .splat import render_splat, splat_feasible
        ok, why = splat_feasible(scene, lens, options)
        if ok:
            return render_splat(scene, lens, plan, options, progress=progress)
        note = f"light splat not used: {why}; camera paths instead"
    else:
        note = None
    t_start = time.perf_counter()
    dev = resolve_device(options.device) if executor is None else executor.devices[0]
    setup, info = prepare_render(scene, lens, options, dev)
    n_px = setup.n_pixels
    rule = stop_rule(scene, options, n_px)
    planned = max(1, math.ceil(rule.max_samples / (n_px * setup.spp_per_pass)))
    acc = PassSum(n_px, setup.n_bands, setup.shape, setup.spp_per_pass)
    history: list[dict] = []
    pass_times: list[float] = []
    stop = None
    prep = None
    if executor is None:                 # pack lens and scene (BVH build) before the clock of the passes starts
        t0 = time.perf_counter()
        prep = prepare_setup(setup, dev)
        info["times"]["pack_scene_and_lens"] = time.perf_counter() - t0
    t_loop = time.perf_counter()
    cpu0 = time.process_time()
    items = None
    if executor is None:
        spec, stop = _render_in_process(prep, acc, rule, t_loop, n_px, history, progress, planned, pass_times)
    elif rule.time_budget_s is None and rule.target_error is None:
        acc, n_items = _render_tiles(setup, executor, t_loop, planned, progress)
        stop = _after_pass(acc, rule, t_loop, n_px, history, progress, planned, pass_times)
        spec, items = acc.spec, ("tiles", n_items)
    else:
        spec, stop = _render_with_executor(setup, executor, acc, rule, t_loop, n_px, history, progress, planned,
                                           pass_times)
        items = ("passes", acc.passes)
    seconds = time.perf_counter() - t_loop
    cpu_seconds = time.process_time() - cpu0
    if history and history[-1].get("rel_error") is None:
        history[-1]["rel_error"] = relative_error(acc)
    spp_total = acc.samples_per_pixel
    if executor is None:                 # already the mean, as float32
        irr = np.asarray(spec, dtype=np.float32).reshape(setup.shape + (setup.n_bands,))
    else:
        irr = (np.asarray(spec, dtype=np.float64) * (1.0 / spp_total)).astype(np.float32).reshape(
            setup.shape + (setup.n_bands,))
    notes = [note] if note else []
    bnote = band_note(plan, options.band_width_nm, setup.band_width_nm)
    if bnote:
        notes.append(bnote)
    if plan.variant.diffraction:
        notes.append("the plan asks for diffraction; the integrator does not apply it (geometric optics only)")
    res = RenderResult(irr, setup.band_centres_nm(), setup.band_width_nm, plan.output_unit, acc.xyz_mean(),
                       acc.xyz_stderr(), spp_total * n_px, spp_total, acc.passes, seconds, stop or "samples",
                       "camera_paths", dev if executor is None else executor.describe(), setup.camera, plan,
                       regions(acc, spp_total * n_px, seconds), history,
                       acc.hits / max(spp_total * n_px, 1),
                       {**info["times"], "total_before_passes": t_loop - t_start}, notes, setup.window)
    res.cpu_seconds = cpu_seconds
    if items is not None:
        res.executor_items, res.executor_item_count = items
    if acc.passes >= 2:
        v, se = batch_means(np.asarray(acc.pass_hits, dtype=np.float64) / (setup.spp_per_pass * n_px))
        res.through = Estimate(float(v), float(se), spp_total * n_px, seconds, f"batch means over {acc.passes} passes",
                               "")
    res.setup_seconds["pupil_pass_fraction_mean"] = float(np.mean(info["table"].pass_fraction[info["table"].areas_mm2 > 0]))
    return res


def _render_in_process(prep, acc: PassSum, rule: StopRule, t_loop: float, n_px: int,
                       history: list, progress, planned: int, pass_times: list[float]):
    """Passes on one device; spectral sums and per-pixel moments stay on the device until the end (the
    same float64 arithmetic as :class:`PassSum` on the host, so the same bits as the executor path)."""
    from ..device import warp
    from .pupil_table import launch_sliced
    wp = warp()
    setup, dev = prep.setup, prep.device
    k = prep.kernels
    n_spec = setup.n_pixels * setup.n_bands
    spec_sum = wp.zeros(n_spec, dtype=wp.float64, device=dev)
    s1 = wp.zeros((setup.n_pixels, 3), dtype=wp.float64, device=dev)
    s2 = wp.zeros((setup.n_pixels, 3), dtype=wp.float64, device=dev)
    # the per-pass error measure (error against run time) needs the moments on the host: always for a
    # target error, else for images up to a megapixel (a copy of 48 bytes per pixel per pass)
    need_err = rule.target_error is not None or setup.n_pixels <= ERROR_EVERY_PASS_MAX_PIXELS
    buf = None
    stop = None
    while stop is None:
        t0 = time.perf_counter()
        buf = device_pass(prep, acc.passes, buf)
        launch_sliced(k.accumulate, n_spec, lambda base: [buf.spec[base:], spec_sum[base:]], dev)
        launch(k.accumulate_moments, dim=setup.n_pixels, inputs=[buf.xyz, s1, s2], device=dev)
        acc.add_counts(buf.xyz.numpy()[:, 1], int(buf.hits.numpy().astype(np.int64).sum()))
        if need_err:
            acc.xyz1, acc.xyz2 = s1.numpy(), s2.numpy()
        pass_times.append(time.perf_counter() - t0)
        stop = _after_pass(acc, rule, t_loop, n_px, history, progress, planned, pass_times, need_err)
    acc.xyz1, acc.xyz2 = s1.numpy(), s2.numpy()
    # the image as float32 on the device, then one copy (the same bits as float64 sums / n on the host)
    out = wp.empty(n_spec, dtype=float, device=dev)
    launch(k.finalize, dim=n_spec, inputs=[spec_sum, wp.float64(1.0 / acc.samples_per_pixel), out], device=dev)
    return out.numpy(), stop


def _after_pass(acc: PassSum, rule: StopRule, t_loop: float, n_px: int, history: list, progress, planned: int,
                pass_times: list[float], with_error: bool = True) -> str | None:
    elapsed = time.perf_counter() - t_loop
    err = relative_error(acc) if with_error else None
    history.append(history_row(acc, n_px, elapsed, err))
    reason = rule.reason(acc.samples_per_pixel * n_px, elapsed, err, acc.passes)
    if progress is not None:
        recent = pass_times[1:] if len(pass_times) > 1 else pass_times
        per = float(np.mean(recent[-8:])) if recent else None
        left = None
        if per is not None and reason is None:
            left = per * max(planned - acc.passes, 0)
            if rule.time_budget_s is not None:
                left = min(left, max(rule.time_budget_s - elapsed, 0.0))
        progress(acc.passes, planned, elapsed, 0.0 if reason else left)
    return reason


def _executor_slots(executor) -> int:
    """Items an executor runs at once: its devices, or its workers on a Dask cluster."""
    slots = max(1, len(getattr(executor, "devices", [None])))
    if callable(getattr(executor, "n_workers", None)):
        slots = max(slots, int(executor.n_workers()))
    return slots


def _render_tiles(setup: RenderSetup, executor, t_loop: float, planned: int, progress) -> tuple[PassSum, int]:
    """All ``planned`` passes as one Job of row-band tiles (:func:`lensrt.render.jobs.render_tiles_job`): the
    reduced :class:`PassSum` (spectral sums, moments, per-pass hits and region means) and the tile count."""
    from ..parallel.local import LocalExecutor
    from .jobs import render_tiles_job
    # in-place tile writes pay off where results cross a process boundary; in one process (device threads) the
    # returned sums are faster (4 x H200, benchmarks/results/bench_multigpu_render_h200x4_stop30.txt)
    job = render_tiles_job(setup, planned, TILES_PER_SLOT * _executor_slots(executor),
                           in_place=not isinstance(executor, LocalExecutor))
    n = len(job.items)

    def tiles_done(done: int, total: int) -> None:
        # passes are not done one by one here: report the fraction of tiles in as passes (the end is
        # reported by the caller, with the history row)
        if progress is not None and 0 < done < total:
            elapsed = time.perf_counter() - t_loop
            progress(planned * done // total, planned, elapsed, elapsed * (total - done) / done)

    return executor.run(job, progress=tiles_done).value.pass_sum, n


def _render_with_executor(setup: RenderSetup, executor, acc: PassSum, rule: StopRule, t_loop: float, n_px: int,
                          history: list, progress, planned: int, pass_times: list[float]):
    """Rounds of one pass per device slot (or Dask worker) as :mod:`lensrt.parallel` Jobs, reduced in pass order."""
    from ..parallel import Job, make_items
    from .passes import run_pass_item
    slots = _executor_slots(executor)
    stop = None
    while stop is None:
        first = acc.passes
        left = max(1, math.ceil(rule.max_samples / (n_px * setup.spp_per_pass)) - first)
        n = min(slots, left)
        job = Job(make_items(range(first, first + n), setup.seed), run_pass_item, list, context=setup,
                  prepare=prepare_setup, name="render-passes")
        t0 = time.perf_counter()
        results = executor.run(job).value
        dt = (time.perf_counter() - t0) / n
        for r in results:
            acc.add(r.xyz, r.hits, r.spec)
            pass_times.append(dt)
            stop = _after_pass(acc, rule, t_loop, n_px, history, progress, planned, pass_times)
            if stop is not None:
                break
    return acc.spec, stop
