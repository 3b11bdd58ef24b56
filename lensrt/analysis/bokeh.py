"""Bokeh: defocused point sources through the real lens, one at a time or as a map across the frame.

Bokeh is the defocused PSF away from the plane of focus (Field Guide p. 26-27):
its outline comes from the iris blades and mechanical vignetting (cat's eyes
toward the corners), its inside from the aberrations (spherical aberration
makes one side of focus soft-edged and the other bright-rimmed), its rims from
chromatic aberration. lensrt traces it with Monte Carlo rays from an isotropic
point source over the *real* entrance pupil (the box of the vignetted pupil,
iris included) and over a spectrum, and bins them on the sensor plane in CIE
XYZ (:mod:`.bokeh_spectrum`).

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
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Iris, Lens
from ..units import MM_PER_M
from .bokeh_focus import BlurPrediction, Focus, focus_lens, gaussian_blur, stop_radius_for_f_number
from .bokeh_trace import Frame, object_heights_for_image, pupil_boxes, stream_windows

__all__ = ["Focus", "focus_lens", "BlurPrediction", "gaussian_blur", "BokehImage", "bokeh_spot", "bokeh_map",
           "SpotPlan", "prepare_spot",
           "map_sources", "spot_source", "sensor_frame", "stop_radius_for_f_number", "Frame", "INTENSITY_SCALINGS",
           "near_far_depths_mm", "bokeh_near_far"]

#: a spot keeps per-batch XYZ histograms only while they fit in this many bytes
_BATCH_HIST_LIMIT_BYTES = 1 << 30
#: how a map's sources' luminous intensities depend on their depth (see :func:`map_sources`)
INTENSITY_SCALINGS = ("distance2", "none")


# ---- the image -----------------------------------------------------------------------------

@dataclass
class BokehImage:
    """A bokeh image: CIE XYZ on a pixel grid of the sensor plane, with its error, rays and time.

    Attributes
    ----------
    sensor_xyz : ndarray (3, ny, nx)
        X, Y, Z in lux (Y = illuminance on the sensor) in *sensor orientation* (row 0 at the
        lowest y, column 0 at the lowest x); :meth:`picture` gives the upright picture.
    var_y : ndarray (ny, nx)
        Variance of Y per pixel (lux^2), by each source's noise method.
    frame : Frame
        Pixel grid on the sensor plane.
    sources : list of dict
        Per source: where it is (``object_mm``, ``depth_mm``, ``target_mm`` ...), pupil box and
        transmission with standard errors, centroid and RMS radius with standard errors, rays,
        the noise level in its disc and how it was estimated.
    rays, seconds : int, float
        Rays traced (all sources) and wall-clock seconds.
    settings : dict
        Lens, focus, light, iris, sampler, precision, pixel pitch (the metadata of the files).
    timing : dict
        Seconds spent on placement, pupil boxes and items.
    seed : int
    batch_xyz : ndarray (batches, 3, ny, nx) or None
        XYZ of each independent batch, each scaled to estimate the whole image (spots with
        batch noise only; sensor orientation): for jackknife errors of derived quantities.
    """

    sensor_xyz: np.ndarray
    var_y: np.ndarray
    frame: Frame
    sources: list
    rays: int
    seconds: float
    settings: dict
    timing: dict = field(default_factory=dict)
    seed: int = 0
    batch_xyz: np.ndarray | None = None

    # -- the one mapping between picture pixels and the sensor plane ---------------------------
    def picture(self) -> np.ndarray:
        """(rows, cols, 3) XYZ (lux), upright as a photograph: the sensor image turned by 180 deg."""
        return np.moveaxis(self.sensor_xyz[:, :, ::-1], 0, -1)

    def picture_rel_stderr(self) -> np.ndarray:
        """(rows, cols) relative standard error of Y per pixel (0 where Y = 0), upright."""
        y = self.sensor_xyz[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(y > 0, np.sqrt(np.maximum(self.var_y, 0.0)) / np.where(y > 0, y, 1.0), 0.0)
        return rel[:, ::-1]

    def picture_batches(self) -> np.ndarray | None:
        """(batches, rows, cols, 3) XYZ of each batch, upright (None unless kept)."""
        return None if self.batch_xyz is None else np.moveaxis(self.batch_xyz[:, :, :, ::-1], 1, -1)

    def sensor_xy(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """Sensor-plane (x, y) in mm of continuous picture coordinates (pixel centres at integers)."""
        f = self.frame
        x = f.x0_mm + (f.nx - 0.5 - np.asarray(col, dtype=np.float64)) * f.pitch_mm
        y = f.y0_mm + (np.asarray(row, dtype=np.float64) + 0.5) * f.pitch_mm
        return x, y

    def pixel_of(self, x_mm, y_mm) -> tuple[np.ndarray, np.ndarray]:
        """Continuous picture (row, col) of sensor-plane points (mm); inverse of :meth:`sensor_xy`."""
        f = self.frame
        col = f.nx - 0.5 - (np.asarray(x_mm, dtype=np.float64) - f.x0_mm) / f.pitch_mm
        row = (np.asarray(y_mm, dtype=np.float64) - f.y0_mm) / f.pitch_mm - 0.5
        return row, col

    # -- summaries -----------------------------------------------------------------------------
    @property
    def noise(self) -> dict:
        """Per-pixel relative standard error of Y in the discs: median over sources of each
        source's median over its disc pixels, the largest source value, the largest RMS over a
        disc (what a target error is compared with), and the method."""
        vals = [r["noise"] for r in self.sources if r.get("reached_sensor") and math.isfinite(r.get("noise", math.nan))]
        rms = [r["noise_rms"] for r in self.sources
               if r.get("reached_sensor") and math.isfinite(r.get("noise_rms", math.nan))]
        methods = sorted({r["noise_method"] for r in self.sources if r.get("reached_sensor")})
        return {"rel_stderr_median": float(np.median(vals)) if vals else None,
                "rel_stderr_max": float(np.max(vals)) if vals else None,
                "rel_stderr_rms_max": float(np.max(rms)) if rms else None,
                "method": "; ".join(methods) + (f"; disc = pixels >= 10 % of the source's 99th-percentile Y"
                                                if methods else "")}

    def digest(self) -> str:
        """SHA-256 (hex, 16 digits) of what the image holds -- pixels, variances and per-source results,
        not the timings: equal digests mean bit-identical images (benchmarks/bench_multigpu.py)."""
        import hashlib
        import json
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.sensor_xyz).tobytes())
        h.update(np.ascontiguousarray(self.var_y).tobytes())
        recs = [{k: v for k, v in r.items() if k != "seconds"} for r in self.sources]
        h.update(json.dumps(recs, sort_keys=True, default=str).encode())
        return h.hexdigest()[:16]

    def to_dict(self) -> dict:
        """JSON-ready summary (arrays go to EXR/PNG files)."""
        f = self.frame
        reached = sum(1 for r in self.sources if r.get("reached_sensor"))
        return {"settings": self.settings, "rays": int(self.rays), "seconds": float(self.seconds),
                "rays_per_second": self.rays / self.seconds if self.seconds > 0 else None, "seed": self.seed,
                "noise": self.noise, "n_sources": len(self.sources), "n_sources_on_sensor": reached,
                "frame": {"pixels": [f.nx, f.ny], "pitch_um": f.pitch_mm * 1000.0,
                          "sensor_x_mm": [f.x0_mm, f.x0_mm + f.nx * f.pitch_mm],
                          "sensor_y_mm": [f.y0_mm, f.y0_mm + f.ny * f.pitch_mm],
                          "orientation": "picture upright (sensor image turned by 180 deg)"},
                "timing": self.timing, "sources": self.sources}


# ---- sources ---------------------------------------------------------------------------------

def sensor_frame(size_mm: tuple[float, float], pixels: tuple[int, int]) -> Frame:
    """The frame of a sensor ``size_mm`` (width, height) with ``pixels`` (nx, ny), square pixels,
    centred on the axis."""
    w, h = (float(v) for v in size_mm)
    nx, ny = (int(v) for v in pixels)
    if nx < 1 or ny < 1 or not (w > 0 and h > 0):
        raise LensrtError(f"a sensor needs a positive size and pixel counts, not {w:g} x {h:g} mm at {nx} x {ny}")
    p = w / nx
    if abs(ny * p - h) > 0.01 * h + 0.5 * p:
        raise LensrtError(f"{nx} x {ny} pixels on {w:g} x {h:g} mm are not square",
                          hint=f"use {nx} x {max(1, round(h / p))} pixels")
    return Frame(nx, ny, p, -0.5 * w, -0.5 * ny * p)


def map_sources(lens: Lens, focus: Focus, frame: Frame, grid: tuple[int, int], depths_mm: Sequence[float],
                wavelength_nm: float | None = None, device: str | None = None, intensity_cd: float = 1.0,
                intensity_scaling: str = "distance2") -> list[dict]:
    """Point sources on a grid over the frame at each depth, placed by the real chief ray.

    The picture is divided into ``grid`` = (cols, rows) cells; each cell holds one source per
    depth side by side (left to right in the order of ``depths_mm``), at the cell's vertical
    centre. Each source's object point at its depth is the one whose real chief ray (primary
    wavelength, through the centre of the real stop) meets the sensor at its grid position,
    so the grid is uniform on the sensor whatever the distortion. Sources whose chief ray
    cannot be found are left out with a warning.

    ``intensity_scaling``: ``"distance2"`` (default) gives a source at depth d the luminous
    intensity ``intensity_cd * (d / 1 m)^2`` -- as bright as ``intensity_cd`` at 1 m, so discs of
    every depth show in one exposure, as street lights of similar apparent brightness do;
    ``"none"``: every source has ``intensity_cd``.
    """
    if intensity_scaling not in INTENSITY_SCALINGS:
        raise LensrtError(f"unknown intensity scaling {intensity_scaling!r}",
                          hint=f"use one of {', '.join(INTENSITY_SCALINGS)}")
    import warnings
    cols, rows = (int(v) for v in grid)
    if cols < 1 or rows < 1:
        raise LensrtError(f"a bokeh map needs at least one column and row, not {cols} x {rows}")
    depths = [float(d) for d in depths_mm]
    if not depths or any(not (d > 0) for d in depths):
        raise LensrtError("source depths must be positive distances in front of the lens (mm)")
    nd = len(depths)
    w, h = frame.nx * frame.pitch_mm, frame.ny * frame.pitch_mm
    specs = []
    for r in range(rows):
        for c in range(cols):
            for j, d in enumerate(depths):
                u = (c + (j + 0.5) / nd) / cols  # picture x fraction (left to right)
                v = (r + 0.5) / rows  # picture y fraction (top to bottom)
                inten = intensity_cd * ((d / MM_PER_M) ** 2 if intensity_scaling == "distance2" else 1.0)
                specs.append({"kind": "map", "row": r, "col": c, "depth_index": j, "depth_mm": d,
                              "target_mm": [frame.x0_mm + w * (1.0 - u), frame.y0_mm + h * v],
                              "intensity_cd": inten})
    tx = np.array([s["target_mm"][0] for s in specs])
    ty = np.array([s["target_mm"][1] for s in specs])
    dep = np.array([s["depth_mm"] for s in specs])
    wl = focus.wavelength_nm if wavelength_nm is None else float(wavelength_nm)
    rad = np.hypot(tx, ty)
    y_obj, ok = object_heights_for_image(lens, dep, focus.sensor_z_mm, rad, wl, device)
    out = []
    for k, s in enumerate(specs):
        if not ok[k]:
            continue
        ux, uy = (tx[k] / rad[k], ty[k] / rad[k]) if rad[k] > 0 else (0.0, 1.0)
        s["object_mm"] = [float(ux * y_obj[k]), float(uy * y_obj[k]), -float(dep[k])]
        out.append(s)
    if len(out) < len(specs):
        warnings.warn(f"{len(specs) - len(out)} of {len(specs)} map sources have no real chief ray to their "
                      "sensor position and are left out")
    return out


def spot_source(lens: Lens, focus: Focus, depth_mm: float, *, field_deg: tuple[float, float] | None = None,
                object_mm: tuple[float, float] | None = None, image_mm: tuple[float, float] | None = None,
                device: str | None = None) -> dict:
    """One source at ``depth_mm`` in front of the first vertex, placed by at most one of:

    ``field_deg`` (x, y): seen from the paraxial entrance pupil at these angles (a positive
    angle puts the object below the axis and its image above, as lens files' fields do);
    ``object_mm`` (x, y): the object point's lateral position; ``image_mm`` (x, y): where its
    real chief ray meets the sensor. Default: on the axis.
    """
    from ..paraxial import first_order
    d = float(depth_mm)
    if not (d > 0 and math.isfinite(d)):
        raise LensrtError(f"source distance {depth_mm!r} mm must be a finite positive distance")
    given = [v for v in (field_deg, object_mm, image_mm) if v is not None]
    if len(given) > 1:
        raise LensrtError("place the source by one of: a field angle, an object position or an image position")
    src: dict[str, Any] = {"kind": "spot", "depth_mm": d, "depth_index": 0}
    if field_deg is not None:
        z_ep = first_order(lens, focus.wavelength_nm).entrance_pupil_z_mm
        tx, ty = (math.tan(math.radians(float(a))) for a in field_deg)
        src["field_deg"] = [float(a) for a in field_deg]
        src["object_mm"] = [-(d + z_ep) * tx, -(d + z_ep) * ty, -d]
    elif image_mm is not None:
        x, y = (float(v) for v in image_mm)
        r = math.hypot(x, y)
        yo, ok = object_heights_for_image(lens, d, focus.sensor_z_mm, r, focus.wavelength_nm, device)
        if not ok[0]:
            raise LensrtError(f"no real chief ray from {d:g} mm reaches the sensor at ({x:g}, {y:g}) mm")
        ux, uy = (x / r, y / r) if r > 0 else (0.0, 1.0)
        src["target_mm"] = [x, y]
        src["object_mm"] = [ux * float(yo[0]), uy * float(yo[0]), -d]
    else:
        x, y = (0.0, 0.0) if object_mm is None else (float(v) for v in object_mm)
        src["object_mm"] = [x, y, -d]
    return src


# ---- the two entry points ------------------------------------------------------------------

def _nice_pitch_mm(extent_mm: float, n: int) -> float:
    """A pitch of 1, 2 or 5 x 10^k um near extent / n."""
    raw = max(extent_mm / n, 1e-5) * 1000.0
    k = math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10 ** k >= raw:
            return m * 10 ** k / 1000.0
    return 10 ** (k + 1) / 1000.0  # pragma: no cover


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
    from .bokeh_job import BokehSetup, box_wavelengths
    from .bokeh_spectrum import bokeh_light
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
    pitch = _nice_pitch_mm(ext, 200) if pixel_um is None else float(pixel_um) / 1000.0
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
    (seconds of tracing); ``rays`` is the cap (:func:`lensrt.analysis.bokeh_trace.stream_windows`).
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
              device: str | None = None, sources_per_item: int = 32, progress=None,
              target_error: float | None = None) -> BokehImage:
    """A bokeh map: point sources on a ``grid`` (cols, rows) over the sensor at each depth, in one
    image of ``pixels`` on a sensor of ``sensor_mm`` (see :func:`map_sources`).

    Runs as a :class:`lensrt.parallel.Job` on ``executor`` (default: this process on
    ``device``); the image is the same for any number of devices. The noise level is the
    Poisson estimate (batch histograms of a full frame would cost batches x its memory).
    ``target_error``: add rays (doubling rounds, ``rays`` the cap) until every source's RMS
    relative standard error of Y over its disc is at most this.
    """
    if target_error is not None and not (target_error > 0 and math.isfinite(target_error)):
        raise LensrtError(f"target_error {target_error!r} must be a positive number")
    from ..parallel import LocalExecutor
    from .bokeh_job import BokehSetup, bokeh_job
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
    job = bokeh_job(setup, sources, seed, sources_per_item)
    ex = LocalExecutor(device) if executor is None else executor
    result = ex.run(job, progress=progress)
    img: BokehImage = result.value
    img.seconds = time.perf_counter() - t0
    img.seed = int(seed)
    img.timing.update({"placement_seconds": t_place, "job_seconds": result.seconds,
                       "executor": result.executor, "devices": list(result.devices)})
    return img


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
