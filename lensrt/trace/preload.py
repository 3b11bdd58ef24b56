"""Plan which Warp kernel modules a job will launch, and compile them up front, side by side.

A job that knows its trace calls -- :class:`KernelNeed`: store or stream, precision, rays per call,
stream options -- gets from :func:`plan_modules` the Warp modules those calls will launch on a
device, with the choice the calls themselves make (:func:`lensrt.trace.variants.choose_kernel`:
on a GPU the lens-specialised kernel for calls of at least ``GPU_MIN_RAYS`` rays of a shape it can
unroll, else the generic instance of the lens's variant; on the CPU the generic one), and
:func:`preload` compiles them in background threads (:mod:`lensrt.core.compile_ahead`) while the
job starts. A module the plan missed still compiles on its first launch, as without a plan; a plan
entry the job does not launch costs a background compile and nothing else.

``lensrt report`` plans per lens and options (:mod:`lensrt.report.kernel_plan`); with an empty
Warp kernel cache its modules then compile concurrently from the start of the report instead of
one after another on the report's critical path (docs/guide/report-speed.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Any, Sequence

from ..core.compile_ahead import Preload, start
from ..prescription.model import Lens
from .sampling import sampler_code

__all__ = ["KernelNeed", "PlannedModule", "plan_modules", "preload", "host_packed"]

KINDS = ("store", "stream", "boxes", "focus_grid")


@dataclass(frozen=True)
class KernelNeed:
    """One kind of trace call a job will make.

    kind : {'store', 'stream', 'boxes', 'focus_grid'}
        :func:`lensrt.trace.trace` (every ray's end state), :func:`lensrt.trace.stream.stream`
        (histograms), the pupil-box grid pass on the device (:mod:`lensrt.trace.kernels.boxes`) or the
        best-focus grids on the device (:mod:`lensrt.trace.kernels.focus_grid`; both for rotationally
        symmetric lenses).
    precision : str
        'float64' or 'float32' (the boxes pass is float64).
    rays : int
        Rays of the call (a stream: sources x rays per source), which decides between the
        specialised and the generic kernel on a GPU.
    clip : bool
        Clear apertures clip (the shape the specialised kernel is built for).
    sampler, table, channels, histogram
        The stream's sampler name, whether its spectrum is discrete (an index table), whether it
        bins into spectral channels, and whether it bins at all (:class:`~.specialised.StreamOptions`).
    why : str
        What the call is for (shown in plans and logs).
    """

    kind: str
    precision: str = "float64"
    rays: int = 0
    clip: bool = True
    sampler: str = "sobol"
    table: bool = False
    channels: bool = False
    histogram: bool = True
    why: str = ""


@dataclass(frozen=True)
class PlannedModule:
    """A Warp module of a plan: its name, why it is there, the Warp ``Module`` object, and how to load it
    when not with Warp's ``force_load`` (``loader(device)``; e.g. :func:`~.specialised.ready`)."""

    name: str
    why: str
    module: Any = field(compare=False, repr=False)
    loader: Any = field(default=None, compare=False, repr=False)


def host_packed(lens: Lens, precision: str = "float64") -> Any:
    """The lens's kernel arrays on the host only (shape, constants, variant: no device upload)."""
    from .pack import PackedLens, pack_arrays
    return PackedLens(lens, precision, "host", None, None, None, *pack_arrays(lens, None, None))


def _modules_of(lens: Lens, device: str, need: KernelNeed) -> list[tuple[Any, Any]]:
    """The Warp modules that ``need``'s call launches on ``device``, each with its loader (None: Warp's)."""
    from .kernels import get_kernels, lens_variant
    from .specialised import DEFAULT_TUNING, GPU_TUNING, StreamOptions, ready, store_kernel, stream_kernel
    from .variants import choose_kernel, shape_and_constants
    if need.kind == "boxes":
        from .kernels.boxes import box_grid_pass_symmetric
        return [(box_grid_pass_symmetric.module, None)]
    if need.kind == "focus_grid":
        from .kernels.focus_grid import focus_grid_pass_symmetric
        return [(focus_grid_pass_symmetric.module, None)]
    gpu = device.startswith("cuda")
    packed = host_packed(lens, need.precision)  # shape and variant do not depend on the device
    shape, _ = shape_and_constants(packed, need.clip)
    k = get_kernels(need.precision)
    tuning = GPU_TUNING[need.precision] if gpu else DEFAULT_TUNING
    store, stream, _ = lens_variant(k, packed.general)
    if need.kind == "store":
        if choose_kernel("auto", device, shape, need.rays) == "specialised":
            spec = store_kernel(need.precision, shape, tuning)
            return [(spec.kernel.module, partial(ready, spec))]  # the way trace() loads it
        return [(store.module, None)]
    opts = StreamOptions(sampler_code(need.sampler), bool(need.table), bool(need.channels), bool(need.histogram))
    if choose_kernel("auto", device, shape, need.rays) == "specialised":
        spec = stream_kernel(need.precision, shape, opts, tuning)
        main = (spec.kernel.module, partial(ready, spec))  # the way stream() loads it
    else:
        main = (stream.module, None)
    return [main, (k.fold_slots.module, None)]  # fold_slots and sum_replicas share a module


def plan_modules(lens: Lens, device: str, needs: Sequence[KernelNeed]) -> list[PlannedModule]:
    """The Warp modules ``needs`` launch on ``device`` (a device name such as 'cpu' or 'cuda:0'; the
    plan is made on the host, nothing is allocated there), in the order of ``needs``, each once."""
    from ..errors import LensrtError
    out: dict[str, PlannedModule] = {}
    for need in needs:
        if need.kind not in KINDS:
            raise LensrtError(f"unknown kernel need {need.kind!r}", hint=f"use one of {', '.join(KINDS)}")
        for m, loader in _modules_of(lens, device, need):
            out.setdefault(m.name, PlannedModule(m.name, need.why or need.kind, m, loader))
    return list(out.values())


def preload(plan: Sequence[PlannedModule], device: str, workers: int | None = None) -> Preload:
    """Compile and load the plan's modules on ``device`` in background threads; returns at once
    (:class:`lensrt.core.compile_ahead.Preload`: ``wait()``, per-module ``loads``)."""
    return start([p.module for p in plan], device, workers, {p.module: p.loader for p in plan if p.loader})
