"""The *stream* shape: rays generated, traced and binned inside the kernel, for PSFs, bokeh, renders.

A stream call traces ``rays_per_source`` rays from each :class:`StreamSource`
(a field point, the box of its real entrance pupil, a detection plane and a
histogram layer) through the lens and accumulates, with no per-ray storage:

* a histogram ``(layers, channels, ny, nx)`` of ray weights on each source's
  plane (deterministic int64 fixed point, see :mod:`.kernels`);
* per batch: status counts and weighted moments (sum w, w x, w y, w x^2, ...),
  from which :class:`StreamResult` gives estimates with standard errors by
  batch means (each batch is an independent randomisation of the sampler).

Pupil sampling: rays start uniformly over a rectangle in the plane through
the paraxial entrance-pupil centre perpendicular to the beam (infinite object)
or to the line from the object point (finite object). :func:`pupil_box` finds
that rectangle per field point by tracing grids of rays through every aperture
(a coarse grid over a region that surely holds the pupil -- everything that
passes surface 1 -- then a finer grid), so the box hugs the *real* pupil,
cat's eyes included; vignetted rays are rejected in the kernel. The estimate of
a flux is ``weights / rays * box area * spectrum total`` (:meth:`StreamResult.flux_per_ray`).

Ray weights: 1 for a collimated beam (uniform flux per area across it); for an
object point, ``cos(theta_plane) (D / rho)^2`` (the solid angle the pupil element
subtends) times ``cos(theta_object)`` for a Lambertian object surface
(``emitter="lambertian"``) or 1 for an isotropic point source
(``emitter="isotropic"``). Channel tables multiply the weight by a spectral
response (e.g. CIE x-bar, y-bar, z-bar for bokeh colour).
"""
from __future__ import annotations

import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Iris, Lens
from .aiming import FieldPoint, beam_basis, field_point, pupil_geometry, ray_through_point
from .kernels import COUNT_NAMES, FIXED_POINT_BITS, N_COUNTS, N_STATS, SRC, SRC_COLS, STAT_NAMES, get_kernels
from .pack import index_table, pack_lens
from .sampling import SPECTRUM_DISCRETE, Spectrum, sampler_code, spectrum_discrete
from .surfaces import N_RECORD
from .shape import describe
from .specialised import DEFAULT_TUNING, GPU_TUNING, StreamOptions, stream_kernel
from .variants import choose_kernel, params, shape_and_constants

__all__ = ["PupilBox", "StreamSource", "Grid", "Channels", "StreamResult", "pupil_box", "stream_source",
           "stream", "EMITTERS"]

EMITTERS = ("lambertian", "isotropic")
_EPOCH = 1 << 30
#: threads per launch on a GPU (all sources and batches), per kernel variant: enough
#: waves that the last one's idle tail stays small
GPU_THREADS = {"generic": 1 << 18, "specialised": 1 << 18}


@dataclass(frozen=True)
class PupilBox:
    """A rectangle [a0, a1] x [b0, b1] in the aim plane through ``centre`` spanned by e1, e2 (mm)."""

    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    e1: tuple[float, float, float]
    e2: tuple[float, float, float]
    a0: float
    a1: float
    b0: float
    b1: float

    @property
    def area_mm2(self) -> float:
        return max(self.a1 - self.a0, 0.0) * max(self.b1 - self.b0, 0.0)

    def points(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        c, e1, e2 = (np.asarray(v) for v in (self.centre, self.e1, self.e2))
        return c + np.asarray(a)[:, None] * e1 + np.asarray(b)[:, None] * e2


@dataclass(frozen=True)
class StreamSource:
    """One source of a stream: field point, pupil box, detection plane, grid centre, histogram layer."""

    field: FieldPoint
    box: PupilBox
    plane_z_mm: float
    centre_mm: tuple[float, float] = (0.0, 0.0)
    layer: int = 0
    emitter: str = "lambertian"


@dataclass(frozen=True)
class Grid:
    """Histogram bins on the detection plane: nx x ny pixels of pixel_mm (square unless pixel_y_mm)."""

    nx: int
    ny: int
    pixel_mm: float
    pixel_y_mm: float | None = None

    @property
    def dy_mm(self) -> float:
        return self.pixel_mm if self.pixel_y_mm is None else self.pixel_y_mm


@dataclass(frozen=True)
class Channels:
    """Spectral responses: ``table[c, g]`` at wavelength nm0 + g * dnm (linear between, 0 outside)."""

    table: np.ndarray
    nm0: float
    dnm: float


@dataclass
class StreamResult:
    """What a stream call accumulated (see the module docstring)."""

    histogram: np.ndarray
    rays_per_source: int
    batches: int
    batch_stats: np.ndarray
    batch_counts: np.ndarray
    pupil_area_mm2: np.ndarray
    spectrum_total: float
    centre_mm: np.ndarray
    grid: Grid
    seconds: float
    precision: str
    device: str
    sampler: str
    seed: int
    launches: int = 0
    #: (layers, batches, channels, ny, nx) when asked for (``batch_histograms=True``)
    batch_histograms: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def rays_total(self) -> int:
        return self.rays_per_source * len(self.pupil_area_mm2)

    @property
    def rays_per_second(self) -> float:
        return self.rays_total / self.seconds if self.seconds > 0 else math.inf

    def status_counts(self, source: int | None = None) -> dict[str, int]:
        """Rays per status (all sources, or one); ``OUTSIDE_GRID`` counts OK rays off the grid,
        ``GRAZING`` OK rays that met or left a surface beyond 80 deg (ill-conditioned)."""
        c = self.batch_counts.sum(axis=(0, 1)) if source is None else self.batch_counts[source].sum(axis=0)
        return {n: int(v) for n, v in zip(COUNT_NAMES, c)}

    def flux_per_ray(self, source: int = 0) -> float:
        """Pupil-box area (mm^2) x spectrum total / rays: multiply weights by it to get flux."""
        return float(self.pupil_area_mm2[source]) * self.spectrum_total / self.rays_per_source

    def _estimate(self, source: int, fn) -> tuple[np.ndarray, np.ndarray]:
        """fn(stat sums, rays) on the pooled sums, and its standard error from the batch values."""
        s = self.batch_stats[source]  # (B, N_STATS)
        n_b = self.rays_per_source // self.batches
        pooled = np.asarray(fn(s.sum(axis=0), self.rays_per_source), dtype=np.float64)
        per = np.array([fn(s[b], n_b) for b in range(s.shape[0])], dtype=np.float64)
        good = np.all(np.isfinite(per.reshape(len(per), -1)), axis=1)
        per = per[good]
        se = per.std(axis=0, ddof=1) / math.sqrt(len(per)) if len(per) > 1 else np.full(pooled.shape, np.inf)
        return pooled, se

    def transmission(self, source: int = 0) -> tuple[float, float]:
        """Fraction of the box's rays that reach the plane, with its standard error."""
        v, se = self._estimate(source, lambda s, n: s[0] / n)
        return float(v), float(se)

    def transmitted_area_mm2(self, source: int = 0) -> tuple[float, float]:
        """Area of the real pupil (the box area times the transmission, mm^2) and its standard error."""
        v, se = self.transmission(source)
        a = float(self.pupil_area_mm2[source])
        return v * a, se * a

    def centroid(self, source: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Weighted centroid (x, y) on the plane (mm, lens frame) and its standard error."""
        v, se = self._estimate(source, lambda s, n: np.array([s[2] / s[1], s[3] / s[1]]) if s[1] > 0
                               else np.array([np.nan, np.nan]))
        return v + self.centre_mm[source], se

    def rms_radius(self, source: int = 0) -> tuple[float, float]:
        """Weighted RMS radius about the centroid (mm) and its standard error."""
        def rms(s, n):
            if s[1] <= 0:
                return np.nan
            mx, my = s[2] / s[1], s[3] / s[1]
            return math.sqrt(max(s[4] / s[1] - mx * mx + s[5] / s[1] - my * my, 0.0))
        v, se = self._estimate(source, rms)
        return float(v), float(se)

    def moment_sums(self, source: int = 0) -> np.ndarray:
        """Per-batch weighted moment sums (B, 6): w, wx, wy, wxx, wxy, wyy, positions relative to the
        source's ``centre_mm`` (the order of ``lensrt.analysis.psf.MOMENT_KEYS``)."""
        s = self.batch_stats[source]
        return np.stack([s[:, 1], s[:, 2], s[:, 3], s[:, 4], s[:, 6], s[:, 5]], axis=1)

    def off_grid_weight(self, source: int = 0) -> np.ndarray:
        """Per-batch weight of the OK rays that landed off the grid (B,)."""
        s = self.batch_stats[source]
        return np.maximum(s[:, 1] - s[:, 7], 0.0)

    def psf_inputs(self, source: int = 0, channel: int = 0) -> dict:
        """Keyword arguments for ``lensrt.analysis.psf.geometric_psf`` (with an ImageGrid of
        shape (ny, nx), pitch grid.pixel_mm * 1000 um, centred on ``centre_mm``).

        Needs ``batch_histograms=True`` and one source per layer; rows run top-down (+y up)
        as the analysis grids do.
        """
        if self.batch_histograms is None:
            raise LensrtError("psf_inputs needs a stream run with batch_histograms=True")
        layer = int(self.extra.get("layers_of_sources", list(range(len(self.pupil_area_mm2))))[source])
        hist = self.batch_histograms[layer, :, channel, ::-1, :]
        return {"hist": hist, "moment_sums": self.moment_sums(source), "off_grid": self.off_grid_weight(source),
                "reference_mm": tuple(float(v) for v in self.centre_mm[source]),
                "samples": self.rays_per_source, "seconds": self.seconds, "seed": self.seed}

    def image(self, layer: int = 0, channel: int = 0) -> np.ndarray:
        """One (ny, nx) plane of the histogram (sum of weights per bin; row 0 = lowest y)."""
        return self.histogram[layer, channel]


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _surface1_box(lens: Lens, fp: FieldPoint, c: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                  w: np.ndarray) -> tuple[float, float, float, float]:
    """A box in the aim plane that holds every ray passing surface 1's clear aperture."""
    s1 = lens.surfaces[0]
    sd = s1.semi_diameter_mm
    if sd is None:
        geom = pupil_geometry(lens)
        sd = 4.0 * geom.ep_radius_mm + abs(geom.ep_z_mm)
    sag = abs(float(s1.sag(min(sd, s1.max_semi_diameter_mm))))
    if fp.infinite:
        ca, cb = float(-c @ e1), float(-c @ e2)
        half = sd + sag
        return ca - half, ca + half, cb - half, cb + half
    o = np.asarray(fp.point_mm)
    phi = np.linspace(0.0, 2.0 * np.pi, 181)
    rim = []
    for z in (0.0, float(s1.sag(min(sd, s1.max_semi_diameter_mm)))):
        rim.append(np.stack([sd * np.cos(phi), sd * np.sin(phi), np.full_like(phi, z)], axis=1))
    pts = np.concatenate(rim)
    v = pts - o
    along = v @ w
    dist = float((c - o) @ w)
    if np.any(along <= 0.0) or dist <= 0.0:
        half = 10.0 * sd
        return -half, half, -half, half
    proj = o + v * (dist / along)[:, None] - c
    a, b = proj @ e1, proj @ e2
    pad = 0.02 * (a.max() - a.min() + b.max() - b.min())
    return a.min() - pad, a.max() + pad, b.min() - pad, b.max() + pad


def _aim_frame(lens: Lens, fp: FieldPoint) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    geom = pupil_geometry(lens)
    c = np.array([0.0, 0.0, geom.ep_z_mm])
    if fp.infinite:
        w = np.asarray(fp.direction, dtype=np.float64)
    else:
        v = c - np.asarray(fp.point_mm, dtype=np.float64)
        w = v / np.linalg.norm(v)
    e1, e2 = beam_basis(w)
    return c, w, e1, e2


def pupil_box(lens: Lens, fp: FieldPoint, wavelengths_nm: Sequence[float] | None = None, *,
              iris: Iris | None = None, stop_radius_mm: float | None = None, device: str | None = None,
              coarse: int = 128, fine: int = 64) -> PupilBox:
    """The box of the real (vignetted) entrance pupil of field point ``fp`` (module docstring).

    Traced in float64 with every aperture, at ``wavelengths_nm`` (default: the
    lens's shortest, primary and longest). An empty box (area 0) means no ray
    gets through.
    """
    from .api import RayBatch, trace
    c, w, e1, e2 = _aim_frame(lens, fp)
    wls = list(lens.wavelengths.nm) if wavelengths_nm is None else [float(v) for v in wavelengths_nm]
    wls = sorted({min(wls), max(wls), lens.wavelengths.primary_nm if wavelengths_nm is None else wls[0]})

    def passing(a0: float, a1: float, b0: float, b1: float, n: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        da, db = (a1 - a0) / n, (b1 - b0) / n
        ga = a0 + (np.arange(n) + 0.5) * da
        gb = b0 + (np.arange(n) + 0.5) * db
        A, B = np.meshgrid(ga, gb, indexing="ij")
        A, B = A.ravel(), B.ravel()
        pts = c + A[:, None] * e1 + B[:, None] * e2
        o, d = ray_through_point(fp, pts)
        ok = np.zeros(len(A), dtype=bool)
        for wl in wls:
            r = trace(lens, RayBatch(o, d, np.full(len(A), wl)), "float64", device, iris=iris,
                      stop_radius_mm=stop_radius_mm)
            ok |= r.ok
        return A[ok], B[ok], da, db

    box = _surface1_box(lens, fp, c, e1, e2, w)
    a, b, da, db = passing(*box, coarse)
    if len(a) == 0:
        return PupilBox(tuple(c), tuple(w), tuple(e1), tuple(e2), 0.0, 0.0, 0.0, 0.0)
    box2 = (max(a.min() - 1.5 * da, box[0]), min(a.max() + 1.5 * da, box[1]),
            max(b.min() - 1.5 * db, box[2]), min(b.max() + 1.5 * db, box[3]))
    a, b, da, db = passing(*box2, fine)
    if len(a) == 0:  # a sliver the fine grid missed: keep the coarse box
        a0, a1, b0, b1 = box2
    else:
        a0, a1 = max(a.min() - 1.5 * da, box2[0]), min(a.max() + 1.5 * da, box2[1])
        b0, b1 = max(b.min() - 1.5 * db, box2[2]), min(b.max() + 1.5 * db, box2[3])
    return PupilBox(tuple(c), tuple(w), tuple(e1), tuple(e2), float(a0), float(a1), float(b0), float(b1))


def stream_source(lens: Lens, hx: float = 0.0, hy: float = 0.0, *, field: FieldPoint | None = None,
                  plane_z_mm: float | None = None, centre_mm: tuple[float, float] | None = None, layer: int = 0,
                  emitter: str = "lambertian", wavelengths_nm: Sequence[float] | None = None,
                  iris: Iris | None = None, stop_radius_mm: float | None = None,
                  device: str | None = None) -> StreamSource:
    """A :class:`StreamSource` for field (hx, hy) (or an explicit ``field`` point).

    ``plane_z_mm`` defaults to the image surface; ``centre_mm`` (grid centre and
    moment reference) to where the real chief ray meets that plane (primary
    wavelength; the axis when it cannot be traced).
    """
    from .aiming import aim_rays
    from .api import RayBatch, kernel_to_stop, trace
    if emitter not in EMITTERS:
        raise LensrtError(f"unknown emitter {emitter!r}", hint=f"use one of {', '.join(EMITTERS)}")
    fp = field_point(lens, hx, hy) if field is None else field
    z = lens.image_z_mm if plane_z_mm is None else float(plane_z_mm)
    box = pupil_box(lens, fp, wavelengths_nm, iris=iris, stop_radius_mm=stop_radius_mm, device=device)
    if centre_mm is None:
        wl = lens.wavelengths.primary_nm
        o, d, ok = aim_rays(lens, fp, np.zeros(1), np.zeros(1), wl, "real", kernel_to_stop(lens, device))
        r = trace(lens, RayBatch(o, d, wl), "float64", device, clip=False, plane_z_mm=z)
        centre_mm = (float(r.position_mm[0, 0]), float(r.position_mm[0, 1])) if r.ok[0] and ok[0] else (0.0, 0.0)
    return StreamSource(fp, box, z, (float(centre_mm[0]), float(centre_mm[1])), int(layer), emitter)


def _source_rows(lens: Lens, sources: Sequence[StreamSource], grid: Grid) -> np.ndarray:
    rows = np.zeros((len(sources), SRC_COLS))
    for k, s in enumerate(sources):
        b = s.box
        r = rows[k]
        if s.field.infinite:
            r[SRC["kind"]] = 0
        else:
            r[SRC["kind"]] = 1 if s.emitter == "lambertian" else 2
            r[SRC["ox"]:SRC["oz"] + 1] = s.field.point_mm
        r[SRC["wx"]:SRC["wz"] + 1] = b.axis
        r[SRC["e1x"]:SRC["e1z"] + 1] = b.e1
        r[SRC["e2x"]:SRC["e2z"] + 1] = b.e2
        r[SRC["cx"]:SRC["cz"] + 1] = b.centre
        r[SRC["a0"]], r[SRC["a1"]], r[SRC["b0"]], r[SRC["b1"]] = b.a0, b.a1, b.b0, b.b1
        if not s.field.infinite:
            r[SRC["dist"]] = float(np.dot(np.asarray(b.centre) - np.asarray(s.field.point_mm), b.axis))
        r[SRC["plane_dz"]] = s.plane_z_mm - lens.image_z_mm
        r[SRC["gx0"]] = s.centre_mm[0] - 0.5 * grid.nx * grid.pixel_mm
        r[SRC["gy0"]] = s.centre_mm[1] - 0.5 * grid.ny * grid.dy_mm
        r[SRC["layer"]] = s.layer
        r[SRC["sx"]], r[SRC["sy"]] = s.centre_mm
    return rows


def stream(lens: Lens, sources: Sequence[StreamSource], grid: Grid, rays_per_source: int, *,
           spectrum: Spectrum | None = None, channels: Channels | None = None, sampler: str = "sobol",
           seed: int = 0, batches: int = 32, precision: str = "float32", device: str | None = None,
           iris: Iris | None = None, stop_radius_mm: float | None = None, clip: bool = True,
           rays_per_launch: int | None = None, threads_per_batch: int | None = None,
           replicas: int | None = None, cpu_workers: int | None = None,
           device_reduce: bool | None = None, batch_histograms: bool = False, kernel: str = "auto",
           histogram: bool = True) -> StreamResult:
    """Trace ``rays_per_source`` Monte Carlo rays from each source and bin them (module docstring).

    Parameters
    ----------
    lens : Lens
    sources : sequence of StreamSource
        Built with :func:`stream_source`; the iris and stop radius must match those given here.
    grid : Grid
        Histogram bins; each source's grid is centred on its ``centre_mm``.
    rays_per_source : int
        Rounded down to a multiple of ``batches``.
    spectrum : Spectrum, optional
        Wavelength distribution (default: the lens's wavelengths and weights).
    channels : Channels, optional
        Spectral responses, one histogram channel each (default: one channel of weight 1).
    sampler : {'random', 'stratified', 'sobol', 'r2'}
    seed : int
        Same seed, device and inputs -> bit-identical histogram and statistics.
    batches : int
        Independent randomisations, for standard errors (>= 2).
    precision, device
        As for :func:`lensrt.trace.trace`.
    rays_per_launch, threads_per_batch, replicas : optional
        Work split (chunks bound the time per launch; memory does not grow with rays),
        threads looping over rays, and histogram copies against atomic contention.
    cpu_workers : int, optional
        On the CPU, host threads running slices of each launch concurrently (default: the
        CPU cores this process may use); results do not depend on it.
    device_reduce : bool, optional
        Sum the per-thread slots with a kernel on the device (default: on GPUs only).
    batch_histograms : bool
        Keep one histogram per batch (``StreamResult.batch_histograms``, for per-pixel standard
        errors); memory grows by the number of batches.
    kernel : {'auto', 'generic', 'specialised'}
        Kernel variant (:mod:`lensrt.trace.variants`); ``extra["kernel"]`` says which ran.
    histogram : bool
        Bin the rays. False: counts and moments only (transmission, pupil areas, centroids,
        RMS radii); the specialised kernel then skips the binning, and the histogram is zero.
    """
    from ..device import warp
    wp = warp()
    if not sources:
        raise LensrtError("a stream needs at least one source")
    if batches < 2:
        raise LensrtError("a stream needs at least 2 batches (for the standard error)")
    code = sampler_code(sampler)
    packed = pack_lens(lens, precision, device, iris, stop_radius_mm)
    dev = packed.device
    k = get_kernels(precision)
    real = k.real
    is_gpu = dev.startswith("cuda")
    S, B = len(sources), int(batches)
    n_b = int(rays_per_source) // B
    if n_b < 1:
        raise LensrtError(f"{rays_per_source} rays cannot fill {B} batches")
    shape, consts = shape_and_constants(packed, clip)
    variant = choose_kernel(kernel, dev, shape, S * B * n_b)
    want_hist = bool(histogram)
    spectrum = spectrum_discrete(lens.wavelengths.nm, lens.wavelengths.weights) if spectrum is None else spectrum
    lens.check_wavelengths([spectrum.wavelength_nm.min(), spectrum.wavelength_nm.max()])
    use_table = int(spectrum.mode == SPECTRUM_DISCRETE)
    table = index_table(lens, spectrum.wavelength_nm) if use_table else np.zeros((1, 1))
    if channels is None:
        chan_mode, n_chan, chan, nm0, dnm = 0, 1, np.zeros((1, 2)), 0.0, 1.0
    else:
        chan = np.atleast_2d(np.asarray(channels.table, dtype=np.float64))
        if chan.shape[1] < 2 or channels.dnm <= 0:
            raise LensrtError("a channel table needs at least two wavelengths and a positive step")
        chan_mode, n_chan, nm0, dnm = 1, chan.shape[0], float(channels.nm0), float(channels.dnm)
    layers = max(s.layer for s in sources) + 1
    plane = grid.nx * grid.ny
    if grid.nx < 1 or grid.ny < 1 or grid.pixel_mm <= 0 or grid.dy_mm <= 0:
        raise LensrtError("the histogram grid needs positive sizes")
    if threads_per_batch is None:
        threads_per_batch = max(1, min(GPU_THREADS[variant] // (S * B), n_b // 64)) if is_gpu else 1
    T = int(threads_per_batch)
    n_threads = S * B * T
    if is_gpu:
        workers = 1
        if replicas is None:
            replicas = max(1, min(16, (256 << 20) // max(8 * plane * layers * n_chan, 1)))
    else:  # Warp's CPU atomics are plain adds: one histogram replica per worker thread
        workers = max(1, min(int(cpu_workers or _cpu_count()), n_threads))
        replicas = workers
    hb = B if batch_histograms else 1
    hist_len = replicas * layers * hb * n_chan * plane
    if hist_len >= 2**31:
        raise LensrtError(f"histogram of {hist_len} bins is too large (limit 2^31)")
    if rays_per_launch is None:
        rays_per_launch = (1 << 30) if is_gpu else (1 << 22)
    chunk = max(1, min(int(rays_per_launch) // (S * B), _EPOCH))
    # device arrays
    src = wp.array(_source_rows(lens, sources, grid), dtype=real, device=dev)
    nm = np.asarray(spectrum.wavelength_nm, dtype=np.float64)
    spec_nm = wp.array(nm, dtype=real, device=dev)
    spec_cdf = wp.array(spectrum.cdf, dtype=real, device=dev)
    tab = wp.array(table, dtype=real, device=dev)
    chan_arr = wp.array(chan, dtype=real, device=dev)
    hist = wp.zeros(hist_len, dtype=wp.int64, device=dev)
    stats = wp.zeros((n_threads, N_STATS), dtype=wp.float64, device=dev)
    counts = wp.zeros((n_threads, N_COUNTS), dtype=wp.int64, device=dev)
    rec = wp.zeros((1, 1, N_RECORD), dtype=real, device=dev)
    spec = None
    if variant == "specialised":
        spec = stream_kernel(precision, shape, StreamOptions(code, bool(use_table), chan_mode == 1, want_hist),
                             GPU_TUNING[precision] if is_gpu else DEFAULT_TUNING)
        pconst = params(spec, consts, dev)
    device_reduce = is_gpu if device_reduce is None else bool(device_reduce)
    dev_stats = wp.zeros((S * B, N_STATS), dtype=wp.float64, device=dev) if device_reduce else None
    dev_counts = wp.zeros((S * B, N_COUNTS), dtype=wp.int64, device=dev) if device_reduce else None
    red_chunk = 64
    n_chunks = -(-T // red_chunk)
    if device_reduce:
        part_stats = wp.zeros((S * B, N_STATS, n_chunks), dtype=wp.float64, device=dev)
        part_counts = wp.zeros((S * B, N_COUNTS, n_chunks), dtype=wp.int64, device=dev)
    n_strata = int(math.isqrt(n_b))
    tot_stats = np.zeros((S, B, N_STATS))
    tot_counts = np.zeros((S, B, N_COUNTS), dtype=np.int64)
    launches = 0
    t0 = time.perf_counter()
    start = 0
    bounds = [n_threads * w // workers for w in range(workers + 1)]
    pool = ThreadPoolExecutor(workers) if workers > 1 else None
    try:
        while start < n_b:
            epoch, local = divmod(start, _EPOCH)
            count = min(chunk, n_b - start, _EPOCH - local)
            tail = [hist, grid.nx, grid.ny, real(1.0 / grid.pixel_mm), real(1.0 / grid.dy_mm),
                    layers, 1 if workers > 1 else int(replicas), hb]
            if spec is None:
                common = [packed.surf, packed.media, packed.iris, lens.n_surfaces, int(clip), src,
                          int(spectrum.mode), spec_nm, spec_cdf, use_table, tab,
                          chan_mode, n_chan, chan_arr, real(nm0), real(dnm)] + tail + [
                          code, int(seed) & 0x7FFFFFFF, int(epoch), B, T, int(local), int(count), n_strata]
            else:
                common = [pconst, src, spec_nm, spec_cdf, tab, n_chan, chan_arr, real(nm0), real(dnm)] + tail + [
                          int(seed) & 0x7FFFFFFF, int(epoch), B, T, int(local), int(count), n_strata]

            def run(w: int) -> None:
                if spec is None:
                    wp.launch(k.trace_stream, dim=bounds[w + 1] - bounds[w], device=dev,
                              inputs=common + [bounds[w], w if workers > 1 else 0, stats, counts, rec])
                else:
                    wp.launch(spec.kernel, dim=bounds[w + 1] - bounds[w], device=dev,
                              inputs=common + [bounds[w], w if workers > 1 else 0, stats, counts])

            if pool is None:
                run(0)
            else:
                list(pool.map(run, range(workers)))
            launches += 1
            if device_reduce:  # sum the threads' slots on the device, in a fixed order (two stages)
                wp.launch(k.reduce_partial, dim=S * B * (N_STATS + N_COUNTS) * n_chunks, device=dev,
                          inputs=[stats, counts, T, red_chunk, n_chunks, part_stats, part_counts])
                wp.launch(k.reduce_final, dim=S * B * (N_STATS + N_COUNTS), device=dev,
                          inputs=[part_stats, part_counts, n_chunks, dev_stats, dev_counts])
            else:
                tot_stats += stats.numpy().reshape(S, B, T, N_STATS).sum(axis=2)
                tot_counts += counts.numpy().reshape(S, B, T, N_COUNTS).sum(axis=2)
            start += count
    finally:
        if pool is not None:
            pool.shutdown()
    if device_reduce:
        tot_stats = dev_stats.numpy().reshape(S, B, N_STATS)
        tot_counts = dev_counts.numpy().reshape(S, B, N_COUNTS)
    h = hist.numpy().reshape(replicas, layers, hb, n_chan, grid.ny, grid.nx).sum(axis=0)
    if not want_hist:
        h[...] = 0
    seconds = time.perf_counter() - t0
    per_batch = h.astype(np.float64) / float(2**FIXED_POINT_BITS)
    histogram = h.sum(axis=1).astype(np.float64) / float(2**FIXED_POINT_BITS)
    return StreamResult(histogram, n_b * B, B, tot_stats, tot_counts,
                        np.array([s.box.area_mm2 for s in sources]), spectrum.total,
                        np.array([s.centre_mm for s in sources], dtype=np.float64), grid, seconds, precision, dev,
                        sampler, int(seed), launches, per_batch if batch_histograms else None,
                        {"threads_per_batch": T, "replicas": int(replicas), "cpu_workers": workers,
                         "kernel": variant, "shape": describe(shape),
                         "layers_of_sources": [s.layer for s in sources],
                         "stat_names": STAT_NAMES})
