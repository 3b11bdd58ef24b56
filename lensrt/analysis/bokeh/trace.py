"""Bokeh sources through the real lens: placement by the real chief ray, pupil boxes, windows, streaming.

Used by :mod:`lensrt.analysis.bokeh.entry`; everything here works on many sources at
once (kernels over all sources, vectorised float64 host work), so that a map of
hundreds of sources costs a handful of kernel launches before the stream launch.

* :func:`object_heights_for_image` -- where to put a point source at depth s
  so that its real chief ray (through the centre of the real stop, primary
  wavelength) meets the sensor plane at a given height: Newton on the aim
  point for the chief ray inside a secant iteration on the object height
  (steps into heights that have no chief ray are halved back toward the axis:
  strongly distorting lenses), for every height and depth in one kernel
  launch (one thread each; general lenses: on the host, a batched trace per
  step). A rotationally symmetric lens maps azimuths one to one, so one
  radial solve serves every azimuth.
* :func:`pupil_boxes` -- the box of each source's *real* (vignetted) entrance
  pupil and its *footprint* on the sensor plane (the bounding box of its blur
  spot): :func:`lensrt.trace.stream.pupil_boxes` (maps use grids of 64 and 48;
  the shortest, a middle and the longest wavelength).
* :func:`stream_windows` -- one stream launch for many sources, each binned
  into its own histogram layer: a window of the frame's pixel grid around its
  footprint. Each source is scaled to sensor illuminance by its own pupil box
  and distance, so sources of different depths and vignetting share one launch.
  With a target error or a time budget the launch becomes rounds (the first of
  at most 2^16 rays per source, then each doubling the total) until every
  source's noise measure -- the RMS over its disc of the per-pixel relative
  standard error of Y -- is at most the target, the time budget would be
  overrun, or ``rays_per_source`` is reached. Round r has its own seed; batch b of
  every round joins batch b of the total (the stream's per-batch sums simply
  add), so batch means over the batches stay valid, as for progressive PSFs.

Pixel values are CIE XYZ with Y the illuminance on the sensor in lux (lm/m^2)
for sources of ``intensity_cd`` candela; no glass absorption or Fresnel loss
(the tracer does not model them).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Iris, Lens
from ...units import MM_PER_M

__all__ = ["Frame", "object_heights_for_image", "pupil_boxes", "stream_windows", "SourceOut",
           "WINDOW_MARGIN", "DISC_THRESHOLD", "GROUP_HIST_BYTES", "disc_noise", "disc_noise_rms", "stream_estimates",
           "percentile99"]

#: windows extend the traced footprint by this fraction of its size on every side (plus 2 px)
WINDOW_MARGIN = 0.04
#: "in the disc": pixels at or above this fraction of the 99th percentile of the source's lit pixels
DISC_THRESHOLD = 0.1
#: most bytes of one stream launch group's histogram: a GPU then keeps at least 8 histogram replicas against
#: atomic contention (``LENSRT_REPLICA_MB``, 256 MiB, over this), as work items of 32 sources had when a map
#: on one device ran several; a map of small discs (the report's: 4.4 MB for 108 sources) is one group
GROUP_HIST_BYTES = 32 << 20


@dataclass(frozen=True)
class Frame:
    """A pixel grid on the sensor plane, in sensor orientation.

    Pixel (iy, ix) covers x in [x0 + ix p, x0 + (ix + 1) p), y in [y0 + iy p, y0 + (iy + 1) p)
    (mm; iy counts up from the lowest y). ``lensrt.analysis.bokeh.entry`` turns it upright for pictures.
    """

    nx: int
    ny: int
    pitch_mm: float
    x0_mm: float
    y0_mm: float

    @property
    def pixel_area_m2(self) -> float:
        return (self.pitch_mm / MM_PER_M) ** 2


# ---- rays from object points (vectorised over sources) ------------------------------------

def _rays_from_points(obj: np.ndarray, aim: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays from object points ``obj`` (n, 3) through ``aim`` (n, 3), starting on the sphere
    through the first vertex centred on the object point (as lensrt.trace.aiming does)."""
    v = aim - obj
    dist = np.sqrt(np.einsum("ij,ij->i", v, v))[:, None]
    d = v / dist
    r0 = np.sqrt(np.einsum("ij,ij->i", obj, obj))[:, None]
    back = (np.einsum("ij,ij->i", aim, aim - 2.0 * obj))[:, None] / (dist + r0)
    return aim - back * d, d


def _trace(lens: Lens, o: np.ndarray, d: np.ndarray, wl: float, device: str | None, **kw):
    from ...trace import RayBatch, trace
    return trace(lens, RayBatch(o, d, np.full(len(o), wl)), "float64", device, **kw)


def object_heights_for_image(lens: Lens, depth_mm, plane_z_mm: float, image_r_mm, wavelength_nm: float,
                             device: str | None = None, tol_mm: float = 1e-7,
                             on_device: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Object heights y (object points (0, y, -depth)) whose real chief rays meet the plane z =
    ``plane_z_mm`` at (0, r); ``depth_mm`` and ``image_r_mm`` broadcast together. Also a mask of
    converged solves.

    y is negative for a lens that inverts the image. Rays are traced without clipping. For a
    rotationally symmetric lens the whole search runs in one kernel launch, one thread per height
    (:func:`lensrt.trace.kernels.boxes.chief_heights`: the host search's arithmetic, operation for
    operation -- the same bits on the CPU); ``on_device=False``, or a general lens, runs it on the host
    (a batched trace per Newton step of every secant step).
    """
    from ...trace.aiming import pupil_geometry
    from ...trace.pack import pack_lens
    depth, r = np.broadcast_arrays(np.asarray(depth_mm, dtype=np.float64), np.asarray(image_r_mm, dtype=np.float64))
    depth, r = depth.ravel().copy(), r.ravel().copy()
    y = np.zeros_like(r)
    ok = np.ones(len(r), dtype=bool)
    todo = r != 0.0
    if not todo.any():
        return y, ok
    geom = pupil_geometry(lens)
    args = (lens, r[todo], depth[todo], geom.ep_z_mm, 1e-6 * max(geom.ep_radius_mm, 1.0), float(plane_z_mm),
            float(wavelength_nm), device, float(tol_mm))
    if on_device is not False and not pack_lens(lens, "float64", device).general:
        y[todo], ok[todo] = _heights_device(*args)
    else:
        y[todo], ok[todo] = _heights_host(*args)
    return y, ok


def _no_chief_ray(depth_mm: float) -> LensrtError:
    return LensrtError(f"no real chief ray from a point {depth_mm:g} mm in front of the lens reaches the sensor plane")


def _heights_device(lens: Lens, rt: np.ndarray, st: np.ndarray, z_ep: float, h_fd: float, plane_z_mm: float,
                    wavelength_nm: float, device: str | None, tol_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`object_heights_for_image`'s search for image heights ``rt`` at depths ``st`` in one launch."""
    from ...core.telemetry import download, launch, upload
    from ...device import warp
    from ...trace.kernels import N_RECORD
    from ...trace.kernels.boxes import CHIEF_CONVERGED, CHIEF_NO_PROBE, chief_heights_symmetric
    from ...trace.kernels.surfaces import SymmetricLens
    from ...trace.pack import pack_lens
    wp = warp()
    packed = pack_lens(lens, "float64", device)
    dev, n = packed.device, len(rt)
    y_out = wp.zeros(n, dtype=wp.float64, device=dev)
    flags = wp.zeros(n, dtype=wp.int32, device=dev)
    launch(chief_heights_symmetric, dim=n, device=dev,
           inputs=[packed.surf, packed.media, packed.iris, lens.n_surfaces, lens.stop_index, float(z_ep), float(h_fd),
                   float(wavelength_nm), float(plane_z_mm) - lens.image_z_mm, float(tol_mm),
                   upload(rt, wp.float64, dev), upload(st, wp.float64, dev),
                   wp.zeros((1, 1), dtype=wp.float64, device=dev),
                   wp.zeros((1, 1, N_RECORD), dtype=wp.float64, device=dev), SymmetricLens(), y_out, flags])
    y, f = download(y_out), download(flags)
    if np.any(f == CHIEF_NO_PROBE):
        raise _no_chief_ray(float(st[np.argmax(f == CHIEF_NO_PROBE)]))
    return y, (f & CHIEF_CONVERGED) != 0


def _heights_host(lens: Lens, rt: np.ndarray, st: np.ndarray, z_ep: float, h_fd: float, plane_z_mm: float,
                  wavelength_nm: float, device: str | None, tol_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`object_heights_for_image`'s search on the host: Newton on the aim point for the chief ray
    inside a secant iteration on the object height, every step one batched trace of all heights."""
    stop = lens.stop_index

    def chief(y: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image height of the real chief ray of each object point (0, y, -s), and whether it was found."""
        n = len(y)
        obj = np.stack([np.zeros(n), y, -s], axis=1)

        def rays(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return _rays_from_points(obj, np.stack([np.zeros(n), b, np.full(n, z_ep)], axis=1))

        def at_stop(b: np.ndarray) -> tuple[np.ndarray, ...]:
            """Stop heights at b and at b + h_fd (the finite difference's neighbour) in one trace."""
            bb = np.concatenate([b, b + h_fd])
            o, d = _rays_from_points(np.concatenate([obj, obj]),
                                     np.stack([np.zeros(2 * n), bb, np.full(2 * n, z_ep)], axis=1))
            res = _trace(lens, o, d, wavelength_nm, device, clip=False, end=stop)
            yb, okb = res.position_mm[:, 1], res.ok
            return yb[:n], okb[:n], yb[n:], okb[n:]

        b = np.zeros(n)  # aim point (0, b) in the paraxial entrance-pupil plane; Newton to the stop centre
        f0, ok, f1, ok1 = at_stop(b)
        for _ in range(30):
            if np.all(~ok | (np.abs(f0) < 1e-11)):
                break
            slope = (f1 - f0) / h_fd
            good = ok & ok1 & (slope != 0.0) & (np.abs(f0) >= 1e-11)
            b = b - np.where(good, f0 / np.where(good, slope, 1.0), 0.0)
            f0, ok_new, f1, ok1 = at_stop(b)
            ok &= ok_new
        ok &= np.abs(f0) < 1e-8
        res = _trace(lens, *rays(b), wavelength_nm, device, clip=False, plane_z_mm=plane_z_mm)
        return res.position_mm[:, 1], ok & res.ok

    # a probe near the axis gives each depth's scale; then secant steps on every height at once
    probe = 1e-3 * (st + abs(z_ep))
    hp, okp = chief(-probe, st)
    if not np.all(okp & (hp != 0.0)):
        raise _no_chief_ray(float(st[~(okp & (hp != 0.0))][0]))
    y0 = rt * (-probe / hp)
    h0, ok0 = chief(y0, st)
    for _ in range(20):  # a paraxial start with no chief ray (strong distortion): move it toward the axis
        if ok0.all():
            break
        y0 = np.where(ok0, y0, 0.7 * y0)
        hb, okb = chief(y0[~ok0], st[~ok0])
        h0[~ok0], ok0[~ok0] = hb, okb
    y1 = y0 * (1.0 + 1e-3)
    h1, ok1 = chief(y1, st)
    conv = ok1 & (np.abs(h1 - rt) <= tol_mm)
    for _ in range(40):
        good = ok0 & ok1 & (h1 != h0) & ~conv
        if not good.any():
            break
        y2 = np.where(good, y1 - (h1 - rt) * (y1 - y0) / np.where(good, h1 - h0, 1.0), y1)
        h2, ok2 = chief(y2, st)
        for _ in range(12):  # a step into heights with no chief ray: halve it (strong distortion)
            back = good & ~ok2
            if not back.any():
                break
            y2 = np.where(back, 0.5 * (y1 + y2), y2)
            h2b, ok2b = chief(y2[back], st[back])
            h2[back], ok2[back] = h2b, ok2b
        y0, h0, ok0 = np.where(good, y1, y0), np.where(good, h1, h0), np.where(good, ok1, ok0)
        y1, h1, ok1 = np.where(good, y2, y1), np.where(good, h2, h1), np.where(good, ok2, ok1)
        conv |= ok1 & (np.abs(h1 - rt) <= tol_mm)
    return y1, conv


# ---- pupil boxes of many sources ------------------------------------------------------------

def pupil_boxes(lens: Lens, obj: np.ndarray, wavelengths_nm: Sequence[float], plane_z_mm: float, *,
                iris: Iris | None = None, stop_radius_mm: float | None = None, device: str | None = None,
                coarse: int = 128, fine: int = 64, min_cells_across_pupil: int = 0) -> tuple[list, np.ndarray]:
    """Real pupil boxes of the object points ``obj`` (S, 3) and their footprints on the plane
    z = ``plane_z_mm``: :func:`lensrt.trace.stream.pupil_boxes` with ``footprint=True``.

    Returns (boxes, footprint): a :class:`lensrt.trace.stream.PupilBox` per source
    (area 0 when nothing passes) and (S, 4) footprint bounds x_min, x_max, y_min, y_max
    (mm; NaN when nothing passes) of the passing grid rays on the plane.
    """
    from ...trace.stream import pupil_boxes as batched
    return batched(lens, np.atleast_2d(np.asarray(obj, dtype=np.float64)), wavelengths_nm, plane_z_mm=plane_z_mm,
                   iris=iris, stop_radius_mm=stop_radius_mm, device=device, coarse=coarse, fine=fine,
                   min_cells_across_pupil=min_cells_across_pupil, footprint=True)


# ---- streaming many sources into windows of one frame -------------------------------------

@dataclass
class SourceOut:
    """One source's contribution: a window of the frame (sensor orientation) and its statistics.

    ``xyz`` (3, wy, wx) is CIE XYZ in lux, ``var_y`` (wy, wx) the variance of Y (lux^2) by the
    method in ``stats["noise_method"]``; both None when no ray reached the sensor plane.
    The window's pixel (0, 0) is frame pixel (``iy0``, ``ix0``).
    """

    index: int
    ix0: int
    iy0: int
    xyz: np.ndarray | None
    var_y: np.ndarray | None
    stats: dict
    #: (batches, 3, wy, wx) XYZ of each batch (lux, the batch's own estimate of the window) when kept
    batch_xyz: np.ndarray | None = None


def _window(foot: np.ndarray, frame: Frame) -> tuple[int, int, int, int] | None:
    """(ix0, ix1, iy0, iy1) frame pixels covering a footprint plus margin, clipped to the frame."""
    if not np.all(np.isfinite(foot)):
        return None
    p = frame.pitch_mm
    fx0, fx1 = (foot[0] - frame.x0_mm) / p, (foot[1] - frame.x0_mm) / p
    fy0, fy1 = (foot[2] - frame.y0_mm) / p, (foot[3] - frame.y0_mm) / p
    m = WINDOW_MARGIN * max(fx1 - fx0, fy1 - fy0) + 2.0
    ix0, ix1 = max(int(math.floor(fx0 - m)), 0), min(int(math.ceil(fx1 + m)), frame.nx)
    iy0, iy1 = max(int(math.floor(fy0 - m)), 0), min(int(math.ceil(fy1 + m)), frame.ny)
    if ix1 <= ix0 or iy1 <= iy0:
        return None
    return ix0, ix1, iy0, iy1


def percentile99(values: np.ndarray) -> float:
    """``np.percentile(values, 99.0)`` of a 1-d float64 array without NaNs, the same bits: the two order
    statistics around the virtual index (n - 1) q found by a partition and interpolated as NumPy's
    'linear' method does (its overhead, not the arithmetic, is what this saves: a map has one per source)."""
    n = values.size
    v = (n - 1) * (99.0 / 100)
    if v >= n - 1:
        i = j = n - 1
    else:
        i = int(math.floor(v))
        j = i + 1
    part = np.partition(values, (i, j)) if j != i else np.partition(values, i)
    a, b = part[i], part[j]
    t = v - i
    diff = b - a
    return b - diff * (1 - t) if t >= 0.5 else a + diff * t


def _disc(y: np.ndarray) -> np.ndarray | None:
    """The disc of :func:`disc_noise` (a mask of ``y``), None when no pixel is lit."""
    lit = y[y > 0]
    if lit.size == 0:
        return None
    return y >= DISC_THRESHOLD * percentile99(lit)


def disc_noise(y: np.ndarray, var_y: np.ndarray, disc: np.ndarray | None = None) -> tuple[float, int]:
    """Median per-pixel relative standard error of Y over the disc, and the disc's pixel count.

    The disc: pixels at or above :data:`DISC_THRESHOLD` of the 99th percentile of the lit pixels
    (``disc``: that mask when already known).
    """
    disc = _disc(y) if disc is None else disc
    if disc is None:
        return math.nan, 0
    rel = np.sqrt(np.maximum(var_y[disc], 0.0)) / y[disc]
    return float(np.median(rel)), int(disc.sum())


def disc_noise_rms(y: np.ndarray, var_y: np.ndarray, disc: np.ndarray | None = None) -> float:
    """RMS over the disc (as :func:`disc_noise`) of the per-pixel relative standard error of Y: the
    error measure of a target error (what the RMS relative error against the truth estimates)."""
    disc = _disc(y) if disc is None else disc
    if disc is None:
        return math.nan
    return float(np.sqrt(np.mean(np.maximum(var_y[disc], 0.0) / (y[disc] * y[disc]))))


def _per_batch(fn, s: np.ndarray, pooled_n: int, batch_n: int) -> tuple[np.ndarray, np.ndarray]:
    """``StreamResult._estimate`` for every source of a stream at once: ``fn`` (whole arrays, per source
    and batch) on the pooled sums (S, ...) and the standard error (S, ...) from the finite batch values."""
    pooled = fn(s.sum(axis=1), pooled_n)
    per = fn(s, batch_n)  # (S, B, ...)
    good = np.all(np.isfinite(per.reshape(per.shape[0], per.shape[1], -1)), axis=2)
    se = np.empty_like(pooled)
    full = good.all(axis=1)
    if full.any() and per.shape[1] > 1:
        se[full] = per[full].std(axis=1, ddof=1) / math.sqrt(per.shape[1])
    for k in np.nonzero(~full | (per.shape[1] < 2))[0]:  # a batch with a non-finite value is left out
        v = per[k][good[k]]
        se[k] = v.std(axis=0, ddof=1) / math.sqrt(len(v)) if len(v) > 1 else np.inf
    return pooled, se


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / den


def _transmission(v: np.ndarray, n: int) -> np.ndarray:
    return v[..., 0] / n


def _centroid(v: np.ndarray, n: int) -> np.ndarray:
    c = np.stack([_ratio(v[..., 2], v[..., 1]), _ratio(v[..., 3], v[..., 1])], axis=-1)
    return np.where((v[..., 1] > 0)[..., None], c, np.nan)


def _rms(v: np.ndarray, n: int) -> np.ndarray:
    mx, my = _ratio(v[..., 2], v[..., 1]), _ratio(v[..., 3], v[..., 1])
    r = np.sqrt(np.maximum(_ratio(v[..., 4], v[..., 1]) - mx * mx + _ratio(v[..., 5], v[..., 1]) - my * my, 0.0))
    return np.where(v[..., 1] > 0, r, np.nan)


def stream_estimates(res) -> dict:
    """Transmission, centroid (mm, on the plane) and RMS radius (mm) of every source of a stream result,
    each with its standard error: what ``StreamResult.transmission`` / ``centroid`` / ``rms_radius`` give
    one source at a time (the same formulas, sums and reductions), as (S,) and (S, 2) arrays."""
    s, n = res.batch_stats, res.rays_per_source
    n_b = n // res.batches
    out = {}
    for name, fn in (("transmission", _transmission), ("centroid", _centroid), ("rms_radius", _rms)):
        out[name], out[name + "_se"] = _per_batch(fn, s, n, n_b)
    out["centroid"] = out["centroid"] + res.centre_mm
    return out


def _merge_rounds(a, b):
    """Two stream results of the same sources and grid as one: every per-batch sum adds up."""
    bh = None if a.batch_histograms is None else a.batch_histograms + b.batch_histograms
    return replace(a, histogram=a.histogram + b.histogram, rays_per_source=a.rays_per_source + b.rays_per_source,
                   batch_stats=a.batch_stats + b.batch_stats, batch_counts=a.batch_counts + b.batch_counts,
                   seconds=a.seconds + b.seconds, launches=a.launches + b.launches, batch_histograms=bh)


def stream_windows(lens: Lens, obj: np.ndarray, boxes: list, footprint: np.ndarray, frame: Frame,
                   plane_z_mm: float, light, rays_per_source: int, *, intensity_cd=1.0,
                   iris: Iris | None = None, stop_radius_mm: float | None = None, sampler: str = "sobol",
                   seed: int = 0, batches: int = 32, precision: str = "float32", device: str | None = None,
                   batch_noise: bool = False, hist_budget_bytes: int = GROUP_HIST_BYTES,
                   target_error: float | None = None, time_budget_s: float | None = None,
                   source_ids: Sequence[int] | None = None) -> list[SourceOut]:
    """Stream every source into its own window of ``frame`` (module docstring); one record per source.

    Sources go into stream launches in groups whose histograms (3 channels per window, int64)
    fit ``hist_budget_bytes``. Every source draws its own random numbers: round r of source
    ``source_ids[k]`` (default k) uses the seed ``hash(seed, id, r)`` and index 0, so a source's
    window is the same bits whichever sources share its launch (grouping, chunking into work
    items, devices of one kind); a progressive group stops on its worst member, so there the
    number of rounds can depend on the group. ``batch_noise`` keeps
    per-batch histograms and gives each pixel's variance by batch means (else the Poisson
    estimate, see :func:`poisson_var_y`). ``intensity_cd`` is one luminous intensity (cd) for
    all sources or one per source. ``target_error`` (relative, e.g. 0.02) / ``time_budget_s``
    make each group progressive (module docstring); ``rays_per_source`` is then the cap, and
    each record says ``rounds`` and ``stop_reason``.
    """
    from ...trace.aiming import FieldPoint
    from ...trace.stream import Grid, StreamSource, stream
    obj = np.atleast_2d(np.asarray(obj, dtype=np.float64))
    inten = np.broadcast_to(np.asarray(intensity_cd, dtype=np.float64), (len(obj),))
    ids = list(range(len(obj))) if source_ids is None else [int(v) for v in source_ids]
    if len(ids) != len(obj):
        raise LensrtError(f"{len(ids)} source ids for {len(obj)} sources")

    def source_seed(k: int, r: int) -> int:
        key = [int(seed), ids[k]] if r == 0 else [int(seed), ids[k], r]
        return int(np.random.SeedSequence(key).generate_state(1)[0]) & 0x7FFFFFFF
    outs: list[SourceOut | None] = [None] * len(obj)
    wins: dict[int, tuple[int, int, int, int]] = {}
    for k in range(len(obj)):
        win = _window(footprint[k], frame) if boxes[k].area_mm2 > 0 else None
        if win is None:
            outs[k] = SourceOut(k, 0, 0, None, None, {"rays": 0, "reached_sensor": False,
                                                         "why": "no ray reaches the frame" if boxes[k].area_mm2 > 0
                                                         else "fully vignetted"})
        else:
            wins[k] = win
    # groups of sources (in order of window size) whose histograms fit the budget
    order = sorted(wins, key=lambda k: ((wins[k][1] - wins[k][0]) * (wins[k][3] - wins[k][2]), k))
    groups: list[list[int]] = []
    cur: list[int] = []
    wx = wy = 0
    mult = (batches + 1) if batch_noise else 1
    for k in order:
        nwx, nwy = max(wx, wins[k][1] - wins[k][0]), max(wy, wins[k][3] - wins[k][2])
        if cur and (len(cur) + 1) * nwx * nwy * 3 * 8 * mult > hist_budget_bytes:
            groups.append(cur)
            cur, nwx, nwy = [], wins[k][1] - wins[k][0], wins[k][3] - wins[k][2]
        cur.append(k)
        wx, wy = nwx, nwy
    if cur:
        groups.append(cur)
    spectrum, channels = light.spectrum(), light.channels()
    kappa_y = float(light.kappa[1])
    p = frame.pitch_mm
    for g, members in enumerate(groups):
        gx = max(wins[k][1] - wins[k][0] for k in members)
        gy = max(wins[k][3] - wins[k][2] for k in members)
        sources = []
        for j, k in enumerate(members):
            ix0, _, iy0, _ = wins[k]
            centre = (frame.x0_mm + (ix0 + 0.5 * gx) * p, frame.y0_mm + (iy0 + 0.5 * gy) * p)
            sources.append(StreamSource(FieldPoint(False, None, tuple(float(v) for v in obj[k])), boxes[k],
                                        float(plane_z_mm), centre, j, "isotropic", seed=source_seed(k, 0),
                                        rng_index=0))
        progressive = target_error is not None or time_budget_s is not None
        n_next = int(rays_per_source)
        if progressive:
            n_next = min(n_next, max(1 << 16, batches * 256))
        res, r, reason, t0 = None, 0, "rays", time.perf_counter()
        while True:
            if r:
                sources = [replace(src, seed=source_seed(k, r)) for src, k in zip(sources, members)]
            got = stream(lens, sources, Grid(gx, gy, p), max(batches, (n_next // batches) * batches), spectrum=spectrum,
                         channels=channels, sampler=sampler, seed=int(seed), batches=batches, precision=precision,
                         device=device, iris=iris, stop_radius_mm=stop_radius_mm, batch_histograms=batch_noise)
            res = got if res is None else _merge_rounds(res, got)
            r += 1
            if not progressive:
                break
            if target_error is not None:
                est = dict(stream_estimates(res), kappa_y=kappa_y)
                worst = max(_source_out(res, j, k, wins[k], obj[k], boxes[k], frame, light, float(inten[k]),
                                        batch_noise, 0.0, source_seed(k, 0), est).stats["noise_rms"]
                            for j, k in enumerate(members))
                if worst <= target_error:
                    reason = "target_error"
                    break
            n_next = min(res.rays_per_source, int(rays_per_source) - res.rays_per_source)  # double the total
            if time_budget_s is not None:
                rate = res.rays_per_source / max(time.perf_counter() - t0, 1e-9)
                n_next = min(n_next, int(0.8 * (time_budget_s - (time.perf_counter() - t0)) * rate))
                if n_next < batches * 64:
                    reason = "time_budget"
                    break
            if n_next < batches:
                reason = "rays"
                break
        share = res.seconds / len(members)
        est = dict(stream_estimates(res), kappa_y=kappa_y)
        for j, k in enumerate(members):
            outs[k] = _source_out(res, j, k, wins[k], obj[k], boxes[k], frame, light, float(inten[k]),
                                  batch_noise, share, source_seed(k, 0), est)
            if progressive:
                outs[k].stats.update({"rounds": r, "stop_reason": reason, "target_error": target_error,
                                      "time_budget_s": time_budget_s})
    return [o for o in outs if o is not None]


def poisson_var_y(y_raw: np.ndarray, rays_landed: int, kappa_y: float) -> np.ndarray:
    """Poisson estimate of the variance of each pixel's raw Y sum (same units as ``y_raw`` squared).

    A pixel's sum is ~Poisson(n) rays of weight w: Var = n E[w^2] = kappa E[w] * sum, with
    E[w] = (all landed Y weight) / (rays landed) and kappa = E[w^2] / E[w]^2 of the spectral
    sampling (:attr:`BokehLight.kappa`; the geometric weights of a point source vary by
    far less than that and are taken as constant). Assumes every pixel sees the source's
    mean spectrum: at strongly coloured rims it is approximate.
    """
    if rays_landed <= 0:
        return np.zeros_like(y_raw)
    mean_w = float(y_raw.sum()) / rays_landed
    return kappa_y * mean_w * y_raw


def _source_out(res, j: int, k: int, win: tuple[int, int, int, int], obj: np.ndarray, box, frame: Frame,
                light, intensity_cd: float, batch_noise: bool, seconds: float, seed: int, est: dict) -> SourceOut:
    """Source ``k`` (layer ``j`` of ``res``; ``est``: :func:`stream_estimates` of ``res`` and ``kappa_y``, the
    light's Poisson factor of Y) as a window in lux with its statistics."""
    ix0, ix1, iy0, iy1 = win
    gy, gx = res.histogram.shape[2], res.histogram.shape[3]
    raw = res.histogram[j]  # (3, gy, gx)
    n = res.rays_per_source
    dist = float(np.dot(np.asarray(box.centre) - obj, np.asarray(box.axis)))
    # lux per unit of raw weight: I_v / E[t_Y] x (box area / (rays dist^2) sr per unit geometric weight) / pixel area
    scale = intensity_cd / float(light.mean_t[1]) * box.area_mm2 / (n * dist * dist) / frame.pixel_area_m2
    counts = res.status_counts(j)
    landed = counts["OK"] - counts["OUTSIDE_GRID"]
    var_p = poisson_var_y(raw[1], landed, est["kappa_y"]) * scale * scale
    var_b = batch_xyz = None
    if batch_noise and res.batch_histograms is not None:
        bh = res.batch_histograms[j]  # (B, 3, gy, gx)
        var_b = bh.shape[0] * bh[:, 1].var(axis=0, ddof=1) * scale * scale
        batch_xyz = (bh * (scale * bh.shape[0])).astype(np.float32)
    xyz = raw * scale
    disc = _disc(xyz[1])
    noise_p, disc_px = disc_noise(xyz[1], var_p, disc)
    trans, trans_se = float(est["transmission"][j]), float(est["transmission_se"][j])
    a = float(res.pupil_area_mm2[j])
    area, area_se = trans * a, trans_se * a
    cen, cen_se = est["centroid"][j], est["centroid_se"][j]
    rms, rms_se = float(est["rms_radius"][j]), float(est["rms_radius_se"][j])
    sum_w = float(res.batch_stats[j][:, 1].sum())
    stats = {
        "rays": int(n), "reached_sensor": True, "seed": int(seed), "seconds": float(seconds),
        "intensity_cd": float(intensity_cd),
        "object_mm": [float(v) for v in obj], "distance_to_pupil_mm": dist,
        "pupil_box_mm2": float(box.area_mm2),
        "transmission": float(trans), "transmission_stderr": float(trans_se),
        "pupil_area_mm2": float(area), "pupil_area_stderr_mm2": float(area_se),
        "solid_angle_sr": float(area) / (dist * dist),
        "centroid_mm": [float(v) for v in cen], "centroid_stderr_mm": [float(v) for v in cen_se],
        "rms_radius_mm": float(rms), "rms_radius_stderr_mm": float(rms_se),
        "off_window_fraction": float(res.off_grid_weight(j).sum() / sum_w) if sum_w > 0 else 0.0,
        "luminous_flux_lm": float(xyz[1].sum() * frame.pixel_area_m2),
        "window_px": [int(ix0), int(iy0), int(gx), int(gy)],
        "disc_pixels": disc_px, "noise_poisson": noise_p, "status_counts": counts,
    }
    if var_b is not None:
        stats["noise_batch"] = disc_noise(xyz[1], var_b, disc)[0]
    stats["noise"] = stats["noise_batch"] if var_b is not None else noise_p
    stats["noise_method"] = (f"batch means over {res.batches} batches" if var_b is not None
                             else "Poisson estimate from the ray weights")
    var = var_b if var_b is not None else var_p
    stats["noise_rms"] = disc_noise_rms(xyz[1], var, disc)
    # the luminous flux in the window with its standard error: batch means over the batches' window
    # sums, else the Poisson variances of the pixels added up (independent counts)
    if batch_xyz is not None:
        flux_b = batch_xyz[:, 1].astype(np.float64).sum(axis=(1, 2)) * frame.pixel_area_m2
        stats["luminous_flux_stderr_lm"] = float(flux_b.std(ddof=1) / math.sqrt(len(flux_b)))
    else:
        stats["luminous_flux_stderr_lm"] = float(math.sqrt(max(float(var_p.sum()), 0.0)) * frame.pixel_area_m2)
    stats["solid_angle_stderr_sr"] = float(area_se) / (dist * dist)
    return SourceOut(k, ix0, iy0, xyz.astype(np.float32), var.astype(np.float32), stats, batch_xyz)
