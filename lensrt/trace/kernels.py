"""The trace kernels, generated once per precision from one source.

Kernel variants (the complete list, to keep Warp compile time bounded): for
each precision in (float64, float32) one Warp module ``lensrt_trace_<precision>``
holding

* :func:`trace_store` -- *store* shape: one thread per ray, every ray's end state
  (position, direction, OPL, status, surface) and optionally the per-surface
  record (for ``lensrt ray``);
* :func:`trace_stream` -- *stream* shape: rays generated, traced and accumulated
  in the kernel, each thread looping over many rays, no per-ray storage;
* :func:`reduce_partial`, :func:`reduce_final` -- the per-thread stream slots summed on the
  device in two stages, each in a fixed order (parallel, deterministic);
* :func:`sample_square` -- the samplers alone, for tests.

The lens-specialised variants of the store and stream kernels live in
:mod:`.specialised` (one module per lens shape; :mod:`.variants` chooses).

Nothing depends on the lens shape (the surface loop is dynamic), so a new lens
never compiles anything; a module compiles on first use of its precision and is
cached on disk by Warp.

Stream accumulation is deterministic: histogram bins are int64 fixed point
(weight * 2^:data:`FIXED_POINT_BITS`) added with integer atomics, whose sum does not
depend on the order of the additions; moments and status counts are summed per
thread in a fixed order and written to per-thread slots, which the host reduces
in a fixed order. Same seed, same device, same inputs -> bit-identical results.
Histogram replicas (``rep = rep_base + tid % n_rep``) spread atomic traffic on
GPUs; on the CPU, where Warp's atomics are plain adds, each worker thread of
:func:`lensrt.trace.stream.stream` owns its replica (``tid_base``/``rep_base``
select its slice of threads), and the replicas are summed as integers.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations of the
# functions built below as objects (the scalar type ``real`` is a closure variable).

from functools import lru_cache
from types import SimpleNamespace
from .pack import real_dtype
from .sampling import sampling_funcs
from .status import GRAZING_COS, OK, STATUS_NAMES
from .surfaces import surface_funcs

__all__ = ["get_kernels", "module_name", "FIXED_POINT_BITS", "SRC", "SRC_COLS", "N_STATS", "STAT_NAMES",
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
           layer=24, sx=25, sy=26)
SRC_COLS = 28
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
     _DIST, _PLANE_DZ, _GX0, _GY0, _LAYER, _SX, _SY) = (SRC[k] for k in SRC)

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
                     n_surfaces: int, clip: int, sources: wp.array2d(dtype=real),
                     spec_mode: int, spec_nm: wp.array(dtype=real), spec_cdf: wp.array(dtype=real),
                     use_table: int, index_table: wp.array2d(dtype=real),
                     chan_mode: int, n_chan: int, chan: wp.array2d(dtype=real), chan_nm0: real, chan_dnm: real,
                     hist: wp.array(dtype=wp.int64), nx: int, ny: int, inv_dx: real, inv_dy: real,
                     n_layers: int, n_rep: int, hist_batches: int,
                     sampler: int, seed: int, epoch: int, n_batches: int, threads_per_batch: int,
                     start: int, count: int, n_strata: int,
                     tid_base: int, rep_base: int,
                     stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64),
                     rec: wp.array3d(dtype=real)):
        tid = wp.tid() + tid_base
        T = threads_per_batch
        src = tid // (n_batches * T)
        batch = (tid // T) % n_batches
        lane = tid % T
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
        # one independent randomisation per (seed, source, batch, epoch)
        bseed = sm.hash_u32(u32(seed) ^ sm.hash_u32(u32(src * n_batches + batch) ^ sm.hash_u32(u32(epoch))))
        wseed = sm.hash_u32(bseed ^ u32(0x68E31DA4))
        rseed = int(bseed >> u32(1))
        nsx = n_strata
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
        k = lane
        while k < count:
            i = start + k
            state = wp.rand_init(rseed, i)
            u0, u1, state = sm.unit_square(sampler, i, nsx, nsx, bseed, state)
            pa, pb, pdf = sm.box(u0, u1, a0, a1, b0, b1)
            uw = real(0.0)
            if sampler == 2:
                uw = sm.sobol_1d(u32(i), wseed)
            else:
                uw = real(wp.randf(state))
            wl, line, wl_pdf = sm.sample_cdf(uw, spec_mode, spec_nm, spec_cdf)
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
            weight = real(1.0)
            if kind != 0:
                vx = px - ox
                vy = py - oy
                vz = pz - oz
                rho = wp.sqrt(vx * vx + vy * vy + vz * vz)
                dx = vx / rho
                dy = vy / rho
                dz = vz / rho
                q = dist / rho
                weight = (dx * wx + dy * wy + dz * wz) * q * q
                if kind == 1:
                    weight = weight * dz
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
                        g = chan.shape[1]
                        if pos >= real(0.0) and pos <= real(g - 1):
                            k0 = wp.min(int(pos), g - 2)
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
            k = k + T
        stats[tid, 0] = n_ok
        stats[tid, 1] = sw
        stats[tid, 2] = swx
        stats[tid, 3] = swy
        stats[tid, 4] = swxx
        stats[tid, 5] = swyy
        stats[tid, 6] = swxy
        stats[tid, 7] = swg
        counts[tid, 0] = c_ok
        counts[tid, 1] = c_missed
        counts[tid, 2] = c_vig
        counts[tid, 3] = c_tir
        counts[tid, 4] = c_nc
        counts[tid, 5] = c_inv
        counts[tid, 6] = c_out
        counts[tid, 7] = c_graze

    @wp.kernel(module=mod, enable_backward=False)
    def reduce_threads(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), T: int,
                       out_stats: wp.array2d(dtype=wp.float64), out_counts: wp.array2d(dtype=wp.int64)):
        # one thread per (source, batch): sum its T threads' slots in a fixed order (deterministic)
        g = wp.tid()
        for j in range(N_STATS_C):
            acc = wp.float64(0.0)
            for t in range(T):
                acc = acc + stats[g * T + t, j]
            out_stats[g, j] = out_stats[g, j] + acc
        for j in range(N_COUNTS_C):
            c = wp.int64(0)
            for t in range(T):
                c = c + counts[g * T + t, j]
            out_counts[g, j] = out_counts[g, j] + c

    @wp.kernel(module=mod, enable_backward=False)
    def reduce_partial(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), T: int,
                       chunk: int, n_chunks: int, part_stats: wp.array3d(dtype=wp.float64),
                       part_counts: wp.array3d(dtype=wp.int64)):
        # stage 1 of the device reduction: one thread per (source-batch g, column j, chunk c) sums
        # the chunk's thread slots in a fixed order (deterministic, and parallel enough for a GPU)
        tid = wp.tid()
        c = tid % n_chunks
        j = (tid // n_chunks) % (N_STATS_C + N_COUNTS_C)
        g = tid // (n_chunks * (N_STATS_C + N_COUNTS_C))
        t0 = g * T + c * chunk
        t1 = g * T + wp.min(T, (c + 1) * chunk)
        if j < N_STATS_C:
            acc = wp.float64(0.0)
            for t in range(t0, t1):
                acc = acc + stats[t, j]
            part_stats[g, j, c] = acc
        else:
            cnt = wp.int64(0)
            for t in range(t0, t1):
                cnt = cnt + counts[t, j - N_STATS_C]
            part_counts[g, j - N_STATS_C, c] = cnt

    @wp.kernel(module=mod, enable_backward=False)
    def reduce_final(part_stats: wp.array3d(dtype=wp.float64), part_counts: wp.array3d(dtype=wp.int64),
                     n_chunks: int, out_stats: wp.array2d(dtype=wp.float64),
                     out_counts: wp.array2d(dtype=wp.int64)):
        # stage 2: one thread per (g, column) adds the chunks' sums in order, into the running totals
        tid = wp.tid()
        j = tid % (N_STATS_C + N_COUNTS_C)
        g = tid // (N_STATS_C + N_COUNTS_C)
        if j < N_STATS_C:
            acc = wp.float64(0.0)
            for c in range(n_chunks):
                acc = acc + part_stats[g, j, c]
            out_stats[g, j] = out_stats[g, j] + acc
        else:
            cnt = wp.int64(0)
            for c in range(n_chunks):
                cnt = cnt + part_counts[g, j - N_STATS_C, c]
            out_counts[g, j - N_STATS_C] = out_counts[g, j - N_STATS_C] + cnt

    @wp.kernel(module=mod, enable_backward=False)
    def sample_square(kind: int, n_strata: int, seed: int, out: wp.array2d(dtype=real)):
        i = wp.tid()
        bseed = sm.hash_u32(u32(seed))
        state = wp.rand_init(int(bseed >> u32(1)), i)
        u0, u1, state = sm.unit_square(kind, i, n_strata, n_strata, bseed, state)
        out[i, 0] = u0
        out[i, 1] = u1

    return SimpleNamespace(trace_store=trace_store, trace_stream=trace_stream, reduce_threads=reduce_threads,
                           reduce_partial=reduce_partial, reduce_final=reduce_final,
                           sample_square=sample_square,
                           real=real, module=mod, surfaces=sf, sampling=sm)
