"""The trace kernels, generated once per precision from one source.

Kernel variants (the complete list, to keep Warp compile time bounded): for
each precision in (float64, float32) one Warp module ``lensrt_trace_<precision>``
holding

* :func:`trace_store` -- *store* shape: one thread per ray, every ray's end state
  (position, direction, OPL, status, surface) and optionally the per-surface
  record (for ``lensrt ray``);
* :func:`trace_stream` -- *stream* shape: rays generated, traced and accumulated
  in the kernel, each thread looping over many rays, no per-ray storage;
* :func:`fold_slots` -- the stream's per-slot sums added to running totals in slot order;
* :func:`sum_replicas` -- histogram replicas added on the device;
* :func:`sample_square` -- the samplers alone, for tests.

The lens-specialised variants of the store and stream kernels live in
:mod:`.specialised` (one module per lens shape; :mod:`.variants` chooses).

Nothing depends on the lens shape (the surface loop is dynamic), so a new lens
never compiles anything; a module compiles on first use of its precision and is
cached on disk by Warp.

Stream accumulation is deterministic: histogram bins are int64 fixed point
(weight * 2^:data:`FIXED_POINT_BITS`) added with integer atomics, whose sum does not
depend on the order of the additions. Moments and status counts are summed per
*slot*: a contiguous run of ``slot_rays`` rays of one (source, batch), traced by one
thread, whose sums start from zero -- so a slot's sums depend on its rays only. The
slots are then added one after another in slot order (:func:`fold_slots`), continuing
across launches. Slots never straddle launches, so the result is the same bits
whatever the launch split, the number of sources in the launch or the CPU worker
threads; it depends on the slot length (a function of the rays per batch only, unless
the caller fixes it). Same seed, same device, same inputs -> bit-identical results.
Histogram replicas (``rep = rep_base + tid % n_rep``) spread atomic traffic on
GPUs; on the CPU, where Warp's atomics are plain adds, each worker thread of
:func:`lensrt.trace.stream.stream` owns its replica (``tid_base``/``rep_base``
select its slice of threads); the replicas are summed as integers on the device.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations of the
# functions built below as objects (the scalar type ``real`` is a closure variable).

from functools import lru_cache
from types import SimpleNamespace
from .pack import real_dtype
from .sampling import sampling_funcs
from .status import GRAZING_COS, OK, STATUS_NAMES
from .surfaces import surface_funcs

__all__ = ["get_kernels", "module_name", "FIXED_POINT_BITS", "SRC", "SRC_COLS", "SRC_INT", "SRC_INT_COLS", "N_STATS",
           "STAT_NAMES",
           "N_COUNTS", "COUNT_NAMES", "RAY_IN_COLS", "RAY_OUT_COLS"]

#: histogram weights are stored as round(weight * 2^FIXED_POINT_BITS) in int64
FIXED_POINT_BITS = 24
#: per-ray input columns of the store kernel: x y z L M N wavelength_nm
RAY_IN_COLS = 7
#: per-ray output columns: x y z(frame of the last surface met) L M N opl, smallest cos(incidence)
RAY_OUT_COLS = 8

#: columns of a stream source row (see lensrt.trace.stream.StreamSource)
SRC = dict(kind=0, ox=1, oy=2, oz=3, wx=4, wy=5, wz=6, e1x=7, e1y=8, e1z=9, e2x=10, e2y=11, e2z=12,
           cx=13, cy=14, cz=15, a0=16, a1=17, b0=18, b1=19, dist=20, plane_dz=21, gx0=22, gy0=23,
           layer=24, sx=25, sy=26, idx=27, idy=28, wscale=29)
SRC_COLS = 30
#: integer columns of a stream source (``src_int``): random seed, index mixed into the seed, first entry
#: and number of lines/bins of its spectrum in the concatenated spectrum tables
SRC_INT = dict(seed=0, index=1, spec_off=2, spec_n=3)
SRC_INT_COLS = 4
#: per-thread moments of the stream kernel (float64): over OK rays at the plane,
#: weights w, positions relative to the source's (sx, sy)
STAT_NAMES = ("n_ok", "sum_w", "sum_wx", "sum_wy", "sum_wxx", "sum_wyy", "sum_wxy", "sum_w_grid")
N_STATS = len(STAT_NAMES)
#: per-thread counts: one per ray status, then OK rays that fell outside the grid, then OK rays
#: that met or left a surface at a grazing angle (> GRAZING_INCIDENCE_DEG, incidence or refraction)
COUNT_NAMES = STATUS_NAMES + ("OUTSIDE_GRID", "GRAZING")
N_COUNTS = len(COUNT_NAMES)


def module_name(precision: str) -> str:
    return f"lensrt_trace_{precision}"


@lru_cache(maxsize=None)
def get_kernels(precision: str) -> SimpleNamespace:
    """The kernels of one precision ('float64' or 'float32'), built on first call."""
    from ..device import warp
    wp = warp()
    real = real_dtype(wp, precision)
    mod = module_name(precision)
    wp.set_module_options({"enable_backward": False}, module=mod)
    sf = surface_funcs(wp, real, mod)
    sm = sampling_funcs(wp, real, mod)
    trace_ray = sf.trace_ray
    u32 = wp.uint32
    fixed_one = float(2**FIXED_POINT_BITS)
    N_STATS_C, N_COUNTS_C = N_STATS, N_COUNTS
    (_KIND, _OX, _OY, _OZ, _WX, _WY, _WZ, _E1X, _E1Y, _E1Z, _E2X, _E2Y, _E2Z, _CX, _CY, _CZ, _A0, _A1, _B0, _B1,
     _DIST, _PLANE_DZ, _GX0, _GY0, _LAYER, _SX, _SY, _IDX, _IDY, _WSCALE) = (SRC[k] for k in SRC)

    @wp.kernel(module=mod, enable_backward=False)
    def trace_store(surf: wp.array2d(dtype=real), media: wp.array2d(dtype=real), iris: wp.array(dtype=real),
                    n_surfaces: int, rays: wp.array2d(dtype=real), end: int, clip: int, plane_dz: real,
                    record: int, index_table: wp.array2d(dtype=real), ray_base: int,
                    out: wp.array2d(dtype=real), status: wp.array(dtype=wp.int32),
                    surface: wp.array(dtype=wp.int32), rec: wp.array3d(dtype=real)):
        r = wp.tid() + ray_base
        w_um = rays[r, 6] * real(1.0e-3)
        st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
            surf, media, iris, n_surfaces, rays[r, 0], rays[r, 1], rays[r, 2], rays[r, 3], rays[r, 4],
            rays[r, 5], w_um * w_um, index_table, -1, end, clip, plane_dz, record, rec, r)
        out[r, 0] = x
        out[r, 1] = y
        out[r, 2] = z
        out[r, 3] = L
        out[r, 4] = M
        out[r, 5] = N
        out[r, 6] = opl
        out[r, 7] = min_cos
        status[r] = st
        surface[r] = where

    @wp.kernel(module=mod, enable_backward=False)
    def trace_stream(surf: wp.array2d(dtype=real), media: wp.array2d(dtype=real), iris: wp.array(dtype=real),
                     n_surfaces: int, clip: int, sources: wp.array2d(dtype=real), src_int: wp.array2d(dtype=wp.int32),
                     spec_mode: int, spec_nm: wp.array(dtype=real), spec_cdf: wp.array(dtype=real),
                     use_table: int, index_table: wp.array2d(dtype=real),
                     chan_mode: int, n_chan: int, chan: wp.array2d(dtype=real), chan_nm0: real, chan_dnm: real,
                     hist: wp.array(dtype=wp.int64), nx: int, ny: int,
                     n_layers: int, n_rep: int, hist_batches: int,
                     sampler: int, epoch: int, n_batches: int, n_slots: int, slot_rays: int,
                     start: int, count: int, n_strata: int, n_wstrata: int,
                     tid_base: int, rep_base: int,
                     stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64),
                     rec: wp.array3d(dtype=real)):
        # one thread per slot: a contiguous run of slot_rays rays of one (source, batch); its sums
        # depend on those rays only, never on the launch split (module docstring)
        tid = wp.tid() + tid_base
        q = tid % n_slots
        g = tid // n_slots
        src = g // n_batches
        batch = g % n_batches
        rep = rep_base + tid % n_rep
        kind = int(sources[src, _KIND])
        ox = sources[src, _OX]
        oy = sources[src, _OY]
        oz = sources[src, _OZ]
        wx = sources[src, _WX]
        wy = sources[src, _WY]
        wz = sources[src, _WZ]
        e1x = sources[src, _E1X]
        e1y = sources[src, _E1Y]
        e1z = sources[src, _E1Z]
        e2x = sources[src, _E2X]
        e2y = sources[src, _E2Y]
        e2z = sources[src, _E2Z]
        cx = sources[src, _CX]
        cy = sources[src, _CY]
        cz = sources[src, _CZ]
        a0 = sources[src, _A0]
        a1 = sources[src, _A1]
        b0 = sources[src, _B0]
        b1 = sources[src, _B1]
        dist = sources[src, _DIST]
        plane_dz = sources[src, _PLANE_DZ]
        gx0 = sources[src, _GX0]
        gy0 = sources[src, _GY0]
        layer = int(sources[src, _LAYER])
        refx = sources[src, _SX]
        refy = sources[src, _SY]
        inv_dx = sources[src, _IDX]
        inv_dy = sources[src, _IDY]
        wscale = sources[src, _WSCALE]
        spec_off = src_int[src, 2]
        spec_n = src_int[src, 3]
        # one independent randomisation per (source seed, source index, batch, epoch)
        bseed = sm.hash_u32(u32(src_int[src, 0]) ^ sm.hash_u32(u32(src_int[src, 1] * n_batches + batch)
                                                               ^ sm.hash_u32(u32(epoch))))
        wseed = sm.hash_u32(bseed ^ u32(0x68E31DA4))
        rseed = int(bseed >> u32(1))
        nsx = n_strata
        n_cells = n_strata * n_strata
        n_strat = n_cells * n_wstrata
        plane_size = nx * ny
        # per-thread accumulators (fixed order of addition)
        n_ok = wp.float64(0.0)
        sw = wp.float64(0.0)
        swx = wp.float64(0.0)
        swy = wp.float64(0.0)
        swxx = wp.float64(0.0)
        swyy = wp.float64(0.0)
        swxy = wp.float64(0.0)
        swg = wp.float64(0.0)
        c_ok = wp.int64(0)
        c_missed = wp.int64(0)
        c_vig = wp.int64(0)
        c_tir = wp.int64(0)
        c_nc = wp.int64(0)
        c_inv = wp.int64(0)
        c_out = wp.int64(0)
        c_graze = wp.int64(0)
        k = q * slot_rays
        k_end = wp.min(k + slot_rays, count)
        while k < k_end:
            i = start + k
            state = wp.rand_init(rseed, i)
            # stratified: n_wstrata wavelength strata, each with an n_strata^2 jittered pupil grid
            cell = i
            if sampler == 1 and i < n_strat:
                cell = i % n_cells
            u0, u1, state = sm.unit_square(sampler, cell, nsx, nsx, bseed, state)
            pa, pb, pdf = sm.box(u0, u1, a0, a1, b0, b1)
            uw = real(0.0)
            if sampler == 2:
                uw = sm.sobol_1d(u32(i), wseed)
            else:
                uw = real(wp.randf(state))
                if sampler == 1 and i < n_strat:
                    uw = (real(i // n_cells) + uw) / real(n_wstrata)
            wl, line, wl_pdf = sm.sample_spectrum(uw, spec_mode, spec_nm, spec_cdf, spec_off, spec_n)
            row = int(-1)
            if use_table != 0:
                row = line
            # the ray: through P = C + a e1 + b e2, along w (infinite) or from the object point
            px = cx + pa * e1x + pb * e2x
            py = cy + pa * e1y + pb * e2y
            pz = cz + pa * e1z + pb * e2z
            dx = wx
            dy = wy
            dz = wz
            weight = wscale
            if kind != 0:
                vx = px - ox
                vy = py - oy
                vz = pz - oz
                rho = wp.sqrt(vx * vx + vy * vy + vz * vz)
                dx = vx / rho
                dy = vy / rho
                dz = vz / rho
                qd = dist / rho
                weight = (dx * wx + dy * wy + dz * wz) * qd * qd
                if kind == 1:
                    weight = weight * dz
                weight = weight * wscale
            w_um = wl * real(1.0e-3)
            st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
                surf, media, iris, n_surfaces, px, py, pz, dx, dy, dz, w_um * w_um, index_table, row,
                n_surfaces, clip, plane_dz, 0, rec, 0)
            if st == OK:
                c_ok = c_ok + wp.int64(1)
                if min_cos < real(GRAZING_COS):
                    c_graze = c_graze + wp.int64(1)
                xd = wp.float64(x - refx)
                yd = wp.float64(y - refy)
                wd = wp.float64(weight)
                n_ok = n_ok + wp.float64(1.0)
                sw = sw + wd
                swx = swx + wd * xd
                swy = swy + wd * yd
                swxx = swxx + wd * xd * xd
                swyy = swyy + wd * yd * yd
                swxy = swxy + wd * xd * yd
                fx = (x - gx0) * inv_dx
                fy = (y - gy0) * inv_dy
                if fx >= real(0.0) and fy >= real(0.0) and fx < real(nx) and fy < real(ny):
                    ix = int(fx)
                    iy = int(fy)
                    swg = swg + wd
                    hb = batch % hist_batches  # per-batch histograms when hist_batches = n_batches
                    base = (((rep * n_layers + layer) * hist_batches + hb) * n_chan) * plane_size + iy * nx + ix
                    if chan_mode == 0:
                        wp.atomic_add(hist, base, wp.int64(weight * real(fixed_one) + real(0.5)))
                    else:
                        pos = (wl - chan_nm0) / chan_dnm
                        gc = chan.shape[1]
                        if pos >= real(0.0) and pos <= real(gc - 1):
                            k0 = wp.min(int(pos), gc - 2)
                            f = pos - real(k0)
                            for c in range(n_chan):
                                cw = chan[c, k0] * (real(1.0) - f) + chan[c, k0 + 1] * f
                                v = weight * cw * real(fixed_one) + real(0.5)
                                if v >= real(1.0):
                                    wp.atomic_add(hist, base + c * plane_size, wp.int64(v))
                else:
                    c_out = c_out + wp.int64(1)
            elif st == 1:
                c_missed = c_missed + wp.int64(1)
            elif st == 2:
                c_vig = c_vig + wp.int64(1)
            elif st == 3:
                c_tir = c_tir + wp.int64(1)
            elif st == 4:
                c_nc = c_nc + wp.int64(1)
            else:
                c_inv = c_inv + wp.int64(1)
            k = k + 1
        slot = tid
        stats[slot, 0] = n_ok
        stats[slot, 1] = sw
        stats[slot, 2] = swx
        stats[slot, 3] = swy
        stats[slot, 4] = swxx
        stats[slot, 5] = swyy
        stats[slot, 6] = swxy
        stats[slot, 7] = swg
        counts[slot, 0] = c_ok
        counts[slot, 1] = c_missed
        counts[slot, 2] = c_vig
        counts[slot, 3] = c_tir
        counts[slot, 4] = c_nc
        counts[slot, 5] = c_inv
        counts[slot, 6] = c_out
        counts[slot, 7] = c_graze

    @wp.kernel(module=mod, enable_backward=False)
    def fold_slots(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), n_slots: int,
                   out_stats: wp.array2d(dtype=wp.float64), out_counts: wp.array2d(dtype=wp.int64)):
        # one thread per (source-batch g, column j): add the launch's slots to the running total one
        # after another, in slot order -- a sequential sum over all slots of the call, whatever the
        # launch split (deterministic)
        tid = wp.tid()
        j = tid % (N_STATS_C + N_COUNTS_C)
        g = tid // (N_STATS_C + N_COUNTS_C)
        if j < N_STATS_C:
            acc = out_stats[g, j]
            for q in range(n_slots):
                acc = acc + stats[g * n_slots + q, j]
            out_stats[g, j] = acc
        else:
            cnt = out_counts[g, j - N_STATS_C]
            for q in range(n_slots):
                cnt = cnt + counts[g * n_slots + q, j - N_STATS_C]
            out_counts[g, j - N_STATS_C] = cnt

    @wp.kernel(module=mod, enable_backward=False)
    def sum_replicas(hist: wp.array(dtype=wp.int64), n_rep: int, length: int, out: wp.array(dtype=wp.int64)):
        # the histogram replicas added on the device (integers: exact), so one copy comes to the host
        i = wp.tid()
        acc = wp.int64(0)
        for r in range(n_rep):
            acc = acc + hist[r * length + i]
        out[i] = acc

    @wp.kernel(module=mod, enable_backward=False)
    def sample_square(kind: int, n_strata: int, seed: int, out: wp.array2d(dtype=real)):
        i = wp.tid()
        bseed = sm.hash_u32(u32(seed))
        state = wp.rand_init(int(bseed >> u32(1)), i)
        u0, u1, state = sm.unit_square(kind, i, n_strata, n_strata, bseed, state)
        out[i, 0] = u0
        out[i, 1] = u1

    return SimpleNamespace(trace_store=trace_store, trace_stream=trace_stream, fold_slots=fold_slots,
                           sum_replicas=sum_replicas, sample_square=sample_square,
                           real=real, module=mod, surfaces=sf, sampling=sm)
