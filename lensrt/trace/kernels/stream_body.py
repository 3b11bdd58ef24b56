"""The stream kernels' shared body: slots, seeds, the ray of a source, binning and the slot sums.

Used by BOTH stream kernels, the generic :func:`lensrt.trace.kernels.generic.trace_stream` and
the lens-specialised one (:func:`lensrt.trace.specialised.stream_kernel`); they differ only in
how they draw the samples (a run-time or a compile-time sampler) and trace the ray. The code
is branch-free (``wp.where``): every value is defined on every path, so a loop over rays keeps
no value of one ray alive into the next (see :mod:`lensrt.trace.specialised`). The contracts
(slots, seeds, fixed-point bins) are in :mod:`lensrt.trace.kernels`.

Kernel data are structs: ``Source`` (one stream source; :data:`SOURCE` holds it per precision,
as a Warp struct's fields have concrete types), :class:`Histogram` (the bins and their layout),
:class:`Slots` (which slots a launch runs), :class:`SlotSums` (one slot's moments and counts).
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import numpy as np
import warp as wp

from ..status import GRAZING_COS, INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED
from . import FIXED_POINT_BITS, SRC
from .sampling import hash_u32

__all__ = ["SOURCE", "source_array", "Histogram", "Slots", "SlotSums", "slot_of", "batch_seeds", "hist_base",
           "ray_from_source", "pick_wavelength", "accumulate", "bin_ray", "store_slot"]

wp.set_module_options({"enable_backward": False})

FIXED_ONE = float(2**FIXED_POINT_BITS)


def _source_struct(real):
    """The ``Source`` struct in precision ``real``."""
    vec2, vec3, vec4 = (wp.types.vector(length=n, dtype=real) for n in (2, 3, 4))

    @wp.struct
    class Source:
        """One stream source as the kernels read it (host side: :class:`lensrt.trace.stream.StreamSource`)."""

        kind: int           # 0 infinite object (collimated beam), 1 Lambertian point, 2 isotropic point
        layer: int          # histogram layer
        origin_mm: vec3     # the object point O
        axis: vec3          # the beam direction, normal of the pupil-box plane, w
        e1: vec3            # the pupil box's axes ...
        e2: vec3
        centre_mm: vec3     # ... and its centre C
        box: vec4           # a0 a1 b0 b1: the box, mm along e1 and e2
        dist_mm: real       # D = (C - O) . w (0 for an infinite object)
        plane_dz_mm: real   # the detection plane's distance behind the image surface
        grid0_mm: vec2      # the grid's corner (x0, y0)
        ref_mm: vec2        # the moments' reference point (the grid centre)
        inv_pixel: vec2     # 1 / bin size (1/mm)
        weight: real        # factor on every ray weight

    return Source


#: the Source struct per precision
SOURCE = {"float32": _source_struct(wp.float32), "float64": _source_struct(wp.float64)}
#: Source fields <- columns of the host's source table (:data:`lensrt.trace.kernels.SRC`)
_FIELDS = {"kind": ("kind",), "layer": ("layer",), "origin_mm": ("ox", "oy", "oz"), "axis": ("wx", "wy", "wz"),
           "e1": ("e1x", "e1y", "e1z"), "e2": ("e2x", "e2y", "e2z"), "centre_mm": ("cx", "cy", "cz"),
           "box": ("a0", "a1", "b0", "b1"), "dist_mm": ("dist",), "plane_dz_mm": ("plane_dz",),
           "grid0_mm": ("gx0", "gy0"), "ref_mm": ("sx", "sy"), "inv_pixel": ("idx", "idy"), "weight": ("wscale",)}


def source_array(rows: np.ndarray, precision: str, device: str):
    """The sources as a device array of ``SOURCE[precision]`` from the host table ``rows``
    (:data:`lensrt.trace.kernels.SRC` columns, float64; rounded to the precision as an array of it is)."""
    struct = SOURCE[precision]
    out = np.zeros(len(rows), dtype=struct.numpy_dtype())
    for name, cols in _FIELDS.items():
        v = rows[:, [SRC[c] for c in cols]]
        out[name] = v[:, 0] if len(cols) == 1 else v
    return wp.array(out, dtype=struct, device=device)


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
def hist_base(h: Histogram, s: Any, rep: int, batch: int) -> int:
    """The first bin of source ``s``'s histogram layer for ``batch`` in replica ``rep``."""
    return (((rep * h.n_layers + s.layer) * h.batches + batch % h.batches) * h.n_chan) * (h.nx * h.ny)


@wp.func
def ray_from_source(s: Any, u0: Any, u1: Any):
    """The ray through P = C + a e1 + b e2 ((a, b) uniform in the pupil box): along w (infinite
    object) or from the object point O, weight cos(theta_plane) (D / rho)^2 (x cos(theta_obj) for a
    Lambertian source), x the source's weight factor. Returns P, the direction, the weight."""
    pa = s.box[0] + u0 * (s.box[1] - s.box[0])
    pb = s.box[2] + u1 * (s.box[3] - s.box[2])
    px = s.centre_mm[0] + pa * s.e1[0] + pb * s.e2[0]
    py = s.centre_mm[1] + pa * s.e1[1] + pb * s.e2[1]
    pz = s.centre_mm[2] + pa * s.e1[2] + pb * s.e2[2]
    wx = s.axis[0]
    wy = s.axis[1]
    wz = s.axis[2]
    vx = px - s.origin_mm[0]
    vy = py - s.origin_mm[1]
    vz = pz - s.origin_mm[2]
    rho = wp.sqrt(vx * vx + vy * vy + vz * vz)
    point = s.kind != 0
    rs = wp.where(point, rho, type(u0)(1.0))
    dx = wp.where(point, vx / rs, wx)
    dy = wp.where(point, vy / rs, wy)
    dz = wp.where(point, vz / rs, wz)
    qq = s.dist_mm / rs
    weight = wp.where(point, (dx * wx + dy * wy + dz * wz) * qq * qq, type(u0)(1.0))
    weight = wp.where(s.kind == 1, weight * dz, weight) * s.weight
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
def accumulate(sums: SlotSums, st: int, min_cos: Any, x: Any, y: Any, weight: Any, s: Any, h: Histogram):
    """``sums`` with one ray of source ``s`` added (its status; its weight and position when it is OK); returns the
    sums, whether the ray lands on the grid, and its fractional bin (fx, fy)."""
    ok = st == int(OK)
    sums.ok = sums.ok + wp.where(ok, 1, 0)
    sums.grazing = sums.grazing + wp.where(ok and min_cos < type(x)(GRAZING_COS), 1, 0)
    sums.missed = sums.missed + wp.where(st == int(MISSED), 1, 0)
    sums.vignetted = sums.vignetted + wp.where(st == int(VIGNETTED), 1, 0)
    sums.tir = sums.tir + wp.where(st == int(TIR), 1, 0)
    sums.no_converge = sums.no_converge + wp.where(st == int(NO_CONVERGE), 1, 0)
    sums.invalid = sums.invalid + wp.where(st == int(INVALID), 1, 0)
    xd = wp.float64(wp.where(ok, x - s.ref_mm[0], type(x)(0.0)))
    yd = wp.float64(wp.where(ok, y - s.ref_mm[1], type(x)(0.0)))
    wd = wp.float64(wp.where(ok, weight, type(x)(0.0)))
    sums.sw = sums.sw + wd
    sums.swx = sums.swx + wd * xd
    sums.swy = sums.swy + wd * yd
    sums.swxx = sums.swxx + wd * xd * xd
    sums.swyy = sums.swyy + wd * yd * yd
    sums.swxy = sums.swxy + wd * xd * yd
    fx = (x - s.grid0_mm[0]) * s.inv_pixel[0]
    fy = (y - s.grid0_mm[1]) * s.inv_pixel[1]
    on_grid = ok and fx >= type(x)(0.0) and fy >= type(x)(0.0) and fx < type(x)(h.nx) and fy < type(x)(h.ny)
    sums.swg = sums.swg + wp.where(on_grid, wd, wp.float64(0.0))
    sums.outside = sums.outside + wp.where(ok and not on_grid, 1, 0)
    return sums, on_grid, fx, fy


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
def store_slot(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), slot: int, sums: SlotSums):
    """The slot's sums in the order of :data:`lensrt.trace.kernels.STAT_NAMES` and ``COUNT_NAMES``."""
    stats[slot, 0] = wp.float64(sums.ok)
    stats[slot, 1] = sums.sw
    stats[slot, 2] = sums.swx
    stats[slot, 3] = sums.swy
    stats[slot, 4] = sums.swxx
    stats[slot, 5] = sums.swyy
    stats[slot, 6] = sums.swxy
    stats[slot, 7] = sums.swg
    counts[slot, 0] = wp.int64(sums.ok)
    counts[slot, 1] = wp.int64(sums.missed)
    counts[slot, 2] = wp.int64(sums.vignetted)
    counts[slot, 3] = wp.int64(sums.tir)
    counts[slot, 4] = wp.int64(sums.no_converge)
    counts[slot, 5] = wp.int64(sums.invalid)
    counts[slot, 6] = wp.int64(sums.outside)
    counts[slot, 7] = wp.int64(sums.grazing)
