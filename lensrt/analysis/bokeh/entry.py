"""Bokeh: defocused point sources through the real lens, one at a time or as a map across the frame.

Bokeh is the defocused PSF away from the plane of focus (Field Guide p. 26-27):
its outline comes from the iris blades and mechanical vignetting (cat's eyes
toward the corners), its inside from the aberrations (spherical aberration
makes one side of focus soft-edged and the other bright-rimmed), its rims from
chromatic aberration. lensrt traces it with Monte Carlo rays from an isotropic
point source over the *real* entrance pupil (the box of the vignetted pupil,
iris included) and over a spectrum, and bins them on the sensor plane in CIE
XYZ (:mod:`.light`).

Focus (unit focusing, Field Guide p. 12). The whole lens moves out by the
extension e to focus at a distance s; lensrt keeps the lens frame (first
vertex at z = 0 in the *focused* position) and moves the sensor plane back
instead: ``sensor_z = image_z(file) - e(file) + e(s)``, where e(s) is the
paraxial extension x' = f f' / x of an object at s (first-order data at the
primary wavelength) and image_z(file) the lens file's image surface (so a
designer's focus offset in the file is kept). Object distances -- the focus
distance and every source depth -- are measured from the first vertex in the
focused position (the scene stage's convention): a source at depth s_p sits
at z = -s_p. :func:`focus_lens` also takes the extension or the sensor z.

Geometry check (:func:`gaussian_blur`): the cone from the exit pupil (diameter
D_XP at z_XP) to the paraxial image z'_p of the source cuts the sensor plane
in a disc of diameter ``c = D_XP |z_S - z'_p| / |z'_p - z_XP|``. With
z'_p - z_XP = f' mp b_p (b_p = 1 + |m_p| / mp the bellows factor of the
source, p. 31) and D_XP = mp f / N this is ``c = |z_S - z'_p| / N_w`` in air:
the working f-number of the *source's* conjugate sets the cone, including the
pupil magnification. A near-perfect lens must give it within sampling error.

Images: ``BokehImage.picture()`` is upright as a photograph (the sensor image
rotated by 180 degrees, as lensrt's renders are); :meth:`BokehImage.sensor_xy`
and :meth:`BokehImage.pixel_of` are the one mapping between picture pixels and
the sensor plane (x, y in mm, +y up, centred on the axis).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Iris, Lens
from .focus import BlurPrediction, Focus, focus_lens, gaussian_blur, stop_radius_for_f_number
from .image import BokehImage, sensor_frame
from .sources import INTENSITY_SCALINGS, map_sources, nice_pitch_mm, spot_source
from .trace import Frame, pupil_boxes, stream_windows

__all__ = ["Focus", "focus_lens", "BlurPrediction", "gaussian_blur", "BokehImage", "bokeh_spot", "bokeh_map",
           "SpotPlan", "prepare_spot",
           "map_sources", "spot_source", "sensor_frame", "stop_radius_for_f_number", "Frame", "INTENSITY_SCALINGS",
           "near_far_depths_mm", "bokeh_near_far", "default_sources_per_item", "ONE_DEVICE_ITEM_SOURCES"]

#: a spot keeps per-batch XYZ histograms only while they fit in this many bytes
_BATCH_HIST_LIMIT_BYTES = 1 << 30


@dataclass
class SpotPlan:
    """One point source ready to stream: its real pupil box and footprint, the window's frame and
    the set-up (:func:`prepare_spot`; used by :func:`bokeh_spot` and the convergence study)."""

    setup: Any
    light: Any
    obj: np.ndarray
    boxes: list
    footprint: np.ndarray
    frame: Frame
    batch_noise: bool
    box_seconds: float


def prepare_spot(lens: Lens, focus: Focus, source: dict, *, light: str = "D65", intensity_cd: float = 1.0,
                 pixel_um: float | None = None, window_px: int | None = None, rays: int = 1_000_000,
                 iris: Iris | None = None, stop_radius_mm: float | None = None, sampler: str = "sobol",
                 batches: int = 32, precision: str = "float32", device: str | None = None,
                 batch_noise: bool = True) -> SpotPlan:
    """Pupil box, footprint and window of one source (see :func:`bokeh_spot` for the window rules)."""
    from .job import BokehSetup, box_wavelengths
    from .light import bokeh_light
    t0 = time.perf_counter()
    lt = bokeh_light(light, lens)
    probe = BokehSetup(lens, focus, Frame(1, 1, 1.0, 0.0, 0.0), light, intensity_cd, iris, stop_radius_mm,
                       int(rays), sampler, batches, precision, batch_noise, (128, 64))
    obj = np.array([source["object_mm"]], dtype=np.float64)
    boxes, foot = pupil_boxes(lens, obj, box_wavelengths(probe, lt), focus.sensor_z_mm, iris=iris,
                              stop_radius_mm=stop_radius_mm, device=device)
    if boxes[0].area_mm2 <= 0 or not np.all(np.isfinite(foot[0])):
        raise LensrtError("no ray from this source gets through the lens (fully vignetted)",
                          hint="move the source toward the axis")
    fx0, fx1, fy0, fy1 = foot[0]
    ext = max(fx1 - fx0, fy1 - fy0)
    pitch = nice_pitch_mm(ext, 200) if pixel_um is None else float(pixel_um) / 1000.0
    if not pitch > 0:
        raise LensrtError(f"pixel pitch {pixel_um!r} um must be positive")
    if window_px is not None:
        nx = ny = int(window_px)
    else:
        m = 0.1 * ext + 4 * pitch
        nx, ny = int(math.ceil((fx1 - fx0 + 2 * m) / pitch)), int(math.ceil((fy1 - fy0 + 2 * m) / pitch))
    if nx < 1 or ny < 1 or nx * ny > 64_000_000:
        raise LensrtError(f"a {nx} x {ny} pixel window is not usable", hint="choose a larger --pixel-um")
    cx, cy = 0.5 * (fx0 + fx1), 0.5 * (fy0 + fy1)
    frame = Frame(nx, ny, pitch, cx - 0.5 * nx * pitch, cy - 0.5 * ny * pitch)
    if batch_noise and nx * ny * 3 * 8 * (batches + 1) > _BATCH_HIST_LIMIT_BYTES:
        batch_noise = False  # per-batch histograms would not fit: the Poisson estimate instead
    setup = replace(probe, frame=frame, batch_noise=batch_noise)
    return SpotPlan(setup, lt, obj, boxes, foot, frame, batch_noise, time.perf_counter() - t0)


def bokeh_spot(lens: Lens, focus: Focus, source: dict, *, light: str = "D65", intensity_cd: float = 1.0,
               pixel_um: float | None = None, window_px: int | None = None, rays: int = 1_000_000,
               iris: Iris | None = None, stop_radius_mm: float | None = None, sampler: str = "sobol",
               seed: int = 0, batches: int = 32, precision: str = "float32", device: str | None = None,
               batch_noise: bool = True, target_error: float | None = None,
               time_budget_s: float | None = None) -> BokehImage:
    """The bokeh of one point source (``source`` from :func:`spot_source`) in a window around it.

    The window covers the traced footprint of the blur spot plus a margin; ``pixel_um``
    defaults to a 1-2-5 pitch that puts about 200 pixels across the spot; ``window_px``
    fixes a square window of that many pixels centred on the spot. The noise level is by
    batch means over the ``batches`` independent batches (``batch_noise``, while their
    histograms fit in 1 GiB), else the Poisson estimate.

    ``target_error`` (e.g. 0.02) and ``time_budget_s`` make the run progressive: rays are added
    in doubling rounds until the RMS over the disc of the per-pixel relative standard error of
    Y (``noise_rms``) is at most the target, or before the next round would overrun the budget
    (seconds of tracing); ``rays`` is the cap (:func:`lensrt.analysis.bokeh.trace.stream_windows`).
    """
    for name, v in (("target_error", target_error), ("time_budget_s", time_budget_s)):
        if v is not None and not (v > 0 and math.isfinite(v)):
            raise LensrtError(f"{name} {v!r} must be a positive number")
    t0 = time.perf_counter()
    plan = prepare_spot(lens, focus, source, light=light, intensity_cd=intensity_cd, pixel_um=pixel_um,
                        window_px=window_px, rays=rays, iris=iris, stop_radius_mm=stop_radius_mm, sampler=sampler,
                        batches=batches, precision=precision, device=device, batch_noise=batch_noise)
    frame = plan.frame
    nx, ny = frame.nx, frame.ny
    outs = stream_windows(lens, plan.obj, plan.boxes, plan.footprint, frame, focus.sensor_z_mm, plan.light,
                          int(rays), intensity_cd=intensity_cd, iris=iris, stop_radius_mm=stop_radius_mm,
                          sampler=sampler, seed=seed, batches=batches, precision=precision, device=device,
                          batch_noise=plan.batch_noise, target_error=target_error, time_budget_s=time_budget_s)
    xyz = np.zeros((3, ny, nx))
    var = np.zeros((ny, nx))
    o = outs[0]
    rec = dict(source)
    rec.update(o.stats)
    batch_xyz = None
    if o.xyz is not None:
        wy, wx = o.xyz.shape[1:]
        y1, x1 = min(o.iy0 + wy, ny), min(o.ix0 + wx, nx)
        xyz[:, o.iy0:y1, o.ix0:x1] = o.xyz[:, :y1 - o.iy0, :x1 - o.ix0]
        var[o.iy0:y1, o.ix0:x1] = o.var_y[:y1 - o.iy0, :x1 - o.ix0]
        if o.batch_xyz is not None:
            batch_xyz = np.zeros((o.batch_xyz.shape[0], 3, ny, nx), dtype=np.float32)
            batch_xyz[:, :, o.iy0:y1, o.ix0:x1] = o.batch_xyz[:, :, :y1 - o.iy0, :x1 - o.ix0]
    seconds = time.perf_counter() - t0
    settings = plan.setup.settings()
    if target_error is not None or time_budget_s is not None:
        settings.update({"target_error": target_error, "time_budget_s": time_budget_s})
    return BokehImage(xyz, var, frame, [rec], int(rec.get("rays", 0)), seconds, settings,
                      {"box_seconds": plan.box_seconds, "stream_seconds": float(rec.get("seconds", 0.0))},
                      int(seed), batch_xyz)


def bokeh_map(lens: Lens, focus: Focus, *, grid: tuple[int, int] = (15, 10), depths_mm: Sequence[float] = (1000.0,),
              sensor_mm: tuple[float, float] = (36.0, 24.0), pixels: tuple[int, int] = (1500, 1000),
              light: str = "D65", intensity_cd: float = 1.0, intensity_scaling: str = "distance2",
              rays: int = 1_000_000, iris: Iris | None = None, stop_radius_mm: float | None = None,
              sampler: str = "sobol", seed: int = 0, batches: int = 32, precision: str = "float32", executor=None,
              device: str | None = None, sources_per_item: int | None = None, progress=None,
              target_error: float | None = None) -> BokehImage:
    """A bokeh map: point sources on a ``grid`` (cols, rows) over the sensor at each depth, in one
    image of ``pixels`` on a sensor of ``sensor_mm`` (see :func:`map_sources`).

    Runs as a :class:`lensrt.parallel.Job` on ``executor`` (default: this process on
    ``device``); the image is the same for any number of devices and any ``sources_per_item``
    (default: :func:`default_sources_per_item` -- on one local device as few items as fit, elsewhere 32
    sources per item). The noise level is the
    Poisson estimate (batch histograms of a full frame would cost batches x its memory).
    ``target_error``: add rays (doubling rounds, ``rays`` the cap) until every source's RMS
    relative standard error of Y over its disc is at most this.
    """
    if target_error is not None and not (target_error > 0 and math.isfinite(target_error)):
        raise LensrtError(f"target_error {target_error!r} must be a positive number")
    from ...parallel import LocalExecutor
    from .job import BokehSetup, bokeh_job
    t0 = time.perf_counter()
    frame = sensor_frame(sensor_mm, pixels)
    place_device = device  # the placement's few small traces run in this process
    if place_device is None and isinstance(executor, LocalExecutor):
        place_device = executor.devices[0]
    sources = map_sources(lens, focus, frame, grid, depths_mm, device=place_device, intensity_cd=intensity_cd,
                          intensity_scaling=intensity_scaling)
    t_place = time.perf_counter() - t0
    setup = BokehSetup(lens, focus, frame, light, intensity_cd, iris, stop_radius_mm, int(rays), sampler,
                       batches, precision, False, target_error=target_error)
    ex = LocalExecutor(device) if executor is None else executor
    per_item = default_sources_per_item(len(sources), ex) if sources_per_item is None else sources_per_item
    job = bokeh_job(setup, sources, seed, per_item)
    result = ex.run(job, progress=progress)
    img: BokehImage = result.value
    img.seconds = time.perf_counter() - t0
    img.seed = int(seed)
    img.timing.update({"placement_seconds": t_place, "job_seconds": result.seconds,
                       "executor": result.executor, "devices": list(result.devices)})
    return img


#: most sources in one work item of a map on one local device: each item is one pupil-box search and one
#: stream call for all its sources, and the reduction holds its windows until it pastes them
ONE_DEVICE_ITEM_SOURCES = 128


def default_sources_per_item(n_sources: int, executor) -> int:
    """Sources per work item of a map: on a :class:`lensrt.parallel.LocalExecutor` of one device as few
    items as hold at most :data:`ONE_DEVICE_ITEM_SOURCES` sources each, split evenly (items there run one
    after another, and each costs its own launches and set-up); with several devices, processes or a
    cluster 32, so that every worker gets several items."""
    from ...parallel import LocalExecutor
    if isinstance(executor, LocalExecutor) and len(executor.devices) == 1:
        items = max(1, -(-int(n_sources) // ONE_DEVICE_ITEM_SOURCES))
        return max(1, -(-int(n_sources) // items))
    return 32


def near_far_depths_mm(focus_distance_mm: float, far_factor: float = 20.0) -> tuple[float, float]:
    """A near and a far source depth (mm) whose paraxial blur discs are the same size for a lens
    focused at ``focus_distance_mm``: far = ``far_factor`` x focus, near such that
    1/near - 1/s = 1/s - 1/far (the blur diameter goes with |1/s_p - 1/s| for s, s_p >> f)."""
    s = float(focus_distance_mm)
    if not (math.isfinite(s) and s > 0 and far_factor > 1):
        raise LensrtError("near/far depths need a finite focus distance and a far factor above 1")
    far = far_factor * s
    return 1.0 / (2.0 / s - 1.0 / far), far


def bokeh_near_far(lens: Lens, focus_distance_mm: float = 2000.0, *, grid: tuple[int, int] = (9, 6),
                   pixels: tuple[int, int] = (900, 600), sensor_mm: tuple[float, float] = (36.0, 24.0),
                   rays: int = 200_000, device: str | None = None, executor=None, **kw) -> BokehImage:
    """A bokeh map at a near and a far depth (:func:`near_far_depths_mm`) of ``lens`` focused at
    ``focus_distance_mm`` by unit focusing: what a report shows (foreground and background discs,
    cat's eyes toward the corners, the iris, coloured rims). Keywords go to :func:`bokeh_map`."""
    focus = focus_lens(lens, focus_distance_mm)
    return bokeh_map(lens, focus, grid=grid, depths_mm=list(near_far_depths_mm(focus_distance_mm)), pixels=pixels,
                     sensor_mm=sensor_mm, rays=rays, device=device, executor=executor, **kw)
