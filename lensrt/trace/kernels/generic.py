"""The generic trace kernels (module :mod:`lensrt.trace.kernels`): one source, one ``wp.overload`` per precision.

Kernels take ``typing.Any`` arrays and scalars (Warp generics); :func:`overloads` gives the
float32 or float64 instances, registered at import. The contracts (slots, determinism) are in
the package docstring.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from types import SimpleNamespace
from typing import Any

import numpy as np
import warp as wp

from ..status import GRAZING_COS, OK
from . import FIXED_POINT_BITS, N_COUNTS, N_STATS, SRC
from .sampling import box, hash_u32, sample_spectrum, sobol_1d, unit_square
from .surfaces import trace_ray

__all__ = ["trace_store", "trace_stream", "fold_slots", "sum_replicas", "sample_square", "overloads",
           "sample_unit_square"]

wp.set_module_options({"enable_backward": False})

FIXED_ONE = float(2**FIXED_POINT_BITS)
(_KIND, _OX, _OY, _OZ, _WX, _WY, _WZ, _E1X, _E1Y, _E1Z, _E2X, _E2Y, _E2Z, _CX, _CY, _CZ, _A0, _A1, _B0, _B1,
 _DIST, _PLANE_DZ, _GX0, _GY0, _LAYER, _SX, _SY, _IDX, _IDY, _WSCALE) = (SRC[k] for k in SRC)


@wp.kernel
def trace_store(surf: wp.array2d(dtype=Any), media: wp.array2d(dtype=Any), iris: wp.array(dtype=Any),
                n_surfaces: int, rays: wp.array2d(dtype=Any), end: int, clip: int, plane_dz: Any,
                record: int, index_table: wp.array2d(dtype=Any), ray_base: int,
                out: wp.array2d(dtype=Any), status: wp.array(dtype=wp.int32),
                surface: wp.array(dtype=wp.int32), rec: wp.array3d(dtype=Any)):
    r = wp.tid() + ray_base
    w_um = rays[r, 6] * type(plane_dz)(1.0e-3)
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


@wp.kernel
def trace_stream(surf: wp.array2d(dtype=Any), media: wp.array2d(dtype=Any), iris: wp.array(dtype=Any),
                 n_surfaces: int, clip: int, sources: wp.array2d(dtype=Any), src_int: wp.array2d(dtype=wp.int32),
                 spec_mode: int, spec_nm: wp.array(dtype=Any), spec_cdf: wp.array(dtype=Any),
                 use_table: int, index_table: wp.array2d(dtype=Any),
                 chan_mode: int, n_chan: int, chan: wp.array2d(dtype=Any), chan_nm0: Any, chan_dnm: Any,
                 hist: wp.array(dtype=wp.int64), nx: int, ny: int,
                 n_layers: int, n_rep: int, hist_batches: int,
                 sampler: int, epoch: int, n_batches: int, n_slots: int, slot_rays: int,
                 start: int, count: int, n_strata: int, n_wstrata: int,
                 tid_base: int, rep_base: int,
                 stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64),
                 rec: wp.array3d(dtype=Any)):
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
    bseed = hash_u32(wp.uint32(src_int[src, 0]) ^ hash_u32(wp.uint32(src_int[src, 1] * n_batches + batch)
                                                           ^ hash_u32(wp.uint32(epoch))))
    wseed = hash_u32(bseed ^ wp.uint32(0x68E31DA4))
    rseed = int(bseed >> wp.uint32(1))
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
        u0, u1, state = unit_square(sampler, cell, nsx, nsx, bseed, state, chan_nm0)
        pa, pb, pdf = box(u0, u1, a0, a1, b0, b1)
        uw = type(chan_nm0)(0.0)
        if sampler == 2:
            uw = sobol_1d(wp.uint32(i), wseed, chan_nm0)
        else:
            uw = type(chan_nm0)(wp.randf(state))
            if sampler == 1 and i < n_strat:
                uw = (type(chan_nm0)(i // n_cells) + uw) / type(chan_nm0)(n_wstrata)
        wl, line, wl_pdf = sample_spectrum(uw, spec_mode, spec_nm, spec_cdf, spec_off, spec_n)
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
        w_um = wl * type(chan_nm0)(1.0e-3)
        st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
            surf, media, iris, n_surfaces, px, py, pz, dx, dy, dz, w_um * w_um, index_table, row,
            n_surfaces, clip, plane_dz, 0, rec, 0)
        if st == OK:
            c_ok = c_ok + wp.int64(1)
            if min_cos < type(chan_nm0)(GRAZING_COS):
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
            if fx >= type(chan_nm0)(0.0) and fy >= type(chan_nm0)(0.0) and fx < type(chan_nm0)(nx) and fy < type(chan_nm0)(ny):
                ix = int(fx)
                iy = int(fy)
                swg = swg + wd
                hb = batch % hist_batches  # per-batch histograms when hist_batches = n_batches
                base = (((rep * n_layers + layer) * hist_batches + hb) * n_chan) * plane_size + iy * nx + ix
                if chan_mode == 0:
                    wp.atomic_add(hist, base, wp.int64(weight * type(chan_nm0)(FIXED_ONE) + type(chan_nm0)(0.5)))
                else:
                    pos = (wl - chan_nm0) / chan_dnm
                    gc = chan.shape[1]
                    if pos >= type(chan_nm0)(0.0) and pos <= type(chan_nm0)(gc - 1):
                        k0 = wp.min(int(pos), gc - 2)
                        f = pos - type(chan_nm0)(k0)
                        for c in range(n_chan):
                            cw = chan[c, k0] * (type(chan_nm0)(1.0) - f) + chan[c, k0 + 1] * f
                            v = weight * cw * type(chan_nm0)(FIXED_ONE) + type(chan_nm0)(0.5)
                            if v >= type(chan_nm0)(1.0):
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


@wp.kernel
def fold_slots(stats: wp.array2d(dtype=wp.float64), counts: wp.array2d(dtype=wp.int64), n_slots: int,
               out_stats: wp.array2d(dtype=wp.float64), out_counts: wp.array2d(dtype=wp.int64)):
    # one thread per (source-batch g, column j): add the launch's slots to the running total one
    # after another, in slot order -- a sequential sum over all slots of the call, whatever the
    # launch split (deterministic)
    tid = wp.tid()
    j = tid % (N_STATS + N_COUNTS)
    g = tid // (N_STATS + N_COUNTS)
    if j < N_STATS:
        acc = out_stats[g, j]
        for q in range(n_slots):
            acc = acc + stats[g * n_slots + q, j]
        out_stats[g, j] = acc
    else:
        cnt = out_counts[g, j - N_STATS]
        for q in range(n_slots):
            cnt = cnt + counts[g * n_slots + q, j - N_STATS]
        out_counts[g, j - N_STATS] = cnt


@wp.kernel
def sum_replicas(hist: wp.array(dtype=wp.int64), n_rep: int, length: int, out: wp.array(dtype=wp.int64)):
    # the histogram replicas added on the device (integers: exact), so one copy comes to the host
    i = wp.tid()
    acc = wp.int64(0)
    for r in range(n_rep):
        acc = acc + hist[r * length + i]
    out[i] = acc


@wp.kernel
def sample_square(kind: int, n_strata: int, seed: int, out: wp.array2d(dtype=Any)):
    i = wp.tid()
    bseed = hash_u32(wp.uint32(seed))
    state = wp.rand_init(int(bseed >> wp.uint32(1)), i)
    u0, u1, state = unit_square(kind, i, n_strata, n_strata, bseed, state, type(out).dtype(0.0))
    out[i, 0] = u0
    out[i, 1] = u1


_REAL = {"float64": wp.float64, "float32": wp.float32}


def _register(real) -> SimpleNamespace:
    """The ``wp.overload`` s of the generic kernels for scalar type ``real``."""
    a1, a2, a3 = wp.array(dtype=real), wp.array2d(dtype=real), wp.array3d(dtype=real)
    store = wp.overload(trace_store, {"surf": a2, "media": a2, "iris": a1, "rays": a2, "plane_dz": real,
                                      "index_table": a2, "out": a2, "rec": a3})
    stream = wp.overload(trace_stream, {"surf": a2, "media": a2, "iris": a1, "sources": a2, "spec_nm": a1,
                                        "spec_cdf": a1, "index_table": a2, "chan": a2, "chan_nm0": real,
                                        "chan_dnm": real, "rec": a3})
    square = wp.overload(sample_square, {"out": a2})
    return SimpleNamespace(trace_store=store, trace_stream=stream, fold_slots=fold_slots, sum_replicas=sum_replicas,
                           sample_square=square, real=real, module="lensrt.trace.kernels.generic")


_OVERLOADS = {name: _register(real) for name, real in _REAL.items()}


def overloads(precision: str) -> SimpleNamespace:
    """The kernels of one precision ('float64' or 'float32')."""
    return _OVERLOADS[precision]


def sample_unit_square(sampler: str, n: int, seed: int = 0, precision: str = "float64",
                       device: str | None = None) -> np.ndarray:
    """The first ``n`` points (n, 2) of ``sampler`` with ``seed``, computed by the kernel code (for tests)."""
    from ...device import resolve_device
    from ..sampling import sampler_code
    dev = resolve_device(device)
    k = overloads(precision)
    out = wp.zeros((n, 2), dtype=k.real, device=dev)
    wp.launch(k.sample_square, dim=n, device=dev,
              inputs=[sampler_code(sampler), int(np.sqrt(n)), int(seed) & 0x7FFFFFFF, out])
    return out.numpy().astype(np.float64)
