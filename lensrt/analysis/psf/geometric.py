"""Geometric PSFs on real rays: the stream kernel's histogram turned into a :class:`PsfResult`.

For one field point (:func:`geometric_psf_at`):

1. the real, vignetted entrance pupil's box is found (:func:`lensrt.trace.stream.pupil_box`)
   and the real chief ray traced to the observation plane: its landing point is
   the PSF's reference point and the grid's centre;
2. the grid: ``setup.pixels`` square pixels; unless ``setup.pitch_um`` fixes it,
   the pitch is chosen so that the grid holds every ray of a 48 x 48 pilot grid
   over the pupil (at the spectrum's shortest, primary and longest wavelength)
   with a 10 % margin; a ``max_pitch_um`` (to sample an MTF up to 1 / (2 pitch))
   adds pixels, but never past :data:`HIST_BYTES_MAX` of per-batch histograms
   (B x pixels^2 float64 -- 1024 pixels a side at 32 batches): a wide PSF then
   gets a coarser pitch, and its MTF stops at that grid's Nyquist frequency
   (listed in ``metadata["mtf_beyond_grid_nyquist_cpmm"]``);
3. ``setup.rays`` Monte Carlo rays (sampler, seed, ``setup.batches`` independent
   batches) are traced and binned by the stream kernel, with per-batch
   histograms and moment sums;
4. :func:`lensrt.analysis.psf.result.geometric_psf` turns them into the PSF (unit
   volume) and jackknife standard errors; the sagittal and tangential MTF at
   the reference frequencies (and optional curves) get theirs the same way.

``PsfResult.seconds`` is the wall-clock time of all of it; the metadata split it
into ``setup_seconds`` (pupil box, chief ray, pilot), ``trace_seconds`` (the
stream kernel) and ``analysis_seconds`` (PSF, standard errors, MTF). The
estimates' own ``seconds`` count set-up and tracing.

Progressive runs (``setup.target_error`` / ``setup.time_budget_s``): rounds of
rays are added -- the first 2^16 (or fewer), then each round doubles the total
-- until the error measure reaches the target (``lensrt.stats.StopRule``) or
the next round would overrun the time budget. Round r uses its own seed
derived from (seed, r); batch b of every round is added to batch b of the
total, so the B batches stay equal and independent and the jackknife over
them remains valid. A fixed-ray run is round 0 alone.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from ...errors import LensrtError
from ...stats import Estimate, ProgressiveRun, StopRule, batch_means, jackknife
from ...units import UM_PER_MM
from ..fields import FieldSpec
from ..grid import ImageGrid
from .otf import mtf_estimate, tangential_angle_rad
from .result import PsfResult, geometric_psf
from .setup import PsfSetup
from ..pupil_rays import field_xy_of, pupil_grid_rays

if TYPE_CHECKING:
    from .bulk import FieldSums

__all__ = ["StreamTotals", "geometric_psf_at", "finish_geometric", "prepare_field", "prepare_fields", "FieldGeometry",
           "round_seed",
           "psf_window", "psf_windows", "pilot_rays", "add_mtf_estimates", "psf_from_stream"]

#: smallest automatic half-width of a geometric PSF grid (mm): 2 um
_MIN_HALF_MM = 2e-3
#: memory cap of the per-batch histograms of an automatically enlarged grid (module docstring, step 2)
HIST_BYTES_MAX = 256 << 20


def round_seed(seed: int, r: int) -> int:
    """Seed of round ``r`` of a progressive run (round 0 is ``seed`` itself)."""
    if r == 0:
        return int(seed) & 0x7FFFFFFF
    return int(np.random.SeedSequence([int(seed), int(r)]).generate_state(1, np.uint32)[0]) & 0x7FFFFFFF


@dataclass(frozen=True)
class FieldGeometry:
    """What a field point needs before tracing: field point, pupil box, chief ray landing point."""

    fp: object
    box: object
    reference_mm: tuple[float, float]
    chief_direction: tuple[float, float, float]
    seconds: float


def prepare_fields(setup: PsfSetup, fields: list[FieldSpec], device: str | None = None) -> list[FieldGeometry]:
    """Pupil boxes (at the spectrum's extremes and primary) and real chief rays of many fields at once:
    one batched pupil-box search and one batched chief-ray solve (:mod:`lensrt.trace.pupil_boxes`,
    :func:`lensrt.trace.aiming.chief_rays`), whatever the number of fields."""
    from ...trace import RayBatch, trace
    from ...trace.aiming import chief_rays, field_point
    from ...trace.api import kernel_to_stop
    from ...trace.stream import pupil_boxes
    from ...trace.pupil_boxes import box_wavelengths
    t0 = time.perf_counter()
    lens, spec = setup.lens, setup.spectrum
    fps = [field_point(lens, f.hx, f.hy) for f in fields]
    wls = sorted({spec.min_nm, spec.primary_nm, spec.max_nm})
    boxes = pupil_boxes(lens, fps, box_wavelengths(lens, wls), device=device)
    for f, box in zip(fields, boxes):
        if box.area_mm2 <= 0:
            raise LensrtError(f"field {f.label or (f.hx, f.hy)}: no ray passes the lens",
                              hint="choose field points inside the lens's coverage")
    wl = spec.primary_nm
    o, d, ok = chief_rays(lens, fps, wl, kernel_to_stop(lens, device))
    chief = trace(lens, RayBatch(o, d, np.full(len(fps), wl)), "float64", device, clip=False,
                  plane_z_mm=setup.plane_z_mm)
    if not (ok.all() and chief.ok.all()):
        raise LensrtError("the real chief ray of this field point cannot be traced to the image",
                          hint="choose a field point inside the lens's coverage")
    each = (time.perf_counter() - t0) / max(len(fields), 1)
    return [FieldGeometry(fp, box, (float(chief.position_mm[k, 0]), float(chief.position_mm[k, 1])),
                          tuple(float(v) for v in chief.direction[k]), each)
            for k, (fp, box) in enumerate(zip(fps, boxes))]


def prepare_field(setup: PsfSetup, f: FieldSpec, device: str | None = None) -> FieldGeometry:
    """Pupil box (at the spectrum's extremes and primary) and real chief ray of field ``f``."""
    return prepare_fields(setup, [f], device)[0]


def _window(setup: PsfSetup, half: float) -> tuple[float, int, float]:
    half = max(1.1 * half, _MIN_HALF_MM)
    pixels = int(setup.pixels)
    if setup.pitch_um is not None:
        return float(setup.pitch_um), pixels, half
    pitch_um = 2.0 * half * UM_PER_MM / pixels
    if setup.max_pitch_um is not None and pitch_um > setup.max_pitch_um:
        cap = min(4096, int(math.sqrt(HIST_BYTES_MAX / (8.0 * setup.batches))))
        cap = max(pixels, cap - cap % 2)
        pixels = min(cap, int(math.ceil(2.0 * half * UM_PER_MM / setup.max_pitch_um)))
        pixels += pixels % 2
        pitch_um = max(setup.max_pitch_um, 2.0 * half * UM_PER_MM / pixels)
    return float(pitch_um), pixels, half


def psf_windows(setup: PsfSetup, geoms: list[FieldGeometry], device: str | None = None, n_side: int = 48
                ) -> list[tuple[float, int, float]]:
    """(pitch_um, pixels, pilot half-width mm) of the grid of each field (module docstring, step 2):
    the pilot grids of all fields at all wavelengths traced together (one launch)."""
    from ...trace import RayBatch, trace
    spec = setup.spectrum
    o, d = pilot_rays(geoms, n_side)
    m = n_side * n_side
    wls = sorted({spec.min_nm, spec.primary_nm, spec.max_nm})
    n = len(o)
    r = trace(setup.lens, RayBatch(np.tile(o, (len(wls), 1)), np.tile(d, (len(wls), 1)),
                                   np.repeat(np.asarray(wls, dtype=np.float64), n)), "float64", device,
              plane_z_mm=setup.plane_z_mm)
    # the farthest landing point of each field from its reference, over its rays at every wavelength, in one
    # pass over (wavelengths, fields, rays) (maxima are exact: the same numbers as wavelength by wavelength)
    ref = np.array([g.reference_mm for g in geoms], dtype=np.float64)
    pos = r.position_mm.reshape(len(wls), len(geoms), m, 3)
    dev = np.maximum(np.abs(pos[..., 0] - ref[:, 0, None]), np.abs(pos[..., 1] - ref[:, 1, None]))
    half = dev.max(axis=(0, 2), where=r.ok.reshape(dev.shape), initial=0.0)
    return [_window(setup, float(h)) for h in half]


def pilot_rays(geoms: list[FieldGeometry], n_side: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions (fields * n_side^2, 3) of every field's pilot grid, field after field: the rays
    of :func:`~lensrt.analysis.pupil_rays.pupil_grid_rays` bit for bit (they set each grid's pitch).

    Fields at infinity are made all at once with the same element-wise operations in the same order (cell
    centres, box points, the foot of each ray on the plane through the first vertex); object points at a
    finite distance take ``pupil_grid_rays`` field by field."""
    m, nf = int(n_side), len(geoms)
    o = np.empty((nf, m * m, 3))
    d = np.empty((nf, m * m, 3))
    inf = [k for k, g in enumerate(geoms) if g.fp.infinite]
    for k in (k for k, g in enumerate(geoms) if not g.fp.infinite):
        r = pupil_grid_rays(geoms[k].fp, geoms[k].box, m)
        o[k], d[k] = r.origin_mm, r.direction
    if inf:
        boxes = [geoms[k].box for k in inf]
        if min(b.area_mm2 for b in boxes) <= 0:  # pupil_grid_rays' error
            pupil_grid_rays(geoms[inf[0]].fp, next(b for b in boxes if b.area_mm2 <= 0), m)
        lim = np.array([(b.a0, b.a1, b.b0, b.b1) for b in boxes], dtype=np.float64)
        c, e1, e2 = (np.array([getattr(b, name) for b in boxes], dtype=np.float64)[:, None, :]
                     for name in ("centre", "e1", "e2"))
        cells = np.arange(m) + 0.5
        a = lim[:, 0:1] + cells * (lim[:, 1] - lim[:, 0])[:, None] / m  # (F, m), as pupil_grid_rays' a and b
        b = lim[:, 2:3] + cells * (lim[:, 3] - lim[:, 2])[:, None] / m
        A = np.repeat(a, m, axis=1)[:, :, None]  # meshgrid(a, b, indexing="ij"), raveled
        B = np.tile(b, (1, m))[:, :, None]
        pts = c + A * e1 + B * e2  # PupilBox.points
        di = np.broadcast_to(np.array([geoms[k].fp.direction for k in inf], dtype=np.float64)[:, None, :],
                             pts.shape)
        o[inf] = pts - np.sum(pts * di, axis=2, keepdims=True) * di  # ray_through_point at infinity
        d[inf] = di
    return o.reshape(-1, 3), d.reshape(-1, 3)


def psf_window(setup: PsfSetup, geom: FieldGeometry, device: str | None = None, n_side: int = 48
               ) -> tuple[float, int, float]:
    """(pitch_um, pixels, pilot half-width mm) of the grid for this field (module docstring, step 2)."""
    return psf_windows(setup, [geom], device, n_side)[0]


@dataclass
class StreamTotals:
    """Per-batch sums over the rounds of a (progressive) stream run."""

    hist: np.ndarray
    moments: np.ndarray
    off_grid: np.ndarray
    counts: dict = field(default_factory=dict)
    rays: int = 0
    trace_seconds: float = 0.0
    launches: int = 0
    rounds: int = 0
    device: str = ""
    box_area_mm2: float = 0.0
    kernel_seconds: float = 0.0
    #: per-batch count of rays that reached the plane (status OK)
    ok: np.ndarray | None = None

    def add(self, res, source: int = 0, share: float = 1.0) -> None:
        """Add source ``source`` of a stream result; ``share`` of its time is this source's."""
        inp = res.psf_inputs(source)
        n_ok = np.asarray(res.batch_stats[source][:, 0], dtype=np.float64)
        self.ok = n_ok if self.ok is None else self.ok + n_ok
        if inp["hist"] is not None:  # None: kept on the device (analysed there, device_sums)
            self.hist += inp["hist"]
        self.moments += inp["moment_sums"]
        self.off_grid += inp["off_grid"]
        for k, v in res.status_counts(source).items():
            self.counts[k] = self.counts.get(k, 0) + int(v)
        self.rays += int(res.rays_per_source)
        self.trace_seconds += float(res.seconds) * share
        self.kernel_seconds += float(res.extra.get("kernel_seconds", res.seconds)) * share
        self.launches += int(res.launches)
        self.rounds += 1
        self.device = res.device
        self.box_area_mm2 = float(res.pupil_area_mm2[source])


def rms_rel_error(moments: np.ndarray) -> tuple[float, float]:
    def rms(t: np.ndarray) -> float:
        w = t[0]
        if not w > 0:
            return 0.0
        cx, cy = t[1] / w, t[2] / w
        return math.sqrt(max(t[3] / w - cx * cx + t[5] / w - cy * cy, 0.0))
    v, se = jackknife(moments, rms)
    return v, (se / v if v > 0 else math.inf)


def _mtf_error(hist: np.ndarray, grid: ImageGrid, freqs: np.ndarray, ref: tuple[float, float]) -> float:
    if freqs.size == 0 or not hist.sum() > 0:
        return math.inf
    t = tangential_angle_rad(ref)
    se = [np.max(mtf_estimate(hist, grid, freqs, a).stderr) for a in (t, t + 0.5 * math.pi)]
    return float(max(se))


def _usable_freqs(freqs, grid: ImageGrid) -> np.ndarray:
    f = np.asarray(freqs, dtype=np.float64)
    return f[(f >= 0) & (f <= 0.5 / grid.pitch_mm * (1 - 1e-9))]


def run_stream(setup: PsfSetup, geom: FieldGeometry, grid: ImageGrid, seed: int, device: str | None = None
               ) -> tuple[StreamTotals, ProgressiveRun]:
    """Trace and bin the field's rays, progressively when the setup asks for it (module docstring)."""
    from ...trace.stream import Grid, StreamSource, stream
    lens = setup.lens
    src = StreamSource(geom.fp, geom.box, setup.plane_z_mm, geom.reference_mm, 0, "lambertian")
    sgrid = Grid(grid.shape[1], grid.shape[0], grid.pitch_mm)
    spectrum = setup.spectrum.trace_spectrum()
    B = int(setup.batches)
    rows, cols = grid.shape
    tot = StreamTotals(np.zeros((B, rows, cols)), np.zeros((B, 6)), np.zeros(B))
    rule = StopRule(max_samples=int(setup.rays), target_error=setup.target_error,
                    time_budget_s=setup.time_budget_s, relative=setup.target_quantity == "rms", min_batches=1)
    run = ProgressiveRun(rule)
    freqs = _usable_freqs(setup.mtf_freqs_cpmm, grid)
    n_next = int(setup.rays)
    if setup.progressive:
        n_next = min(int(setup.rays), max(1 << 16, B * 256))
    # GPU histogram replicas (against atomic contention) within 256 MiB of per-batch histograms
    from ...device import resolve_device
    replicas = None
    if resolve_device(device).startswith("cuda"):
        replicas = int(max(1, min(16, (256 << 20) // (8 * rows * cols * B))))
    r = 0
    while True:
        n_next = max(B, (n_next // B) * B)
        res = stream(lens, [src], sgrid, n_next, spectrum=spectrum, sampler=setup.sampler, seed=round_seed(seed, r),
                     batches=B, precision=setup.precision, device=device, batch_histograms=True, replicas=replicas)
        tot.add(res)
        run.add(res.rays_total)
        r += 1
        if not setup.progressive:
            break
        if setup.target_quantity == "rms":
            value, err = rms_rel_error(tot.moments)
            run.record(value, err * value)
        else:
            err = _mtf_error(tot.hist, grid, freqs, geom.reference_mm)
            run.record(err, err)
        if run.should_stop(err):
            break
        # next round: double the total, within the ray cap and the time budget
        n_next = min(tot.rays, int(setup.rays) - tot.rays)
        if setup.time_budget_s is not None:
            rate = tot.rays / max(tot.trace_seconds, 1e-9)
            left = setup.time_budget_s - run.elapsed_s
            n_next = min(n_next, int(0.8 * left * rate))
            if n_next < B * 64:
                run.stop_reason = "time_budget"
                break
        if n_next < B:
            run.stop_reason = "samples"
            break
    return tot, run


def add_mtf_estimates(result: PsfResult, hist: np.ndarray | None, freqs_ref, freqs_curve,
                      mtf_fn=None, sums: FieldSums | None = None) -> dict[str, Estimate]:
    """Sagittal/tangential MTF Estimates at the reference frequencies (and curves) for a PSF result.

    From per-batch histograms (jackknife) when ``hist`` is given; else deterministic, from
    ``mtf_fn(freqs, angle_rad)`` (e.g. a diffraction OTF over whole FFT periods) or the PSF itself.
    Frequencies beyond the grid's Nyquist are left out (listed in the metadata). ``sums``: the
    histograms' :class:`~lensrt.analysis.psf.bulk.FieldSums` (Fourier sums of :func:`mtf_requests`).
    """
    from .otf import mtf_along
    from .jackknife import mtf_jackknife
    out: dict[str, Estimate] = {}
    grid = result.grid
    t = tangential_angle_rad(result.reference_mm)
    nyq = 0.5 / grid.pitch_mm if mtf_fn is None else math.inf
    # a diffraction PSF has unit volume over the whole plane: its MTF is normalised by that power, not by
    # the window's sum (which the cut wings make too small)
    total = 1.0 / grid.pixel_area_mm2 if result.kind.startswith("diffraction") else None
    for key, freqs in (("mtf", freqs_ref), ("mtf_curve", freqs_curve)):
        f_all = np.asarray(freqs, dtype=np.float64)
        if f_all.size == 0:
            continue
        f = f_all[(f_all >= 0) & (f_all <= nyq * (1 - 1e-9))]
        if f.size < f_all.size:
            result.metadata.setdefault("mtf_beyond_grid_nyquist_cpmm", []).extend(
                [float(v) for v in f_all[f_all > nyq * (1 - 1e-9)]])
        if f.size == 0:
            continue
        pairs = (("sagittal", t + 0.5 * math.pi), ("tangential", t))
        jk = mtf_jackknife(hist, grid, f, [a for _, a in pairs], sums=sums) if hist is not None else None
        for j, (name, ang) in enumerate(pairs):
            if jk is not None:  # mtf_estimate's numbers, both directions in one pass
                e = Estimate(jk[j][0], jk[j][1], int(result.samples), float(result.seconds),
                             f"jackknife over {np.shape(hist)[0]} batches", "")
            else:
                v = mtf_fn(f, ang) if mtf_fn is not None else mtf_along(result.psf, grid, f, ang,
                                                                        binned=result.binned, total=total)
                e = Estimate(np.asarray(v), np.zeros(f.size), result.samples, result.seconds, "deterministic", "")
            out[f"{key}_{name}"] = e
        result.metadata[f"{key}_freqs_cpmm"] = [float(v) for v in f]
    result.estimates.update(out)
    return out


def geometric_psf_at(setup: PsfSetup, f: FieldSpec, seed: int, device: str | None = None,
                     geom: FieldGeometry | None = None, reason: str = "asked for") -> PsfResult:
    """The geometric PSF of field point ``f`` (module docstring)."""
    t0 = time.perf_counter()
    geom = prepare_field(setup, f, device) if geom is None else geom
    pitch_um, pixels, half = psf_window(setup, geom, device)
    grid = ImageGrid.centred((pixels, pixels), pitch_um, geom.reference_mm)
    tot, run = run_stream(setup, geom, grid, seed, device)
    return finish_geometric(setup, f, seed, geom, grid, half, tot, run, time.perf_counter() - t0, reason)


def finish_geometric(setup: PsfSetup, f: FieldSpec, seed: int, geom: FieldGeometry, grid: ImageGrid, half: float,
                     tot: StreamTotals, run: ProgressiveRun | None, seconds: float, reason: str = "asked for",
                     extra: dict | None = None, sums: FieldSums | None = None) -> PsfResult:
    """The PsfResult of a field's traced totals (``seconds``: set-up and tracing so far); ``sums``: their
    :func:`~lensrt.analysis.psf.bulk.field_sums` when a group made them (else made here for this field)."""
    t1 = time.perf_counter()
    spec = setup.spectrum
    n = tot.rays
    meta = {"method": "geometric", "method_reason": reason, "sampler": setup.sampler, "precision": setup.precision,
            "device": tot.device, "focus": setup.focus, "spectrum": spec.to_dict(), "field": f.to_dict(),
            "pupil_box_mm2": tot.box_area_mm2, "status_counts": tot.counts,
            "transmission": tot.counts.get("OK", 0) / n if n else 0.0, "trace_seconds": tot.trace_seconds,
            "kernel_seconds": tot.kernel_seconds,
            "rays_per_second": n / tot.trace_seconds if tot.trace_seconds > 0 else None,
            "launches": tot.launches, "rounds": tot.rounds,
            "stop_reason": run.stop_reason if (setup.progressive and run is not None) else "rays",
            "pilot_half_width_mm": half, "chief_direction": list(geom.chief_direction)}
    meta.update(extra or {})
    if setup.progressive and run is not None:
        meta["progress"] = [p.to_dict() for p in run.history]
        meta["target_error"] = setup.target_error
        meta["target_quantity"] = setup.target_quantity
    if tot.counts.get("GRAZING", 0):
        meta["grazing_rays"] = tot.counts["GRAZING"]
    if not (sums.H.sum() if sums is not None and sums.complete else tot.hist.sum()) > 0:
        raise LensrtError(f"field {f.label}: no ray reached the PSF grid", hint="check the focus and the field")
    if sums is None:
        from .bulk import field_sums
        sums = field_sums(tot.hist[None], tot.off_grid[None], [grid], [geom.reference_mm], setup)[0]
    result = geometric_psf(tot.hist, grid, moment_sums=tot.moments, off_grid=tot.off_grid,
                           reference_mm=geom.reference_mm, wavelengths_nm=spec.lines_nm, weights=spec.line_weights,
                           field_xy=field_xy_of(setup.lens, f.hx, f.hy), field_kind=setup.lens.fields.kind,
                           samples=n, seconds=seconds, seed=int(seed), ee_fractions=setup.ee_fractions,
                           metadata=meta, sums=sums)
    add_mtf_estimates(result, tot.hist, setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm, sums=sums)
    # the fraction of the pupil box's rays that reach the plane, batch means over the (equal) batches
    v, se = batch_means(tot.ok / (n / setup.batches))
    result.estimates["transmission"] = Estimate(float(v), float(se), n, seconds,
                                                f"batch means over {setup.batches} batches", "")
    analysis = time.perf_counter() - t1
    result.metadata["setup_seconds"] = seconds - tot.trace_seconds
    result.metadata["analysis_seconds"] = analysis
    return replace(result, seconds=seconds + analysis)


def psf_from_stream(res, source: int = 0, channel: int = 0, **kwargs) -> PsfResult:
    """The geometric PSF of one source of a stream run with ``batch_histograms=True``: its
    :meth:`~lensrt.trace.stream.StreamResult.psf_inputs` on the source's own bins as an ImageGrid
    (``kwargs`` go to :func:`lensrt.analysis.psf.result.geometric_psf`)."""
    b = res.bins(source)
    if abs(b["pixel_mm"] - b["pixel_y_mm"]) > 1e-12 * b["pixel_mm"]:
        raise LensrtError("a PSF grid needs square bins")
    grid = ImageGrid.centred(b["shape"], b["pixel_mm"] * UM_PER_MM, b["centre_mm"])
    return geometric_psf(grid=grid, **{**res.psf_inputs(source, channel), **kwargs})
