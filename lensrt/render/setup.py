"""Render set-up: the options a render takes, the result it returns, and :func:`prepare_render` (scene,
lens, camera, wavelength bands and exit-pupil table packed for the device passes)."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import LensrtError
from ..stats import Estimate
from .camera import Camera, setup_camera
from .passes import RenderSetup
from .plan import Plan, plan_render

__all__ = ["RenderOptions", "RenderResult", "prepare_render", "scale_pixels", "bands", "band_note"]


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


def bands(plan: Plan, band_width_nm: float) -> tuple[float, float, int]:
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


def _refuse_shapes(lens) -> None:
    """The render integrator runs the symmetric kernel variant: conics and even aspheres only (one clear error)."""
    shaped = [i for i, s in enumerate(lens.surfaces) if s.shape is not None]
    if shaped:
        i = shaped[0]
        raise LensrtError(f"render traces conic and even-asphere surfaces only; surface {i + 1} is a "
                          f"{lens.surfaces[i].shape.kind} surface", path=lens.path,
                          hint="trace, psf, mtf, spot and bokeh handle it (docs/guide/surface-types.md)")


def _refuse_mirrors(lens) -> None:
    """Camera paths trace the lens backwards from the sensor (reversed_lens): coaxial refracting lenses only."""
    if lens.has_mirrors:
        raise LensrtError("render traces camera paths backwards from the sensor through a coaxial refracting lens; "
                          "this lens has mirrors (the reversed path through its folded frames is not built)",
                          path=lens.path, hint="a scene of point and sphere lights only renders through it from the "
                                               "light side (light splat, e.g. its ring bokeh); or use lensrt bokeh")


def _check_coverage(cam, table) -> None:
    """One clear error when the tilted/shifted lens sends no light to the sensor's centre (beyond its image circle)."""
    origin, rot = cam.lens_frame()
    q = rot.T @ (np.array([0.0, 0.0, cam.sensor_z_mm]) - origin)
    b = min(int(math.hypot(q[0], q[1]) * table.inv_dr), table.n_bins - 1)
    if not table.areas_mm2[b] > 0.0:
        raise LensrtError(f"the lens tilted {math.degrees(cam.tilt_rad):g} deg, swung {math.degrees(cam.swing_rad):g} "
                          f"deg and shifted ({cam.shift_mm[0]:g}, {cam.shift_mm[1]:g}) mm does not cover the sensor's "
                          f"centre: it lies {math.hypot(q[0], q[1]):.3g} mm off the lens axis, beyond its image circle",
                          path=cam.lens.path, hint="tilt, swing or shift less")


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
    _refuse_shapes(lens)
    _refuse_mirrors(lens)
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
    if cam.is_tilt_shift:
        _check_coverage(cam, table)
    t["exit_pupil_table"] = time.perf_counter() - t0
    spp = options.samples_per_pixel or scene.render.samples_per_pixel
    spp_pass = options.spp_per_pass or max(1, spp // 8)
    band0, bw, nb = bands(plan, options.band_width_nm)
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
