"""The trace kernels: one generic source, instantiated per precision (Warp ``wp.overload``).

Kernel variants (the complete list, to keep Warp compile time bounded): for
each precision in (float64, float32) one overload of each kernel of :mod:`.generic` (a small
Warp module per instance, :func:`module_names`), and of the store and stream kernels one per
lens variant -- :class:`~.surfaces.SymmetricLens` (coaxial refracting surfaces: the code for
mirrors, frames and surface apertures is left out at compile time) and
:class:`~.surfaces.GeneralLens`; :func:`lens_variant` picks by ``PackedLens.general``
(measured on an H100, generic kernel, 50 mm double Gauss: the symmetric variant traces
2.03e9 rays/s in float32 where one kernel with a run-time geometry branch traced 1.80e9;
``benchmarks/results/bench_trace_h100_lens_variant.txt``):

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
never compiles anything; the module compiles on first use and is cached on disk by Warp.

This package: the data layouts shared by host and device code (this file, no Warp
import), :mod:`.surfaces` and :mod:`.sampling` (generic ``@wp.func`` s),
:mod:`.stream_body` (the stream kernels' per-ray body, shared with the specialised
kernels), :mod:`.generic` (the kernels), :mod:`.boxes` (the pupil-box grid pass in one launch:
rays made, traced and reduced to per-field bounds on the device; and the bokeh sources' chief-ray
object-height search, one thread per source; its own module, float64), :mod:`.focus_grid` (the
best-focus search's grids: rays made, traced and reduced to per-job moment sums on the device, no
atomics; its own module, float64).

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
from __future__ import annotations

from functools import lru_cache
from types import SimpleNamespace

from ..status import STATUS_NAMES

__all__ = ["get_kernels", "lens_variant", "module_names", "FIXED_POINT_BITS", "SRC", "SRC_COLS", "SRC_INT", "SRC_INT_COLS", "N_STATS",
           "STAT_NAMES", "N_COUNTS", "COUNT_NAMES", "RAY_IN_COLS", "RAY_OUT_COLS", "N_RECORD", "NEWTON_TOL_F32_MM",
           "NEWTON_TOL_F64_MM"]

#: histogram weights are stored as round(weight * 2^FIXED_POINT_BITS) in int64
FIXED_POINT_BITS = 24
#: per-ray input columns of the store kernel: x y z L M N wavelength_nm
RAY_IN_COLS = 7
#: per-ray output columns: x y z(frame of the last surface met) L M N opl, smallest cos(incidence)
RAY_OUT_COLS = 8
#: values recorded per surface when a trace records: x y z(sag) L M N I I' length
N_RECORD = 9
#: Newton step (mm) that ends the iteration on an aspheric sag, per precision
NEWTON_TOL_F64_MM = 1e-12
NEWTON_TOL_F32_MM = 2e-6

#: columns of the host's stream source table (lensrt.trace.stream builds it from StreamSource s;
#: kernels.stream_body.source_array packs it into the kernels' Source struct)
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


def module_names(precision: str, *, store: bool = True, stream: bool = True, general: bool = True) -> list[str]:
    """The Warp modules holding the generic kernels of one precision (:func:`.generic.module_names`)."""
    get_kernels(precision)
    from .generic import module_names as names
    return names(precision, store=store, stream=stream, general=general)


@lru_cache(maxsize=None)
def get_kernels(precision: str) -> SimpleNamespace:
    """The generic kernels of one precision ('float64' or 'float32'): the ``wp.overload`` s of
    :mod:`.generic` (compiled on first launch)."""
    from ...device import warp
    warp()  # Warp configured (quiet) before the kernel module is imported
    from . import generic
    return generic.overloads(precision)


def lens_variant(kernels: SimpleNamespace, general: bool) -> tuple:
    """(store kernel, stream kernel, variant argument) of ``kernels`` (:func:`get_kernels`) for a
    rotationally symmetric lens or, with ``general``, one with mirrors, frames or surface apertures
    (``PackedLens.general``): the symmetric variant leaves the general code out at compile time."""
    from .surfaces import GeneralLens, SymmetricLens
    if general:
        return kernels.trace_store_general, kernels.trace_stream_general, GeneralLens()
    return kernels.trace_store, kernels.trace_stream, SymmetricLens()
