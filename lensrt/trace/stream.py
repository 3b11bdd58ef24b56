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
or to the line from the object point (finite object): the box of the field
point's *real* pupil, found for many field points at once by
:func:`pupil_boxes` (:mod:`lensrt.trace.pupil_boxes`); vignetted rays are
rejected in the kernel. :func:`stream_sources` builds many sources in a few
batched traces (boxes, real chief rays). The estimate of a flux is ``weights /
rays * box area * spectrum total`` (:meth:`StreamResult.flux_per_ray`).

One launch, many sources: each source has its own histogram layer, detection
plane, grid centre and bin size, spectrum (one of the call's spectra), weight
factor, and random seed. A source's rays are those of (its seed, its index,
batch), whatever else shares the launch: give each source its own ``seed`` and
``rng_index`` and a group of sources traced together gives the same bits as each
traced alone (histograms, counts and moment sums; module :mod:`.kernels`).

Ray weights: 1 for a collimated beam (uniform flux per area across it); for an
object point, ``cos(theta_plane) (D / rho)^2`` (the solid angle the pupil element
subtends) times ``cos(theta_object)`` for a Lambertian object surface
(``emitter="lambertian"``) or 1 for an isotropic point source
(``emitter="isotropic"``). Channel tables multiply the weight by a spectral
response (e.g. CIE x-bar, y-bar, z-bar for bokeh colour).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Iris, Lens
from .aiming import FieldPoint, field_point
from .kernels import (COUNT_NAMES, FIXED_POINT_BITS, N_COUNTS, N_STATS, SRC, SRC_COLS, SRC_INT, SRC_INT_COLS,
                      STAT_NAMES, get_kernels, lens_variant)
from .pupil_boxes import PupilBox, box_wavelengths, pupil_box, pupil_boxes
from .pack import index_table, pack_lens
from .sampling import SPECTRUM_DISCRETE, Spectrum, sampler_code, spectrum_discrete
from .shape import describe
from .specialised import DEFAULT_TUNING, GPU_TUNING, StreamOptions, ready, stream_kernel
from ..core.telemetry import download
from .stream_launch import LAUNCH_SLOTS, SLOT_MIN_RAYS, SLOTS_MAX, device_tables, launch_all, plan_slots, slot_layout
from .variants import choose_kernel, params, shape_and_constants

__all__ = ["PupilBox", "StreamSource", "Grid", "Channels", "StreamResult", "pupil_box", "pupil_boxes",
           "stream_source", "stream_sources", "stream", "slot_layout", "strata", "EMITTERS", "SLOTS_MAX",
           "SLOT_MIN_RAYS", "LAUNCH_SLOTS"]

EMITTERS = ("lambertian", "isotropic")


@dataclass(frozen=True)
class StreamSource:
    """One source of a stream: field point, pupil box, detection plane, grid centre, histogram layer.

    Optional, per source: ``seed`` (default: the call's seed) and ``rng_index`` (default: the
    source's position in the list), which with the batch select its random numbers;
    ``pixel_mm``/``pixel_y_mm`` its bins (default: the grid's); ``spectrum`` the index of its
    spectrum among the call's; ``weight`` a factor on every ray weight (histogram and moments).
    """

    field: FieldPoint
    box: PupilBox
    plane_z_mm: float
    centre_mm: tuple[float, float] = (0.0, 0.0)
    layer: int = 0
    emitter: str = "lambertian"
    seed: int | None = None
    rng_index: int | None = None
    pixel_mm: float | None = None
    pixel_y_mm: float | None = None
    spectrum: int = 0
    weight: float = 1.0


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
        """Pupil-box area (mm^2) x the source's spectrum total / rays: multiply weights by it to get flux
        (weights include the source's ``weight`` factor)."""
        totals = self.extra.get("spectrum_totals")
        total = self.spectrum_total if totals is None else float(totals[source])
        return float(self.pupil_area_mm2[source]) * total / self.rays_per_source

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
        source's ``centre_mm`` (the order of ``lensrt.analysis.psf.result.MOMENT_KEYS``)."""
        s = self.batch_stats[source]
        return np.stack([s[:, 1], s[:, 2], s[:, 3], s[:, 4], s[:, 6], s[:, 5]], axis=1)

    def off_grid_weight(self, source: int = 0) -> np.ndarray:
        """Per-batch weight of the OK rays that landed off the grid (B,)."""
        s = self.batch_stats[source]
        return np.maximum(s[:, 1] - s[:, 7], 0.0)

    def bins(self, source: int = 0) -> dict:
        """The source's histogram bins: ``shape`` (ny, nx), ``pixel_mm`` and ``pixel_y_mm`` (mm) and
        ``centre_mm`` (the grid centre on the plane, lens frame)."""
        px = self.extra.get("pixel_mm")
        dx = self.grid.pixel_mm if px is None else float(px[source][0])
        dy = self.grid.dy_mm if px is None else float(px[source][1])
        return {"shape": (self.grid.ny, self.grid.nx), "pixel_mm": dx, "pixel_y_mm": dy,
                "centre_mm": tuple(float(v) for v in self.centre_mm[source])}

    def psf_inputs(self, source: int = 0, channel: int = 0) -> dict:
        """Keyword arguments for ``lensrt.analysis.psf.result.geometric_psf`` -- all but its ``grid``.

        The grid is the analysis stage's ``ImageGrid.centred(b["shape"], 1000 * b["pixel_mm"],
        b["centre_mm"])`` with ``b = self.bins(source)`` (square bins; the trace stage does not
        import the analysis stage): ``lensrt.analysis.psf.geometric.psf_from_stream`` does both.
        Needs ``batch_histograms=True`` and one source per layer; rows run top-down (+y up)
        as the analysis grids do (``hist`` is None when they were kept on the device).
        """
        on_device = "device_histograms" in self.extra
        if self.batch_histograms is None and not on_device:
            raise LensrtError("psf_inputs needs a stream run with batch_histograms=True")
        layer = int(self.extra.get("layers_of_sources", list(range(len(self.pupil_area_mm2))))[source])
        hist = None if on_device else self.batch_histograms[layer, :, channel, ::-1, :]
        return {"hist": hist, "moment_sums": self.moment_sums(source), "off_grid": self.off_grid_weight(source),
                "reference_mm": tuple(float(v) for v in self.centre_mm[source]),
                "samples": self.rays_per_source, "seconds": self.seconds,
                "seed": int(self.extra.get("source_seeds", [self.seed] * (source + 1))[source])}

    def image(self, layer: int = 0, channel: int = 0) -> np.ndarray:
        """One (ny, nx) plane of the histogram (sum of weights per bin; row 0 = lowest y)."""
        return self.histogram[layer, channel]


def stream_sources(lens: Lens, fields, *, plane_z_mm: float | None = None,
                   centres_mm: Sequence[tuple[float, float]] | None = None, layers: Sequence[int] | None = None,
                   emitter: str = "lambertian", wavelengths_nm: Sequence[float] | None = None,
                   iris: Iris | None = None, stop_radius_mm: float | None = None,
                   device: str | None = None) -> list[StreamSource]:
    """:class:`StreamSource` s for many field points at once (each its own layer unless ``layers``).

    ``fields``: (hx, hy) pairs or :class:`~lensrt.trace.aiming.FieldPoint` s. Pupil boxes come from
    one batched :func:`pupil_boxes` (at :func:`~lensrt.trace.pupil_boxes.box_wavelengths` of
    ``wavelengths_nm``); ``centres_mm`` default to where the real chief rays (primary wavelength,
    batched :func:`lensrt.trace.aiming.chief_rays`) meet the plane -- the axis where one cannot be
    traced. The same sources as :func:`stream_source` gives one at a time.
    """
    from .aiming import chief_rays
    from .api import RayBatch, kernel_to_stop, trace
    if emitter not in EMITTERS:
        raise LensrtError(f"unknown emitter {emitter!r}", hint=f"use one of {', '.join(EMITTERS)}")
    fps = [f if isinstance(f, FieldPoint) else field_point(lens, float(f[0]), float(f[1])) for f in fields]
    if not fps:
        return []
    z = lens.image_z_mm if plane_z_mm is None else float(plane_z_mm)
    boxes = pupil_boxes(lens, fps, box_wavelengths(lens, wavelengths_nm), iris=iris, stop_radius_mm=stop_radius_mm,
                        device=device)
    if centres_mm is None:
        wl = lens.wavelengths.primary_nm
        o, d, ok = chief_rays(lens, fps, wl, kernel_to_stop(lens, device))
        r = trace(lens, RayBatch(o, d, np.full(len(fps), wl)), "float64", device, clip=False, plane_z_mm=z)
        good = ok & r.ok
        centres_mm = [(float(r.position_mm[k, 0]), float(r.position_mm[k, 1])) if good[k] else (0.0, 0.0)
                      for k in range(len(fps))]
    layers = list(range(len(fps))) if layers is None else [int(v) for v in layers]
    return [StreamSource(fp, box, z, (float(c[0]), float(c[1])), lay, emitter)
            for fp, box, c, lay in zip(fps, boxes, centres_mm, layers)]


def stream_source(lens: Lens, hx: float = 0.0, hy: float = 0.0, *, field: FieldPoint | None = None,
                  plane_z_mm: float | None = None, centre_mm: tuple[float, float] | None = None, layer: int = 0,
                  emitter: str = "lambertian", wavelengths_nm: Sequence[float] | None = None,
                  iris: Iris | None = None, stop_radius_mm: float | None = None,
                  device: str | None = None) -> StreamSource:
    """A :class:`StreamSource` for field (hx, hy) (or an explicit ``field`` point).

    ``plane_z_mm`` defaults to the image surface; ``centre_mm`` (grid centre and
    moment reference) to where the real chief ray meets that plane (primary
    wavelength; the axis when it cannot be traced). :func:`stream_sources` for one.
    """
    fp = field_point(lens, hx, hy) if field is None else field
    return stream_sources(lens, [fp], plane_z_mm=plane_z_mm, centres_mm=None if centre_mm is None else [centre_mm],
                          layers=[layer], emitter=emitter, wavelengths_nm=wavelengths_nm, iris=iris,
                          stop_radius_mm=stop_radius_mm, device=device)[0]


def _source_rows(lens: Lens, sources: Sequence[StreamSource], grid: Grid) -> np.ndarray:
    """The kernel's source table (:data:`SRC` columns), built column by column."""
    n = len(sources)
    rows = np.zeros((n, SRC_COLS))
    inf = np.array([s.field.infinite for s in sources], dtype=bool)
    lam = np.array([s.emitter == "lambertian" for s in sources], dtype=bool)
    rows[:, SRC["kind"]] = np.where(inf, 0, np.where(lam, 1, 2))
    obj = np.array([(0.0, 0.0, 0.0) if s.field.infinite else s.field.point_mm for s in sources], dtype=np.float64)
    rows[:, SRC["ox"]:SRC["oz"] + 1] = obj
    boxes = [s.box for s in sources]
    axis = np.array([b.axis for b in boxes], dtype=np.float64)
    centre = np.array([b.centre for b in boxes], dtype=np.float64)
    rows[:, SRC["wx"]:SRC["wz"] + 1] = axis
    rows[:, SRC["e1x"]:SRC["e1z"] + 1] = np.array([b.e1 for b in boxes], dtype=np.float64)
    rows[:, SRC["e2x"]:SRC["e2z"] + 1] = np.array([b.e2 for b in boxes], dtype=np.float64)
    rows[:, SRC["cx"]:SRC["cz"] + 1] = centre
    rows[:, SRC["a0"]:SRC["b1"] + 1] = np.array([(b.a0, b.a1, b.b0, b.b1) for b in boxes], dtype=np.float64)
    dist = np.einsum("ij,ij->i", centre - obj, axis)
    rows[:, SRC["dist"]] = np.where(inf, 0.0, dist)
    rows[:, SRC["plane_dz"]] = np.array([s.plane_z_mm for s in sources], dtype=np.float64) - lens.image_z_mm
    px = np.array([_pixel_of(s, grid) for s in sources], dtype=np.float64).reshape(n, 2)
    cen = np.array([s.centre_mm for s in sources], dtype=np.float64).reshape(n, 2)
    rows[:, SRC["gx0"]] = cen[:, 0] - 0.5 * grid.nx * px[:, 0]
    rows[:, SRC["gy0"]] = cen[:, 1] - 0.5 * grid.ny * px[:, 1]
    rows[:, SRC["idx"]], rows[:, SRC["idy"]] = 1.0 / px[:, 0], 1.0 / px[:, 1]
    rows[:, SRC["layer"]] = [s.layer for s in sources]
    rows[:, SRC["sx"]], rows[:, SRC["sy"]] = cen[:, 0], cen[:, 1]
    rows[:, SRC["wscale"]] = [s.weight for s in sources]
    return rows


def _pixel_of(s: StreamSource, grid: Grid) -> tuple[float, float]:
    if s.pixel_mm is None:
        return grid.pixel_mm, grid.dy_mm
    return float(s.pixel_mm), float(s.pixel_mm if s.pixel_y_mm is None else s.pixel_y_mm)


def strata(rays_per_batch: int, spectra: Sequence[Spectrum]) -> tuple[int, int]:
    """(wavelength strata, pupil strata per side) of the stratified sampler: one wavelength stratum per
    line of a discrete spectrum (of the call's spectra with the most lines) -- equal-weight lines then
    each get a whole jittered pupil grid -- and about the cube root of the rays per batch for a
    tabulated one (a 3-D jittered grid); the pupil grid fills the rest."""
    n_b = int(rays_per_batch)
    if spectra[0].mode == SPECTRUM_DISCRETE:
        n_w = max(len(sp.wavelength_nm) for sp in spectra)
    else:
        n_w = max(1, round(n_b ** (1.0 / 3.0)))
    n_w = max(1, min(n_w, n_b))
    return n_w, max(1, math.isqrt(n_b // n_w))


def _spectrum_tables(lens: Lens, spectra: Sequence[Spectrum]):
    """Concatenated wavelength, CDF and index tables of ``spectra`` (each n + 1 entries), offsets, counts."""
    mode = spectra[0].mode
    if any(sp.mode != mode for sp in spectra):
        raise LensrtError("the spectra of one stream call must all be discrete or all tabulated",
                          hint="trace discrete lines and tabulated spectra in separate calls")
    nms, cdfs, tabs, offs, ns = [], [], [], [], []
    off = 0
    for sp in spectra:
        lens.check_wavelengths([sp.wavelength_nm.min(), sp.wavelength_nm.max()])
        n = len(sp.cdf) - 1
        nm = np.asarray(sp.wavelength_nm, dtype=np.float64)
        if mode == SPECTRUM_DISCRETE:  # pad the lines to n + 1 entries, as the CDF has
            tabs.append(np.concatenate([index_table(lens, nm), index_table(lens, nm[-1:])]))
            nm = np.concatenate([nm, nm[-1:]])
        nms.append(nm)
        cdfs.append(np.asarray(sp.cdf, dtype=np.float64))
        offs.append(off)
        ns.append(n)
        off += n + 1
    table = np.concatenate(tabs) if mode == SPECTRUM_DISCRETE else np.zeros((1, 1))
    return mode, np.concatenate(nms), np.concatenate(cdfs), table, offs, ns


def stream(lens: Lens, sources: Sequence[StreamSource], grid: Grid, rays_per_source: int, *,
           spectrum: Spectrum | Sequence[Spectrum] | None = None, channels: Channels | None = None,
           sampler: str = "sobol", seed: int = 0, batches: int = 32, precision: str = "float32",
           device: str | None = None, iris: Iris | None = None, stop_radius_mm: float | None = None,
           clip: bool = True, rays_per_launch: int | None = None, threads_per_batch: int | None = None,
           replicas: int | None = None, cpu_workers: int | None = None,
           device_reduce: bool | None = None, batch_histograms: bool | str = False, kernel: str = "auto",
           histogram: bool = True) -> StreamResult:
    """Trace ``rays_per_source`` Monte Carlo rays from each source and bin them (module docstring).

    Parameters
    ----------
    lens : Lens
    sources : sequence of StreamSource
        Built with :func:`stream_source` / :func:`stream_sources`; the iris and stop radius must
        match those given here.
    grid : Grid
        Histogram bins; each source's grid is centred on its ``centre_mm`` (bin size: the grid's,
        or the source's own ``pixel_mm``).
    rays_per_source : int
        Rounded down to a multiple of ``batches``.
    spectrum : Spectrum or sequence of Spectrum, optional
        Wavelength distribution (default: the lens's wavelengths and weights); several (all
        discrete or all tabulated): source ``s`` samples ``spectrum[s.spectrum]``.
    channels : Channels, optional
        Spectral responses, one histogram channel each (default: one channel of weight 1).
    sampler : {'random', 'stratified', 'sobol', 'r2'}
    seed : int
        The seed of every source that names none. Same seed, device and inputs -> bit-identical
        histogram and statistics.
    batches : int
        Independent randomisations, for standard errors (>= 2).
    precision, device
        As for :func:`lensrt.trace.trace`.
    rays_per_launch : int, optional
        Bounds the rays of one launch (the time per launch); results do not depend on it.
    threads_per_batch : int, optional
        Slots (threads) per batch, each tracing a contiguous run of rays (default:
        :func:`slot_layout` of the rays per batch). The moment sums depend on it (their order
        of addition), histograms and counts do not.
    replicas : int, optional
        Histogram copies on a GPU against atomic contention (summed on the device).
    cpu_workers : int, optional
        On the CPU, host threads running slices of each launch concurrently (default: the
        CPU cores this process may use); results do not depend on it.
    device_reduce : bool, optional
        Ignored (kept for compatibility): the slots are always added on the device, in slot order.
    batch_histograms : bool or 'device'
        Keep one histogram per batch (``StreamResult.batch_histograms``, for per-pixel standard
        errors); memory grows by the number of batches. ``'device'``: not downloaded -- see :func:`_histograms`.
    kernel : {'auto', 'generic', 'specialised'}
        Kernel variant (:mod:`lensrt.trace.variants`); ``extra["kernel"]`` says which ran.
    histogram : bool
        Bin the rays. False: counts and moments only (transmission, pupil areas, centroids,
        RMS radii); the specialised kernel then skips the binning, and the histogram is zero.

    Notes
    -----
    ``StreamResult.seconds`` is the wall-clock time of the call (set-up, launches, copies);
    ``extra["kernel_seconds"]`` the device time of the launches alone (CUDA events on a GPU,
    the launches' wall-clock time on the CPU).
    """
    from ..device import warp
    wp = warp()
    t_call = time.perf_counter()
    _check_call(sources, batches, batch_histograms)
    code = sampler_code(sampler)
    packed = pack_lens(lens, precision, device, iris, stop_radius_mm)
    dev, k = packed.device, get_kernels(precision)
    S, B = len(sources), int(batches)
    n_b = int(rays_per_source) // B
    if n_b < 1:
        raise LensrtError(f"{rays_per_source} rays cannot fill {B} batches")
    shape, consts = shape_and_constants(packed, clip)
    variant = choose_kernel(kernel, dev, shape, S * B * n_b)
    spectra = _spectra_of(lens, spectrum, sources)
    mode, nm, cdf, table, spec_off, spec_n = _spectrum_tables(lens, spectra)
    chan_mode, chan, nm0, dnm = _channel_table(channels)
    _check_grid(grid, sources)
    plan = plan_slots(S, B, n_b, grid.nx * grid.ny, max(s.layer for s in sources) + 1, chan.shape[0],
                      dev.startswith("cuda"), batch_histograms=bool(batch_histograms),
                      threads_per_batch=threads_per_batch, replicas=replicas, cpu_workers=cpu_workers,
                      rays_per_launch=rays_per_launch)
    src_int, seeds = _source_ints(sources, seed, spec_off, spec_n)
    t = device_tables(wp, dev, precision, plan, _source_rows(lens, sources, grid), src_int, nm, cdf, table, chan)
    use_table = int(mode == SPECTRUM_DISCRETE)
    chan_args = [t.chan, k.real(nm0), k.real(dnm)]
    if variant == "specialised":
        spec = stream_kernel(precision, shape, StreamOptions(code, bool(use_table), chan_mode == 1, bool(histogram)),
                             GPU_TUNING[precision] if plan.is_gpu else DEFAULT_TUNING)
        ready(spec, dev)
        kern, after = spec.kernel, []
        head = [params(spec, consts, dev), t.src, t.src_int, t.spec_nm, t.spec_cdf, t.table] + chan_args
    else:
        _, kern, lens_arg = lens_variant(k, packed.general)
        after = [t.rec, lens_arg]
        head = [packed.surf, packed.media, packed.iris, lens.n_surfaces, int(clip), t.src, t.src_int, t.spec_nm,
                t.spec_cdf, use_table, t.table, chan_mode] + chan_args + [code]
    out, launches, kernel_seconds = launch_all(wp, dev, plan, t, grid.nx, grid.ny, strata(n_b, spectra), kern,
                                               head, after, k.fold_slots, k.sum_replicas)
    unit = 1.0 / float(2**FIXED_POINT_BITS)  # a power of two: the float64 values are exact
    h = _histograms(out, plan, grid, batch_histograms == "device", histogram)
    extra = {"threads_per_batch": plan.n_slots, "slot_rays": plan.slot_rays, "replicas": plan.replicas,
             "cpu_workers": 1 if plan.is_gpu else plan.replicas, "kernel": variant, "shape": describe(shape),
             "layers_of_sources": [s.layer for s in sources], "stat_names": STAT_NAMES,
             "kernel_seconds": float(kernel_seconds), "source_seeds": seeds,
             "spectrum_totals": [spectra[s.spectrum].total * 1.0 for s in sources]}
    if any(s.pixel_mm is not None for s in sources):
        extra["pixel_mm"] = [_pixel_of(s, grid) for s in sources]
    if batch_histograms == "device":
        extra["device_histograms"] = dict(array=out, shape=h.shape[:3] + (grid.ny, grid.nx), unit=unit)
    return StreamResult((h.sum(axis=1) if plan.hb > 1 else h[:, 0]) * unit, n_b * B, B,
                        download(t.tot_stats).reshape(S, B, N_STATS), download(t.tot_counts).reshape(S, B, N_COUNTS),
                        np.array([s.box.area_mm2 for s in sources]), spectra[0].total,
                        np.array([s.centre_mm for s in sources], dtype=np.float64), grid,
                        time.perf_counter() - t_call, precision, dev, sampler, int(seed), launches,
                        h * unit if (batch_histograms and batch_histograms != "device") else None, extra)


def _check_call(sources: Sequence[StreamSource], batches: int, batch_histograms: bool | str) -> None:
    """The errors of a bad :func:`stream` call (no source, fewer than 2 batches, an unknown ``batch_histograms``)."""
    if not sources:
        raise LensrtError("a stream needs at least one source")
    if batches < 2:
        raise LensrtError("a stream needs at least 2 batches (for the standard error)")
    _check_keep(batch_histograms)


def _check_keep(batch_histograms: bool | str) -> None:
    if batch_histograms not in (True, False, "device"):
        raise LensrtError(f"batch_histograms={batch_histograms!r} is not one of True, False, 'device'")


def _histograms(out: Any, plan: Any, grid: Grid, on_device: bool, histogram: bool) -> np.ndarray:
    """The histogram array downloaded (layers, batches, channels, ny, nx), zeroed without ``histogram``.

    ``stream(..., batch_histograms="device")`` (``on_device``): the per-batch histograms are not downloaded
    (analyses that run on the device read them, :mod:`lensrt.analysis.psf.device_sums`):
    ``extra["device_histograms"]`` holds the flat int64 Warp array (layers, batches, channels, ny, nx; row
    0 = lowest y), its ``shape`` and the fixed-point ``unit``; the result's ``histogram`` is empty."""
    if on_device:
        return np.zeros((plan.layers, plan.hb, plan.n_chan, 0, 0), dtype=np.int64)
    h = download(out).reshape(plan.layers, plan.hb, plan.n_chan, grid.ny, grid.nx)
    if not histogram:
        h[...] = 0
    return h


def _spectra_of(lens: Lens, spectrum: Spectrum | Sequence[Spectrum] | None,
                sources: Sequence[StreamSource]) -> list[Spectrum]:
    """The call's spectra (default: the lens's wavelengths and weights), checked against the sources."""
    if spectrum is None:
        spectra = [spectrum_discrete(lens.wavelengths.nm, lens.wavelengths.weights)]
    elif isinstance(spectrum, Spectrum):
        spectra = [spectrum]
    else:
        spectra = list(spectrum)
    if not spectra or any(not (0 <= s.spectrum < len(spectra)) for s in sources):
        raise LensrtError("every source's spectrum index must name one of the call's spectra")
    return spectra


def _channel_table(channels: Channels | None) -> tuple[int, np.ndarray, float, float]:
    """(mode, table (channels, wavelengths), nm0, dnm): mode 0 is one channel of weight 1."""
    if channels is None:
        return 0, np.zeros((1, 2)), 0.0, 1.0
    chan = np.atleast_2d(np.asarray(channels.table, dtype=np.float64))
    if chan.shape[1] < 2 or channels.dnm <= 0:
        raise LensrtError("a channel table needs at least two wavelengths and a positive step")
    return 1, chan, float(channels.nm0), float(channels.dnm)


def _check_grid(grid: Grid, sources: Sequence[StreamSource]) -> None:
    if grid.nx < 1 or grid.ny < 1 or grid.pixel_mm <= 0 or grid.dy_mm <= 0:
        raise LensrtError("the histogram grid needs positive sizes")
    if any(s.pixel_mm is not None and not (s.pixel_mm > 0 and (s.pixel_y_mm or s.pixel_mm) > 0) for s in sources):
        raise LensrtError("a source's pixel size must be positive")


def _source_ints(sources: Sequence[StreamSource], seed: int, spec_off: list[int],
                 spec_n: list[int]) -> tuple[np.ndarray, list[int]]:
    """The per-source integers (:data:`SRC_INT`: seed, index mixed into it, spectrum table entries)."""
    src_int = np.zeros((len(sources), SRC_INT_COLS), dtype=np.int32)
    seeds = [int(seed if s.seed is None else s.seed) & 0x7FFFFFFF for s in sources]
    src_int[:, SRC_INT["seed"]] = seeds
    src_int[:, SRC_INT["index"]] = [j if s.rng_index is None else int(s.rng_index) for j, s in enumerate(sources)]
    src_int[:, SRC_INT["spec_off"]] = [spec_off[s.spectrum] for s in sources]
    src_int[:, SRC_INT["spec_n"]] = [spec_n[s.spectrum] for s in sources]
    return src_int, seeds
