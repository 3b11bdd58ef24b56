"""The render integrator: a scene through a real lens onto the sensor, as spectral irradiance.

What it does (camera paths; README "Rendering" has the whole story):

* per path, a point in the pixel, a wavelength (the plan's importance sampler, or the one
  wavelength of a monochromatic scene), a point in the exit-pupil box of the pixel's radius
  (pbrt-v4's table, :mod:`lensrt.render.pupil_table`), the ray traced backward through the
  lens with the forward tracer's surface code (every aperture; vignetted rays carry nothing),
  then one bounce in the scene (:func:`lensrt.render.scene_kernels.scene_radiance`: emission,
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
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..errors import LensrtError
from ..stats import Estimate, StopRule, batch_means
from .camera import Camera, setup_camera
from .passes import REGIONS, PassSum, RenderSetup, device_pass, prepare_setup
from .plan import Plan, plan_render

__all__ = ["RenderOptions", "RenderResult", "render", "prepare_render", "scale_pixels",
           "ProgressFn"]

#: progress callback: (passes done, passes planned, seconds so far, estimated seconds left or None)
ProgressFn = Callable[[int, int, float, "float | None"], None]
#: most samples per pixel a render started with a time budget or target error but no count may take
MAX_SPP_OPEN = 65536
#: largest image whose error measure is recomputed after every pass without a target error
ERROR_EVERY_PASS_MAX_PIXELS = 1_000_000
#: row-band tiles per device slot (or Dask worker) of a fixed-sample-count render on an executor:
#: a few per slot, so that a slow tile does not leave the other slots idle at the end
TILES_PER_SLOT = 3


@dataclass(frozen=True)
class RenderOptions:
    """How to render (``None`` = the scene file's value).

    ``spp_per_pass``: paths per pixel per pass (default: samples / 8, at least 1, so that the
    standard errors rest on about 8 or more passes). ``band_width_nm``: width of the output
    spectral bands (a multiple of the scene grid step). ``focus``: ``best`` or ``paraxial``.
    ``device``: one Warp device for an in-process render. ``width``: render this many
    columns instead of the scene's (rows follow the aspect ratio; pixels grow accordingly).
    ``window``: render only the pixels (row0, row1, col0, col1) (half-open) of the sensor.
    """

    samples_per_pixel: int | None = None
    spp_per_pass: int | None = None
    seed: int | None = None
    time_budget_s: float | None = None
    target_rel_error: float | None = None
    band_width_nm: float = 10.0
    focus: str = "best"
    device: str | None = None
    width: int | None = None
    pupil_bins: int = 48
    window: tuple[int, int, int, int] | None = None

    def __post_init__(self) -> None:
        if not (self.band_width_nm > 0 and math.isfinite(self.band_width_nm)):
            raise LensrtError(f"band width {self.band_width_nm!r} nm must be a positive number",
                              hint="e.g. 10 (a multiple of the scene's wavelength step)")


@dataclass
class RenderResult:
    """A rendered image and how it was made (every Monte Carlo number with samples, stderr, seconds).

    ``irradiance``: (rows, cols, bands) float32, sensor-plane spectral irradiance averaged over
    each pixel and band, ``unit``; ``wavelength_nm``: band centres; ``xyz``: (rows, cols, 3) CIE
    XYZ of the irradiance with Y the illuminance in lux (K_m int E y-bar d lambda); ``xyz_stderr``
    its per-pixel standard error (batch means over passes). Images are upright
    (:class:`lensrt.render.camera.SensorGrid`).
    """

    irradiance: np.ndarray
    wavelength_nm: np.ndarray
    band_width_nm: float
    unit: str
    xyz: np.ndarray
    xyz_stderr: np.ndarray
    samples: int
    samples_per_pixel: int
    passes: int
    seconds: float
    stop_reason: str
    mode: str
    device: str
    camera: Camera
    plan: Plan
    regions: dict[str, Estimate] = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)
    through_fraction: float = float("nan")
    setup_seconds: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    window: tuple[int, int, int, int] | None = None
    #: CPU time of this process (all threads) during the passes: on a shared machine, paths per CPU
    #: second measure the code when wall-clock seconds measure the neighbours too
    cpu_seconds: float = float("nan")
    #: ``through_fraction`` with its standard error (batch means over passes; None with one pass)
    through: Estimate | None = None
    #: the work items on an executor: "tiles" (row bands, each with every pass) or "passes" (rounds of one
    #: pass per device slot); None in this process
    executor_items: str | None = None
    #: how many items (tiles, or passes) the executor ran
    executor_item_count: int = 0

    def position_of(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """Sensor-plane (x_mm, y_mm) of (row, col) of this image (the camera's one map, shifted by the window)."""
        r0, c0 = (self.window[0], self.window[2]) if self.window else (0, 0)
        return self.camera.sensor.position_of(np.asarray(row) + r0, np.asarray(col) + c0)

    def pixel_of(self, x_mm, y_mm) -> tuple[np.ndarray, np.ndarray]:
        """Continuous (row, col) of this image at sensor-plane points (inverse of :meth:`position_of`)."""
        r, c = self.camera.sensor.pixel_of(x_mm, y_mm)
        r0, c0 = (self.window[0], self.window[2]) if self.window else (0, 0)
        return r - r0, c - c0

    @property
    def shape(self) -> tuple[int, int]:
        return self.irradiance.shape[:2]

    @property
    def samples_per_second(self) -> float:
        return self.samples / self.seconds if self.seconds > 0 else math.inf

    def estimate(self) -> Estimate:
        """The XYZ image as an :class:`Estimate` (per-pixel values and standard errors)."""
        return Estimate(self.xyz, self.xyz_stderr, self.samples, self.seconds,
                        f"batch means over {self.passes} passes", "XYZ, Y in lux")

    def summary(self) -> dict:
        """JSON-ready description (not the images)."""
        return {"scene": self.plan.scene_name, "mode": self.mode, "device": self.device,
                "pixels": [int(self.shape[1]), int(self.shape[0])], "samples": int(self.samples),
                "samples_per_pixel": int(self.samples_per_pixel), "passes": int(self.passes),
                "seconds": float(self.seconds), "samples_per_second": float(self.samples_per_second),
                "cpu_seconds": float(self.cpu_seconds),
                "stop_reason": self.stop_reason, "unit": self.unit, "band_width_nm": self.band_width_nm,
                "bands": int(self.irradiance.shape[2]), "through_lens_fraction": float(self.through_fraction),
                "through_lens": self.through.to_dict() if self.through is not None else None,
                "regions_Y_lux": {k: v.to_dict() for k, v in self.regions.items()},
                "history": self.history, "setup_seconds": self.setup_seconds, "notes": self.notes,
                "executor_items": self.executor_items, "executor_item_count": int(self.executor_item_count),
                "camera": self.camera.to_dict(), "plan": self.plan.to_dict()}


def scale_pixels(scene, width: int):
    """``scene`` with its sensor resampled to ``width`` columns (rows keep the aspect ratio)."""
    if width < 1 or width > 65536:
        raise LensrtError(f"image width {width} must be 1-65536 pixels")
    s = scene.sensor
    rows = max(1, round(width * s.height_mm / s.width_mm))
    return replace(scene, sensor=replace(s, pixels_x=int(width), pixels_y=int(rows)))


def _bands(plan: Plan, band_width_nm: float) -> tuple[float, float, int]:
    """(first band edge, width, count) of the output bands: the asked width rounded to a whole number
    of the scene's wavelength steps; the step itself when that does not split the spectrum evenly
    (:func:`band_note` says so)."""
    if not plan.spectral:
        return float(plan.wavelength_nm), 1.0, 1
    g = plan.grid
    span = g.max_nm - g.min_nm
    k = max(1, round(band_width_nm / g.step_nm))
    bw = k * g.step_nm
    n = int(round(span / bw))
    if abs(n * bw - span) > 1e-6 * span or n < 1:
        bw, n = g.step_nm, int(round(span / g.step_nm))
    return float(g.min_nm), float(bw), n


def band_note(plan: Plan, band_width_nm: float, used_nm: float) -> str | None:
    """A note for the result when the output bands are not the width asked for (None when they are)."""
    if not plan.spectral or abs(used_nm - band_width_nm) <= 1e-9 * band_width_nm:
        return None
    g = plan.grid
    return (f"output bands are {used_nm:g} nm wide, not the {band_width_nm:g} nm asked for: bands are whole "
            f"numbers of the scene's {g.step_nm:g} nm steps that split {g.min_nm:g}-{g.max_nm:g} nm evenly")


def _wavelength_cdf(scene, plan: Plan) -> np.ndarray:
    from .plan import wavelength_weight
    from .spectra import WavelengthSampler
    if not plan.spectral:
        return np.array([0.0, 1.0])
    g = plan.grid
    response = None
    if plan.wavelength_sampling.endswith("camera"):
        from ..sensor import get_preset
        response = get_preset(plan.sensor_preset).qe(g.nm).T
    w = wavelength_weight(scene, plan.wavelength_sampling, response)
    sampler = WavelengthSampler.uniform(g) if w is None else WavelengthSampler.from_weight(g, w)
    return np.asarray(sampler.cdf, dtype=np.float64)


def prepare_render(scene, lens=None, options: RenderOptions = RenderOptions(), device: str | None = None
                   ) -> tuple[RenderSetup, dict]:
    """Plan, camera and exit-pupil table of a camera-path render: the :class:`RenderSetup` and set-up seconds."""
    from ..device import resolve_device
    from ..loading import load_lens
    from ..trace.pack import pack_lens
    from ..trace.reverse import reversed_lens
    from .pupil_table import circular_iris, exit_pupil_table, table_wavelengths
    t = {}
    t0 = time.perf_counter()
    if options.width is not None:
        scene = scale_pixels(scene, options.width)
    lens = load_lens(scene.camera.lens_source) if lens is None else lens
    plan = plan_render(scene, lens)
    # an ExtrapolationWarning where a glass's dispersion formula is extrapolated at the render's wavelengths
    lens.check_wavelengths([plan.grid.min_nm, plan.grid.max_nm] if plan.wavelength_nm is None else [plan.wavelength_nm])
    t["plan"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cam = setup_camera(scene, lens, options.focus)
    lens = cam.lens  # a declared focus group / floating groups moved to focus (render.camera)
    t["camera"] = time.perf_counter() - t0
    dev = resolve_device(device if device is not None else options.device)
    t0 = time.perf_counter()
    rev = pack_lens(reversed_lens(lens, 0.0), "float32", dev, iris=circular_iris(lens), stop_radius_mm=cam.stop_radius_mm)
    table = exit_pupil_table(cam, rev, table_wavelengths(plan), n_bins=options.pupil_bins, device=dev)
    t["exit_pupil_table"] = time.perf_counter() - t0
    spp = options.samples_per_pixel or scene.render.samples_per_pixel
    spp_pass = options.spp_per_pass or max(1, spp // 8)
    band0, bw, nb = _bands(plan, options.band_width_nm)
    seed = scene.render.seed if options.seed is None else int(options.seed)
    window = _check_window(options.window, cam.sensor.shape)
    setup = RenderSetup(scene, cam, plan, table.boxes, table.inv_dr, _wavelength_cdf(scene, plan), band0, bw, nb,
                        int(spp_pass), int(seed), window)
    return setup, {"times": t, "table": table}


def _check_window(window, shape: tuple[int, int]) -> tuple[int, int, int, int] | None:
    if window is None:
        return None
    r0, r1, c0, c1 = (int(v) for v in window)
    if not (0 <= r0 < r1 <= shape[0] and 0 <= c0 < c1 <= shape[1]):
        raise LensrtError(f"window {window} is not inside the {shape[1]} x {shape[0]} px sensor",
                          hint="give row0 < row1 <= rows and col0 < col1 <= columns")
    return (r0, r1, c0, c1)


def _stop_rule(scene, options: RenderOptions, n_pixels: int) -> StopRule:
    budget = options.time_budget_s if options.time_budget_s is not None else scene.render.time_budget_s
    target = options.target_rel_error if options.target_rel_error is not None else scene.render.target_rel_error
    spp = options.samples_per_pixel
    if spp is None:
        spp = MAX_SPP_OPEN if (options.time_budget_s or options.target_rel_error) else scene.render.samples_per_pixel
    return StopRule(max_samples=int(spp) * n_pixels, target_error=target, time_budget_s=budget, relative=True,
                    min_batches=4)


def relative_error(acc: PassSum) -> float | None:
    """The render's error measure: RMS over lit pixels of the relative standard error of Y.

    Lit pixels: Y above 5 % of the 99th percentile of Y over the pixels that received light.
    ``None`` before two passes or when no pixel received light.
    """
    if acc.passes < 2:
        return None
    y = acc.xyz_mean()[..., 1]
    se = acc.xyz_stderr()[..., 1]
    pos = y[y > 0]
    if pos.size == 0:
        return None
    lit = y > 0.05 * float(np.percentile(pos, 99))
    return float(np.sqrt(np.mean((se[lit] / y[lit]) ** 2)))


def _regions(acc: PassSum, samples: int, seconds: float) -> dict[str, Estimate]:
    out = {}
    if acc.passes < 2:
        return out
    means = np.asarray(acc.region_means)
    for k, (name, *_rest) in enumerate(REGIONS):
        v, se = batch_means(means[:, k])
        out[name] = Estimate(float(v), float(se), samples, seconds, f"batch means over {acc.passes} passes", "lux")
    return out


def _history_row(acc: PassSum, n_pixels: int, seconds: float, err: float | None) -> dict:
    row = {"passes": acc.passes, "samples_per_pixel": acc.samples_per_pixel, "samples": acc.samples_per_pixel * n_pixels,
           "seconds": seconds, "rel_error": err}
    if acc.passes >= 2:
        means = np.asarray(acc.region_means)
        for k, (name, *_rest) in enumerate(REGIONS):
            v, se = batch_means(means[:, k])
            row[f"Y_{name.replace(' ', '_')}"] = [float(v), float(se)]
    return row


def render(scene, lens=None, options: RenderOptions = RenderOptions(), *, executor: Any = None,
           progress: ProgressFn | None = None) -> RenderResult:
    """Render ``scene`` (a loaded :class:`~lensrt.render.scene_model.Scene`) through ``lens`` (default: its own).

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
    rule = _stop_rule(scene, options, n_px)
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
                       _regions(acc, spp_total * n_px, seconds), history,
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
        wp.launch(k.accumulate_moments, dim=setup.n_pixels, inputs=[buf.xyz, s1, s2], device=dev)
        acc.add_counts(buf.xyz.numpy()[:, 1], int(buf.hits.numpy().astype(np.int64).sum()))
        if need_err:
            acc.xyz1, acc.xyz2 = s1.numpy(), s2.numpy()
        pass_times.append(time.perf_counter() - t0)
        stop = _after_pass(acc, rule, t_loop, n_px, history, progress, planned, pass_times, need_err)
    acc.xyz1, acc.xyz2 = s1.numpy(), s2.numpy()
    # the image as float32 on the device, then one copy (the same bits as float64 sums / n on the host)
    out = wp.empty(n_spec, dtype=float, device=dev)
    wp.launch(k.finalize, dim=n_spec, inputs=[spec_sum, wp.float64(1.0 / acc.samples_per_pixel), out], device=dev)
    return out.numpy(), stop


def _after_pass(acc: PassSum, rule: StopRule, t_loop: float, n_px: int, history: list, progress, planned: int,
                pass_times: list[float], with_error: bool = True) -> str | None:
    elapsed = time.perf_counter() - t_loop
    err = relative_error(acc) if with_error else None
    history.append(_history_row(acc, n_px, elapsed, err))
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
    from .jobs import render_tiles_job
    job = render_tiles_job(setup, planned, TILES_PER_SLOT * _executor_slots(executor))
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
