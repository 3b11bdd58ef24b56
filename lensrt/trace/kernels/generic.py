"""The generic trace kernels (package :mod:`lensrt.trace.kernels`): one source, a ``wp.overload`` per precision.

Kernels take ``typing.Any`` arrays and scalars (Warp generics); :func:`overloads` gives the
float32 or float64 instances, registered at import. The contracts (slots, determinism) are in
the package docstring.

Each (kernel, precision, lens variant) instance lives in its own small Warp module (a module
is Warp's unit of compilation and caching), named by :func:`module_names`: a job compiles only
the instances it launches, and several compile side by side (:mod:`lensrt.trace.preload`).
One module holding all of them took 11-12 s of NVRTC time on an H200 (38 s on a 2-core CPU),
on the critical path of a cold ``lensrt report``, which launches 3 of its 11 kernels.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from types import SimpleNamespace
from typing import Any

import numpy as np
import warp as wp

from . import N_COUNTS, N_STATS
from .sampling import hash_u32, sobol_1d, unit_square
from .stream_body import (SOURCE, Histogram, Slots, SlotSums, accumulate, batch_seeds, bin_ray, hist_base,
                          pick_wavelength, ray_from_source, slot_of, store_slot)
from .surfaces import GeneralLens, SymmetricLens, trace_ray, write_ray

__all__ = ["trace_store", "trace_stream", "generic_samples", "fold_slots", "sum_replicas", "sample_square", "overloads",
           "module_names", "sample_unit_square"]

def trace_store(surf: wp.array2d(dtype=Any), media: wp.array2d(dtype=Any), iris: wp.array(dtype=Any),
                n_surfaces: int, rays: wp.array2d(dtype=Any), end: int, clip: int, plane_dz: Any,
                record: int, index_table: wp.array2d(dtype=Any), ray_base: int,
                out: wp.array2d(dtype=Any), status: wp.array(dtype=wp.int32),
                surface: wp.array(dtype=wp.int32), rec: wp.array3d(dtype=Any), variant: Any):
    r = wp.tid() + ray_base
    w_um = rays[r, 6] * type(plane_dz)(1.0e-3)
    st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
        surf, media, iris, n_surfaces, rays[r, 0], rays[r, 1], rays[r, 2], rays[r, 3], rays[r, 4],
        rays[r, 5], w_um * w_um, index_table, -1, end, clip, plane_dz, record, rec, r, variant)
    write_ray(out, status, surface, r, st, where, x, y, z, L, M, N, opl, min_cos)


@wp.func
def generic_samples(sampler: int, i: int, sl: Slots, bseed: wp.uint32, wseed: wp.uint32, rseed: int, like: Any):
    """Ray i's pupil point (u0, u1) and wavelength sample uw, the sampler chosen at run time
    (stratified: n_wstrata wavelength strata, each with an n_strata^2 jittered pupil grid)."""
    n_cells = sl.n_strata * sl.n_strata
    strat = sampler == 1 and i < n_cells * sl.n_wstrata
    state = wp.rand_init(rseed, i)
    u0, u1, state = unit_square(sampler, wp.where(strat, i % n_cells, i), sl.n_strata, sl.n_strata, bseed, state,
                                like)
    uw = type(like)(0.0)
    if sampler == 2:
        uw = sobol_1d(wp.uint32(i), wseed, like)
    else:
        uw = type(like)(wp.randf(state))
        if strat:
            uw = (type(like)(i // n_cells) + uw) / type(like)(sl.n_wstrata)
    return u0, u1, uw


def trace_stream(surf: wp.array2d(dtype=Any), media: wp.array2d(dtype=Any), iris: wp.array(dtype=Any),
                 n_surfaces: int, clip: int, sources: wp.array(dtype=Any), src_int: wp.array2d(dtype=wp.int32),
                 spec_nm: wp.array(dtype=Any), spec_cdf: wp.array(dtype=Any), use_table: int,
                 index_table: wp.array2d(dtype=Any), chan_mode: int, chan: wp.array2d(dtype=Any), chan_nm0: Any,
                 chan_dnm: Any, sampler: int, h: Histogram, sl: Slots, stats: wp.array2d(dtype=wp.float64),
                 counts: wp.array2d(dtype=wp.int64), rec: wp.array3d(dtype=Any), variant: Any):
    # one thread per slot: a contiguous run of slot_rays rays of one (source, batch); its sums
    # depend on those rays only, never on the launch split (package docstring)
    tid = wp.tid() + sl.tid_base
    q, src, batch, rep = slot_of(tid, sl, h)
    bseed, wseed, rseed = batch_seeds(src_int, src, sl, batch)
    s = sources[src]
    base = hist_base(h, s, rep, batch)
    plane_dz = s.plane_dz_mm
    sums = SlotSums()
    k = q * sl.slot_rays
    k_end = wp.min(k + sl.slot_rays, sl.count)
    while k < k_end:
        i = sl.start + k
        u0, u1, uw = generic_samples(sampler, i, sl, bseed, wseed, rseed, chan_nm0)
        wl, row = pick_wavelength(uw, use_table, spec_nm, spec_cdf, src_int[src, 2], src_int[src, 3])
        px, py, pz, dx, dy, dz, weight = ray_from_source(s, u0, u1)
        w_um = wl * type(chan_nm0)(1.0e-3)
        st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
            surf, media, iris, n_surfaces, px, py, pz, dx, dy, dz, w_um * w_um, index_table, row,
            n_surfaces, clip, plane_dz, 0, rec, 0, variant)
        sums, on_grid, fx, fy = accumulate(sums, st, min_cos, x, y, weight, s, h)
        if on_grid:
            bin_ray(h, base, fx, fy, weight, wl, chan_mode, chan, chan_nm0, chan_dnm)
        k = k + 1
    store_slot(stats, counts, tid, sums)


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


def sum_replicas(hist: wp.array(dtype=wp.int64), n_rep: int, length: int, out: wp.array(dtype=wp.int64)):
    # the histogram replicas added on the device (integers: exact), so one copy comes to the host
    i = wp.tid()
    acc = wp.int64(0)
    for r in range(n_rep):
        acc = acc + hist[r * length + i]
    out[i] = acc


def sample_square(kind: int, n_strata: int, seed: int, out: wp.array2d(dtype=Any)):
    i = wp.tid()
    bseed = hash_u32(wp.uint32(seed))
    state = wp.rand_init(int(bseed >> wp.uint32(1)), i)
    u0, u1, state = unit_square(kind, i, n_strata, n_strata, bseed, state, type(out).dtype(0.0))
    out[i, 0] = u0
    out[i, 1] = u1


_REAL = {"float64": wp.float64, "float32": wp.float32}
#: the module of the kernels every stream call launches (whatever the precision) and of the sampler test kernel
_UTIL = f"{__name__}.util"


def _module(kind: str, precision: str, suffix: str) -> str:
    """Warp module of one (kernel, precision, lens variant) instance, e.g. ``...generic.stream_float32``."""
    return f"{__name__}.{kind}_{precision}{suffix}"


def _kernel(fn, module: str):
    """``fn`` as a Warp kernel of ``module`` (no adjoint code)."""
    wp.set_module_options({"enable_backward": False}, module=module)
    return wp.kernel(fn, module=module)


def _register(precision: str) -> SimpleNamespace:
    """The ``wp.overload`` s of the generic kernels for one precision: store and stream kernels per
    lens variant (``*_general`` for :class:`~.surfaces.GeneralLens`; :func:`lens_variant` picks),
    each in its own Warp module (module docstring)."""
    real = _REAL[precision]
    a1, a2, a3 = wp.array(dtype=real), wp.array2d(dtype=real), wp.array3d(dtype=real)
    sources = wp.array(dtype=SOURCE[precision])
    store_types = {"surf": a2, "media": a2, "iris": a1, "rays": a2, "plane_dz": real, "index_table": a2,
                   "out": a2, "rec": a3}
    stream_types = {"surf": a2, "media": a2, "iris": a1, "sources": sources, "spec_nm": a1, "spec_cdf": a1,
                    "index_table": a2, "chan": a2, "chan_nm0": real, "chan_dnm": real, "rec": a3}
    kern = {}
    for suffix, variant in (("", SymmetricLens), ("_general", GeneralLens)):
        for kind, fn, types in (("store", trace_store, store_types), ("stream", trace_stream, stream_types)):
            kern[f"trace_{kind}{suffix}"] = wp.overload(_kernel(fn, _module(kind, precision, suffix)),
                                                         {**types, "variant": variant})
    square = wp.overload(_SQUARE, {"out": a2})
    return SimpleNamespace(**kern, fold_slots=_FOLD, sum_replicas=_SUM, sample_square=square, real=real,
                           modules=module_names(precision))


def module_names(precision: str, *, store: bool = True, stream: bool = True, general: bool = True) -> list[str]:
    """The Warp modules of the generic kernels of one precision: store and stream instances (symmetric
    lens variant, and with ``general`` the general one), then the shared one (fold, replica sums)."""
    kinds = [k for k, on in (("store", store), ("stream", stream)) if on]
    suffixes = ["", "_general"] if general else [""]
    return [_module(k, precision, s) for s in suffixes for k in kinds] + [_UTIL]


_FOLD = _kernel(fold_slots, _UTIL)
_SUM = _kernel(sum_replicas, _UTIL)
_SQUARE = _kernel(sample_square, _UTIL)
_OVERLOADS = {precision: _register(precision) for precision in _REAL}


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
