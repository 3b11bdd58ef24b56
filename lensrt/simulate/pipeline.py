"""``simulate``: an image (and its depth map) through a real lens onto the sensor plane.

Order (each step in its module): read the image as linear sRGB (:mod:`.inputs`);
bands of the Mallett-Yuksel spectrum (:mod:`.spectral`); the camera -- focus,
f-number, pixel frame (:mod:`.optics`); depth layers and, per layer, the real
chief-ray mapping and relative illumination (:mod:`.optics`); the PSF grid per
layer and band (:mod:`.psf_grid`, cached); per layer the warp (:mod:`.compose`);
per band the blurred layers composited back to front (:mod:`.compose`,
:mod:`.convolve`); XYZ -> linear sRGB. The output is *relative* sensor-plane
irradiance: a white (1, 1, 1) input on the axis, in focus, gives 1 (absolute:
times ``Simulation.reference_gain_sr`` x the scene's white radiance, see :mod:`.optics`).
"""
from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..colour.rgb import linear_srgb_to_xyz
from ..core.budget import format_bytes
from ..errors import LensrtError
from ..prescription.model import Lens
from .banding import blur_host, fixed_bytes, plan_row_bands
from .compose import LayerFill, assign_layers, layer_depths_mm
from .optics import Camera, LayerOptics, cached_layer_optics, far_depth_mm, make_camera, pinhole_focal_mm
from .psf_grid import cache_dir
from .psf_grid import PsfGrid, compute_psf_grid, hat_weights
from .spectral import Bands, make_bands, round_trip_matrix

__all__ = ["SimulateOptions", "Simulation", "simulate", "memory_bytes", "memory_limit_bytes", "MEMORY_LIMIT_BYTES"]

#: working memory a simulation may take where the machine's memory cannot be read (bytes)
MEMORY_LIMIT_BYTES = 8 << 30


def memory_limit_bytes() -> int:
    """Working memory a simulation may take: 60 % of the machine's physical memory (else
    :data:`MEMORY_LIMIT_BYTES`); beyond it, one clear error."""
    import os
    try:
        return int(0.6 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return MEMORY_LIMIT_BYTES


@dataclass(frozen=True)
class SimulateOptions:
    """Settings of a simulation (lengths in the unit their names say)."""

    sensor: str = "full-frame"
    focus_m: float = math.inf
    f_number: float | None = None
    bands: int = 4
    layers: int = 8
    grid: tuple[int, int] = (5, 7)
    rays: int = 1 << 15
    ri_rays: int = 1 << 16
    seed: int = 0
    cache_dir: str | None = None
    use_cache: bool = True
    device: str | None = None
    #: where the blur runs: "auto" (Warp tile FFTs on a CUDA device, NumPy/SciPy on the CPU), "host", "warp"
    backend: str = "auto"
    #: working-memory budget (bytes) of the host blur; a picture beyond it runs in bands of rows
    #: (:mod:`.banding`). None: 60 % of the machine's memory (:func:`memory_limit_bytes`)
    max_memory_bytes: int | None = None


@dataclass
class Simulation:
    """The simulated image and how it was made.

    ``rgb`` (H, W, 3) linear sRGB of the relative sensor irradiance; ``coefficients`` (K, H, W, 3) the blurred
    Mallett-Yuksel coefficients per band (the spectrum, :func:`lensrt.simulate.spectral.spectral_basis`);
    ``y_stderr`` (H, W) the standard error of Y from the PSFs' Monte Carlo rays.
    """

    rgb: np.ndarray
    coefficients: np.ndarray
    y_stderr: np.ndarray
    camera: Camera
    bands: Bands
    layers: list
    psf_grid: PsfGrid
    seconds: dict
    notes: list = field(default_factory=list)
    depth_error_per_m: float = 0.0
    outside_fraction: float = 0.0

    #: on-axis gain (sr) at the focus distance: the output's unit (absolute irradiance = rgb x this x radiance)
    reference_gain_sr: float = 0.0

    def errors(self) -> dict:
        """The error estimates of the sidecar."""
        y = linear_srgb_to_xyz(self.rgb)[..., 1]   # luminance Y of linear sRGB (lensrt.colour)
        lit = y > 0.05 * max(float(np.percentile(y, 99)), 1e-30)
        rel = self.y_stderr[lit] / np.maximum(y[lit], 1e-30)
        checks = self.psf_grid.checks
        return {
            "psf_monte_carlo": {
                "what": "per-pixel standard error of Y from the rays behind each PSF (ray-sampling variance of the "
                        "PSF-weighted mean, propagated through the compositing; an upper bound for Sobol' rays)",
                "rel_stderr_rms_lit": float(np.sqrt(np.mean(rel ** 2))) if rel.size else 0.0,
                "rel_stderr_max_lit": float(rel.max()) if rel.size else 0.0,
                "rays_per_psf": self.psf_grid.rays, "rays_landed_min": int(self.psf_grid.rays_landed.min()),
                "off_window_max": float(self.psf_grid.off_window.max())},
            "interpolation": {
                "what": "bilinear blend of the 4 node PSFs against a PSF traced directly at cell centres: total-"
                        "variation distance (fraction of the light misplaced); 'direct_vs_direct' is the Monte Carlo "
                        "floor of two independent direct PSFs",
                "checks": checks,
                "tv_max": max((c["tv_interpolated_vs_direct"] for c in checks), default=None),
                "tv_excess_max": max((max(0.0, c["tv_interpolated_vs_direct"] - c["tv_direct_vs_direct"])
                                      for c in checks), default=None)},
            "relative_illumination_stderr_max": float(max(float(o.ri_stderr.max()) for o in self.layers)),
            "depth_quantisation_max_per_m": self.depth_error_per_m,
            "spectral_round_trip_max": float(np.abs(round_trip_matrix(self.bands) - np.eye(3)).max()),
            "pixels_beyond_input_frame": self.outside_fraction,
        }

    def to_dict(self) -> dict:
        return {"camera": self.camera.to_dict(), "bands": self.bands.to_dict(),
                "reference_gain_sr": self.reference_gain_sr,
                "layers": [o.to_dict() for o in self.layers], "psf_grid": self.psf_grid.summary(),
                "seconds": self.seconds, "errors": self.errors(), "notes": self.notes,
                "scheme": {"convolution": "source-side bilinear interpolation of node PSFs (Nagy & O'Leary 1998), "
                                          "FFT per node tile", "occlusion": "layers blurred premultiplied and "
                                          "composited back to front with 'over', renormalised by the coverage "
                                          "(Kraus & Strengert 2007; Lee et al. 2010)",
                           "spectrum": "Mallett & Yuksel 2019 basis x D65, one PSF per band"}}


def memory_bytes(shape: tuple[int, int], bands: int, layers: int) -> int:
    """Working memory of a simulation of ``shape`` (bytes; float32 channels: per band the compositing
    accumulators (5), one layer's blur and its temporaries (11), the output coefficients (3); the picture and
    its per-layer fill, the layer's channels, the float64 geometry and warp temporaries and the sRGB output
    (44); layers are processed one at a time, so ``layers`` does not count)."""
    return int(shape[0] * shape[1] * 4 * (19 * bands + 44))


def _depth_plan(cam: Camera, depth_m: np.ndarray | None, n_layers: int) -> tuple[np.ndarray, np.ndarray | None, float]:
    """(layer depths mm far first, layer index image or None, dioptre error)."""
    if depth_m is None:
        d = cam.focus.distance_mm
        return np.array([d if math.isfinite(d) else far_depth_mm(cam.lens)]), None, 0.0
    depths = layer_depths_mm(depth_m, n_layers)
    idx, err = assign_layers(depth_m, depths)
    return depths, idx, err


def simulate(image: np.ndarray, lens: Lens, depth_m: np.ndarray | None = None,
             options: SimulateOptions = SimulateOptions()) -> Simulation:
    """Simulate ``image`` (H, W, 3 linear sRGB, pinhole view) through ``lens`` (module docstring)."""
    t0 = time.perf_counter()
    _use_device(options)  # a device asked for and not there: one error before any work
    shape = image.shape[:2]
    budget = _budget_bytes(options)
    fixed = fixed_bytes(shape, options.bands)
    if fixed > budget:  # the input and the outputs alone: no band can help
        raise LensrtError(f"a {shape[1]} x {shape[0]} image needs about {format_bytes(fixed)} of working memory "
                          f"for its input and outputs alone, more than the {format_bytes(budget)} allowed",
                          hint="use a smaller image or fewer --bands, or give more memory (--max-memory)")
    # bands of the thinnest kind, before any PSF is traced (the exact plan, with the PSFs' halo, comes later)
    plan_row_bands(shape, options.bands, 0, shape[1] // max(options.grid[1] - 1, 1) + 1, 1, budget)
    if depth_m is not None and depth_m.shape != shape:
        raise LensrtError(f"the depth map is {depth_m.shape[1]} x {depth_m.shape[0]}, the image {shape[1]} x {shape[0]}")
    bands = make_bands(options.bands)
    cam = make_camera(lens, shape, options.sensor, options.focus_m, options.f_number, options.device)
    depths, idx, derr = _depth_plan(cam, depth_m, options.layers)
    f_pin = pinhole_focal_mm(cam)
    where = cache_dir(options.cache_dir) if options.use_cache else None
    optics = [cached_layer_optics(cam, float(d), f_pin, options.ri_rays, options.seed, where) for d in depths]
    ref = _reference_gain(cam, optics, depths, f_pin, options, where)
    t1 = time.perf_counter()
    grid = compute_psf_grid(cam, bands, depths, options.grid, options.rays, options.seed, options.cache_dir,
                            options.use_cache)
    t2 = time.perf_counter()
    with _heap_reuse():
        coef, rgb, var_y, outside, backend = _blur(image, cam, optics, idx, ref, grid, bands, options)
    t3 = time.perf_counter()
    sim = Simulation(rgb, coef, np.sqrt(var_y).astype(np.float32), cam, bands, optics, grid,
                     {"optics": t1 - t0, "psf_grid": t2 - t1, "convolution": t3 - t2, "total": t3 - t0},
                     [f"convolution on {backend}"], derr, outside)
    sim.reference_gain_sr = ref
    sim.notes += _notes(cam, depths, derr, grid)
    return sim


def _blur(image: np.ndarray, cam: Camera, optics: list[LayerOptics], idx: np.ndarray | None, ref: float,
          grid: PsfGrid, bands: Bands, options: SimulateOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                          float, str]:
    """Warp, blur and composite every layer: (coefficients (K, H, W, 3), linear sRGB (H, W, 3), variance of Y
    (H, W), fraction of
    pixels from beyond the input frame, where it ran). On a CUDA device (or ``options.backend == "warp"``) with
    Warp's tile FFTs (:mod:`.device`), else with NumPy/SciPy on the host."""
    shape = image.shape[:2]
    yw = bands.xyz_matrix[:, 1, :]
    rays = grid.rays_landed.reshape(len(optics), bands.count, -1).mean(axis=2).astype(np.float64)
    gains = [opt.axis_gain_sr / ref for opt in optics]
    to_rgb = _rgb_matrix(bands)
    if _use_device(options):
        need, budget = memory_bytes(shape, bands.count, len(optics)), _budget_bytes(options)
        if need > budget:
            raise LensrtError(f"a {shape[1]} x {shape[0]} image needs about {format_bytes(need)} of working memory "
                              f"on the device path, more than the {format_bytes(budget)} allowed (it blurs whole "
                              f"pictures)", hint="use --device cpu (it blurs in bands of rows), or --max-memory")
        from .device import FFT_STATE, simulate_on_device
        coef, rgb, var_y, outside = simulate_on_device(_layer_inputs(image, idx, grid), cam, optics, gains, grid, yw,
                                                       rays, to_rgb, options.device or "cpu")
        note = f"; {FFT_STATE['note']}" if FFT_STATE["note"] else ""
        return coef, rgb, var_y, outside, f"{options.device or 'cpu'} (Warp tile FFTs{note})"
    n_px = max(p.shape[-1] for p in grid.psf)
    cell_cols = int(np.diff(grid.node_cols).max()) + 1
    row_bands = plan_row_bands(shape, bands.count, n_px // 2, cell_cols, n_px, _budget_bytes(options))
    coef, rgb, var_y, outside = blur_host(cam, optics, lambda: _layer_inputs(image, idx, grid), grid, yw, rays,
                                          gains, to_rgb, row_bands)
    where = "host (NumPy/SciPy FFTs)"
    if len(row_bands) > 1:
        where += f" in {len(row_bands)} bands of up to {max(b - a for a, b in row_bands)} rows (memory budget)"
    return coef, rgb, var_y, outside, where


def _budget_bytes(options: SimulateOptions) -> int:
    """The working-memory budget (bytes): ``options.max_memory_bytes``, else :func:`memory_limit_bytes`."""
    if options.max_memory_bytes is None:
        return memory_limit_bytes()
    if not options.max_memory_bytes > 0:
        raise LensrtError(f"memory budget {options.max_memory_bytes!r} bytes: give a positive size")
    return int(options.max_memory_bytes)


def _layer_inputs(image: np.ndarray, idx: np.ndarray | None, grid: PsfGrid):
    """Per layer, far first: (colour, mask) -- the layer continued behind nearer layers as far as their blur
    reaches (:class:`lensrt.simulate.compose.LayerFill`); the whole picture without a depth map. Each colour
    is valid until the next one is drawn."""
    if idx is None:
        yield image, None
        return
    fill = LayerFill(image, idx)
    for li in range(len(grid.psf)):
        reach = max((grid.psf[k].shape[-1] // 2 for k in range(li + 1, len(grid.psf))), default=0)
        yield fill(li, reach)


def _rgb_matrix(bands: Bands) -> np.ndarray:
    """(3, K, 3): linear sRGB = sum over bands b and coefficients c of M[:, b, c] x coefficient (XYZ -> sRGB of
    sum_b W_b c_b, :mod:`.spectral`)."""
    from ..colour import xyz_to_linear_srgb
    a = xyz_to_linear_srgb(np.eye(3)).T  # XYZ -> linear sRGB as a matrix on column vectors
    return np.einsum("ok,bkc->obc", a, bands.xyz_matrix)


@contextmanager
def _heap_reuse():
    """While the blur runs, large temporaries come from the heap and are reused once freed, instead of fresh
    memory maps that the kernel must fault in and zero every time (glibc: ``mallopt``; elsewhere nothing
    changes). The FFT tiles allocate and free hundreds of MB per tile: on a 1.9 MP, 8-layer picture this took
    the system time from 5.5 s to 0.1 s. The defaults are restored, and the heap trimmed, afterwards."""
    import ctypes
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt, trim = libc.mallopt, libc.malloc_trim
    except (OSError, AttributeError):
        yield
        return
    m_trim_threshold, m_mmap_max = -1, -4
    mallopt(m_mmap_max, 0)
    mallopt(m_trim_threshold, 2**31 - 1)
    try:
        yield
    finally:
        mallopt(m_mmap_max, 65536)
        mallopt(m_trim_threshold, 128 * 1024)
        trim(0)


def _use_device(options: SimulateOptions) -> bool:
    """Whether the blur runs with Warp kernels: on a CUDA device always, on the CPU when asked
    (``backend="warp"``). A CUDA device that Warp does not see is one clear error, never a silent host run."""
    dev = (options.device or "cpu").lower()
    if options.backend not in ("auto", "host", "warp"):
        raise LensrtError(f"simulate backend {options.backend!r} is not auto, host or warp")
    if dev.startswith("cuda"):
        if options.backend == "host":
            return False
        import warp as wp
        wp.init()
        if not wp.is_cuda_available():
            raise LensrtError(f"device {options.device!r} asked for, but Warp sees no CUDA device",
                              hint="use --device cpu")
        return True
    return options.backend == "warp"


def _reference_gain(cam: Camera, optics: list[LayerOptics], depths: np.ndarray, f_pin: float,
                    options: SimulateOptions, where) -> float:
    """The on-axis gain (sr) at the focus distance: the output's unit (white in focus on the axis = 1)."""
    fd = cam.focus.distance_mm if math.isfinite(cam.focus.distance_mm) else far_depth_mm(cam.lens)
    for d, o in zip(depths, optics):
        if abs(d - fd) <= 1e-9 * fd:
            return o.axis_gain_sr
    return cached_layer_optics(cam, float(fd), f_pin, options.ri_rays, options.seed, where).axis_gain_sr


def _notes(cam: Camera, depths: np.ndarray, derr: float, grid: PsfGrid) -> list[str]:
    notes = []
    if grid.off_window.max() > 0.01:
        notes.append(f"up to {100 * grid.off_window.max():.1f} % of a PSF's light fell outside its "
                     f"{grid.psf[0].shape[-1]}-pixel window (cut)")
    if derr > 0:
        notes.append(f"depths quantised to {len(depths)} layers: at most {derr:.3g} 1/m from a pixel's depth")
    notes.append("one PSF per band (its centroid wavelength); relative illumination at the primary wavelength")
    return notes
