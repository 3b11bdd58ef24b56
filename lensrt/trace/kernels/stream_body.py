"""The stream kernels' shared body: slots, seeds, the ray of a source, binning and the slot sums.

Used by BOTH stream kernels, the generic :func:`lensrt.trace.kernels.generic.trace_stream` and
the lens-specialised one (:func:`lensrt.trace.specialised.stream_kernel`); they differ only in
how they draw the samples (a run-time or a compile-time sampler) and trace the ray. The code
is branch-free (``wp.where``): every value is defined on every path, so a loop over rays keeps
no value of one ray alive into the next (see :mod:`lensrt.trace.specialised`). The contracts
(slots, seeds, fixed-point bins) are in :mod:`lensrt.trace.kernels`.

Kernel data: :class:`Histogram` (the bins and their layout), :class:`Slots` (which slots a
launch runs), :class:`SlotSums` (one slot's moments and counts). The source table keeps its
columns (:data:`lensrt.trace.kernels.SRC`, read here by name): a Warp struct has fields of
one concrete type, and the table's precision is the kernel's.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..status import GRAZING_COS, INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED
from . import FIXED_POINT_BITS, SRC
from .sampling import hash_u32

__all__ = ["Histogram", "Slots", "SlotSums", "slot_of", "batch_seeds", "hist_base", "ray_from_source",
           "pick_wavelength", "accumulate", "bin_ray", "store_slot"]

wp.set_module_options({"enable_backward": False})

FIXED_ONE = float(2**FIXED_POINT_BITS)
KIND, OX, OY, OZ, WX, WY, WZ = (SRC[k] for k in ("kind", "ox", "oy", "oz", "wx", "wy", "wz"))
E1X, E1Y, E1Z, E2X, E2Y, E2Z = (SRC[k] for k in ("e1x", "e1y", "e1z", "e2x", "e2y", "e2z"))
CX, CY, CZ, A0, A1, B0, B1, DIST = (SRC[k] for k in ("cx", "cy", "cz", "a0", "a1", "b0", "b1", "dist"))
GX0, GY0, LAYER, SX, SY, IDX, IDY, WSCALE = (SRC[k] for k in ("gx0", "gy0", "layer", "sx", "sy", "idx", "idy",
                                                               "wscale"))


@wp.struct
class Histogram:
    """The bins: ``bins[(((rep * n_layers + layer) * batches + batch % batches) * n_chan + c) * ny * nx
    + iy * nx + ix]`` (int64 fixed point)."""

    bins: wp.array(dtype=wp.int64)
    nx: int
    ny: int
    n_layers: int
    n_rep: int
    batches: int
    n_chan: int


@wp.struct
class Slots:
    """The slots of one launch: thread ``t`` runs slot ``t + tid_base`` of (source, batch) ``g``,
    rays ``start + q * slot_rays ..`` (< ``start + count``) of epoch ``epoch``."""

    epoch: int
    n_batches: int
    n_slots: int
    slot_rays: int
    start: int
    count: int
    n_strata: int
    n_wstrata: int
    tid_base: int
    rep_base: int


@wp.struct
class SlotSums:
    """One slot's sums (fixed order of addition): weighted moments of the OK rays (float64), counts."""

    sw: wp.float64
    swx: wp.float64
    swy: wp.float64
    swxx: wp.float64
    swyy: wp.float64
    swxy: wp.float64
    swg: wp.float64
    ok: int
    missed: int
    vignetted: int
    tir: int
    no_converge: int
    invalid: int
    outside: int
    grazing: int


@wp.func
def slot_of(tid: int, sl: Slots, h: Histogram):
    """Slot q of (source, batch), and the histogram replica of thread ``tid``."""
    q = tid % sl.n_slots
    g = tid // sl.n_slots
    return q, g // sl.n_batches, g % sl.n_batches, sl.rep_base + tid % h.n_rep


@wp.func
def batch_seeds(src_int: wp.array2d(dtype=wp.int32), src: int, sl: Slots, batch: int):
    """One independent randomisation per (source seed, source index, batch, epoch): the batch seed,
    the wavelength seed and the seed of Warp's generator."""
    bseed = hash_u32(wp.uint32(src_int[src, 0]) ^ hash_u32(wp.uint32(src_int[src, 1] * sl.n_batches + batch)
                                                           ^ hash_u32(wp.uint32(sl.epoch))))
    wseed = hash_u32(bseed ^ wp.uint32(0x68E31DA4))
    return bseed, wseed, int(bseed >> wp.uint32(1))


@wp.func
def hist_base(h: Histogram, sources: wp.array2d(dtype=Any), src: int, rep: int, batch: int) -> int:
    layer = int(sources[src, LAYER])
    return (((rep * h.n_layers + layer) * h.batches + batch % h.batches) * h.n_chan) * (h.nx * h.ny)


@wp.func
def ray_from_source(sources: wp.array2d(dtype=Any), src: int, u0: Any, u1: Any):
    """The ray through P = C + a e1 + b e2 ((a, b) uniform in the pupil box): along w (infinite
    object) or from the object point O, weight cos(theta_plane) (D / rho)^2 (x cos(theta_obj) for a
    Lambertian source), x the source's weight factor. Returns P, the direction, the weight."""
    kind = int(sources[src, KIND])
    pa = sources[src, A0] + u0 * (sources[src, A1] - sources[src, A0])
    pb = sources[src, B0] + u1 * (sources[src, B1] - sources[src, B0])
    px = sources[src, CX] + pa * sources[src, E1X] + pb * sources[src, E2X]
    py = sources[src, CY] + pa * sources[src, E1Y] + pb * sources[src, E2Y]
    pz = sources[src, CZ] + pa * sources[src, E1Z] + pb * sources[src, E2Z]
    wx = sources[src, WX]
    wy = sources[src, WY]
    wz = sources[src, WZ]
    vx = px - sources[src, OX]
    vy = py - sources[src, OY]
    vz = pz - sources[src, OZ]
    rho = wp.sqrt(vx * vx + vy * vy + vz * vz)
    point = kind != 0
    rs = wp.where(point, rho, type(u0)(1.0))
    dx = wp.where(point, vx / rs, wx)
    dy = wp.where(point, vy / rs, wy)
    dz = wp.where(point, vz / rs, wz)
    qq = sources[src, DIST] / rs
    weight = wp.where(point, (dx * wx + dy * wy + dz * wz) * qq * qq, type(u0)(1.0))
    weight = wp.where(kind == 1, weight * dz, weight) * sources[src, WSCALE]
    return px, py, pz, dx, dy, dz, weight


@wp.func
def pick_wavelength(uw: Any, table: int, nm: wp.array(dtype=Any), cdf: wp.array(dtype=Any), off: int, n: int):
    """The entry lo with cdf[lo] <= uw < cdf[lo + 1] of a spectrum's ``n`` entries from ``off``
    (:func:`lensrt.trace.kernels.sampling.sample_spectrum`): a line (``table`` != 0: returns its
    wavelength and index-table row) or a point uniform in a bin (row -1)."""
    lo = off
    hi = off + n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        below = cdf[mid] <= uw
        lo = wp.where(below, mid, lo)
        hi = wp.where(below, hi, mid)
    # (tables hold n + 1 entries per spectrum: lo + 1 is always in range)
    wl = nm[lo]
    width = cdf[lo + 1] - cdf[lo]
    f = wp.clamp((uw - cdf[lo]) / wp.where(width > type(uw)(0.0), width, type(uw)(1.0)), type(uw)(0.0), type(uw)(1.0))
    f = wp.where(width > type(uw)(0.0), f, type(uw)(0.5))
    return wp.where(table != 0, wl, wl + f * (nm[lo + 1] - wl)), wp.where(table != 0, lo, -1)


@wp.func
def accumulate(s: SlotSums, st: int, min_cos: Any, x: Any, y: Any, weight: Any,
               sources: wp.array2d(dtype=Any), src: int, h: Histogram):
    """``s`` with one ray added (its status; its weight and position when it is OK); returns the
    sums, whether the ray lands on the grid, and its fractional bin (fx, fy)."""
    ok = st == int(OK)
    s.ok = s.ok + wp.where(ok, 1, 0)
    s.grazing = s.grazing + wp.where(ok and min_cos < type(x)(GRAZING_COS), 1, 0)
    s.missed = s.missed + wp.where(st == int(MISSED), 1, 0)
    s.vignetted = s.vignetted + wp.where(st == int(VIGNETTED), 1, 0)
    s.tir = s.tir + wp.where(st == int(TIR), 1, 0)
    s.no_converge = s.no_converge + wp.where(st == int(NO_CONVERGE), 1, 0)
    s.invalid = s.invalid + wp.where(st == int(INVALID), 1, 0)
    xd = wp.float64(wp.where(ok, x - sources[src, SX], type(x)(0.0)))
    yd = wp.float64(wp.where(ok, y - sources[src, SY], type(x)(0.0)))
    wd = wp.float64(wp.where(ok, weight, type(x)(0.0)))
    s.sw = s.sw + wd
    s.swx = s.swx + wd * xd
    s.swy = s.swy + wd * yd
    s.swxx = s.swxx + wd * xd * xd
    s.swyy = s.swyy + wd * yd * yd
    s.swxy = s.swxy + wd * xd * yd
    fx = (x - sources[src, GX0]) * sources[src, IDX]
    fy = (y - sources[src, GY0]) * sources[src, IDY]
    on_grid = ok and fx >= type(x)(0.0) and fy >= type(x)(0.0) and fx < type(x)(h.nx) and fy < type(x)(h.ny)
    s.swg = s.swg + wp.where(on_grid, wd, wp.float64(0.0))
    s.outside = s.outside + wp.where(ok and not on_grid, 1, 0)
    return s, on_grid, fx, fy


@wp.func
def bin_ray(h: Histogram, base: int, fx: Any, fy: Any, weight: Any, wl: Any, channels: int,
            chan: wp.array2d(dtype=Any), chan_nm0: Any, chan_dnm: Any):
    """Add a ray on the grid to its bin (``base``: :func:`hist_base`): its weight, or with
    ``channels`` its weight times each channel's response at ``wl`` (linear between samples)."""
    plane_size = h.nx * h.ny
    b = base + int(fy) * h.nx + int(fx)
    if channels == 0:
        wp.atomic_add(h.bins, b, wp.int64(weight * type(weight)(FIXED_ONE) + type(weight)(0.5)))
    else:
        pos = (wl - chan_nm0) / chan_dnm
        g = chan.shape[1]
        if pos >= type(weight)(0.0) and pos <= type(weight)(g - 1):
            k0 = wp.min(int(pos), g - 2)
            fr = pos - type(weight)(k0)
            for c in range(h.n_chan):
                cw = chan[c, k0] * (type(weight)(1.0) - fr) + chan[c, k0 + 1] * fr
                v = weight * cw * type(weight)(FIXED_ONE) + type(weight)(0.5)
                if v >= type(weight)(1.0):
                    wp.atomic_add(h.bins, b + c * plane_size, wp.int64(v))


@wp.func
def store_slot(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), slot: int, s: SlotSums):
    """The slot's sums in the order of :data:`lensrt.trace.kernels.STAT_NAMES` and ``COUNT_NAMES``."""
    stats[slot, 0] = wp.float64(s.ok)
    stats[slot, 1] = s.sw
    stats[slot, 2] = s.swx
    stats[slot, 3] = s.swy
    stats[slot, 4] = s.swxx
    stats[slot, 5] = s.swyy
    stats[slot, 6] = s.swxy
    stats[slot, 7] = s.swg
    counts[slot, 0] = wp.int64(s.ok)
    counts[slot, 1] = wp.int64(s.missed)
    counts[slot, 2] = wp.int64(s.vignetted)
    counts[slot, 3] = wp.int64(s.tir)
    counts[slot, 4] = wp.int64(s.no_converge)
    counts[slot, 5] = wp.int64(s.invalid)
    counts[slot, 6] = wp.int64(s.outside)
    counts[slot, 7] = wp.int64(s.grazing)
