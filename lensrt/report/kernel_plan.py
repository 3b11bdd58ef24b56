"""The report's kernel plan: which Warp modules its sections will launch, compiled up front.

With an empty Warp kernel cache every module compiles on its first launch, one after another on
the report's critical path (on one H200: 12 of the lens section's 12.7 s, 24.5 s for the report
against 7.4-8.3 s warm). :func:`report_needs` lists the report's trace calls from its options --
the same ray counts, precisions and stream options the sections pass --, and
:func:`start_preload` plans them for the lens and device (:func:`lensrt.trace.preload.plan_modules`)
and starts compiling them in background threads as the report begins, so that they compile side by
side while the first sections run. A module the plan misses still compiles on first use.
``LENSRT_PRELOAD=0`` turns the plan off (every module then compiles on first use, as before);
``LENSRT_COMPILE_WORKERS`` sets the number of compiling threads.
"""
from __future__ import annotations

import os
from functools import partial
from typing import Any, Sequence

from ..core.compile_ahead import default_workers
from ..trace.preload import KernelNeed, PlannedModule, host_packed, plan_modules, preload
from .options import ReportOptions

__all__ = ["report_needs", "report_plan", "start_preload", "preload_enabled", "compile_order", "expected_compile_s",
           "BOKEH_SOURCES_PER_CALL"]

#: sources per stream call of the bokeh map (``bokeh_near_far``'s ``sources_per_item``)
BOKEH_SOURCES_PER_CALL = 32
#: sections that trace rays (aiming, pupil boxes, compare): every one needs the float64 store and stream kernels
_TRACING = ("lens", "first_order", "aberrations", "image_quality", "zoom", "psf", "mtf", "bokeh")


def preload_enabled() -> bool:
    """False when ``LENSRT_PRELOAD`` is ``0``/``off``/``no``/``false``."""
    return os.environ.get("LENSRT_PRELOAD", "1").strip().lower() not in ("0", "off", "no", "false")


def _bokeh_needs(q: Any, precision: str) -> list[KernelNeed]:
    """The bokeh map's streams: a near and a far source per grid cell, in calls of 32 sources."""
    total = 2 * q.bokeh_grid[0] * q.bokeh_grid[1]
    sizes = {min(BOKEH_SOURCES_PER_CALL, total - k) for k in range(0, total, BOKEH_SOURCES_PER_CALL)}
    return [KernelNeed("stream", precision, n * q.bokeh_rays, channels=True, why=f"bokeh map ({n} sources a call)")
            for n in sorted(sizes, reverse=True)]


def report_needs(options: ReportOptions, skip: Sequence[str] = (), symmetric: bool = True) -> list[KernelNeed]:
    """The trace calls of a report with ``options`` (``symmetric``: the lens takes the pupil-box pass on
    the device), in the order the sections first make them."""
    q = options.preset
    p = options.precision
    runs = [k for k in _TRACING if k not in skip]
    needs: list[KernelNeed] = []
    if runs:
        needs.append(KernelNeed("store", "float64", 1, why="aiming, layout, compare"))
        if symmetric:
            needs.append(KernelNeed("boxes", why="pupil boxes"))
            needs.append(KernelNeed("focus_grid", why="best-focus grids"))
        # compare: relative illumination and spot diagrams, a dozen field points / runs (far below the size
        # that takes the specialised kernel on a GPU in every preset)
        needs.append(KernelNeed("stream", "float64", 12 * q.compare_rays, table=True, why="compare: illumination"))
        needs.append(KernelNeed("stream", "float64", 12 * q.spot_rays, table=True, why="compare: spot diagrams"))
    if "psf" not in skip:
        n = q.psf_grid[0] * q.psf_grid[1]
        needs.append(KernelNeed("stream", p, n * q.psf_rays, table=True, why=f"PSF map ({n} fields)"))
    if "mtf" not in skip and q.mtf_method in ("geometric", "auto"):
        needs.append(KernelNeed("stream", p, q.mtf_fields * q.mtf_rays, table=True,
                                why=f"MTF, geometric ({q.mtf_fields} fields)"))
    if "bokeh" not in skip:
        needs.extend(_bokeh_needs(q, p))
    return needs


def report_plan(lens: Any, options: ReportOptions, device: str, skip: Sequence[str] = (),
                workers: int | None = None) -> list[PlannedModule]:
    """The Warp modules a report on ``lens`` with ``options`` launches on ``device``, in the order they are
    to be compiled by ``workers`` threads (default :func:`~lensrt.core.compile_ahead.default_workers`;
    :func:`compile_order`)."""
    symmetric = not host_packed(lens).general
    plan = plan_modules(lens, device, report_needs(options, skip, symmetric))
    from ..analysis.psf.bulk import analysis_on_device
    if "psf" not in skip and analysis_on_device(device):
        plan.extend(_psf_device_sums(device))
    return compile_order(plan, default_workers() if workers is None else workers)


#: modules the report's first sections launch within a second of its start (the lens section's aiming and
#: layout, the first-order section's pupil boxes): compiled first, whatever they cost
_FIRST = ("lensrt.trace.kernels.generic.store_float64", "lensrt.trace.kernels.boxes")
#: expected compile seconds by module name (its start), NVRTC for sm_90 on the project's 2-core build machine,
#: one module at a time (docs/guide/report-speed.md); only their order matters. The lens-specialised streams
#: (``lensrt_fast_stream_*``) are scaled from their load times on one H100 against ``store_float64``'s
_EXPECTED_COMPILE_S = (
    ("lensrt.analysis.psf.device_sums.second_pass", 5.3),
    ("lensrt.trace.kernels.focus_grid", 3.9),
    ("lensrt_fast_stream", 3.0),
    ("lensrt.trace.kernels.generic.stream_", 3.0),
    ("lensrt.trace.kernels.boxes", 2.4),
    ("lensrt.trace.kernels.generic.store_", 1.4),
    ("lensrt.trace.kernels.generic.util", 0.8),
    ("lensrt.analysis.psf.device_sums.first_pass", 0.7),
)


def expected_compile_s(name: str) -> float:
    """The expected compile seconds of module ``name`` (:data:`_EXPECTED_COMPILE_S`; 1.0 for a module not
    listed)."""
    return next((v for k, v in _EXPECTED_COMPILE_S if name.startswith(k)), 1.0)


def compile_order(plan: Sequence[PlannedModule], workers: int) -> list[PlannedModule]:
    """``plan`` (in the order the sections first launch its modules) in the order for ``workers`` threads to
    compile it. With a thread per module every load starts at once and the order is the order in which
    Warp's serialised code generation lets them through: the modules the first sections launch
    (:data:`_FIRST`) first, so that they never wait behind a long compile, then the others longest first, so
    that the last compile to end -- and the launch waiting for it -- ends as early as it can. With fewer
    threads the loads queue, and the plan keeps the order the sections need them in (a module still queued
    when a launch needs it is loaded by that launch: :func:`lensrt.core.compile_ahead.wait_for`)."""
    if workers < len(plan):
        return list(plan)
    first = [p for name in _FIRST for p in plan if p.name == name]
    rest = [p for p in plan if p.name not in _FIRST]
    return first + sorted(rest, key=lambda p: -expected_compile_s(p.name))


def _psf_device_sums(device: str) -> list[PlannedModule]:
    """The PSF map's analysis kernels on the device: two launches, each kernel a module of its own, the second
    with its own block size on a GPU (Warp's CPU runs blocks of one lane)."""
    from ..analysis.psf import device_sums
    from ..device import warp
    wp = warp()
    out = []
    for name, block in ((device_sums.FIRST_PASS_MODULE, None),
                        (device_sums.SECOND_PASS_MODULE, device_sums.SECOND_PASS_BLOCK)):
        m = wp.get_module(name)
        b = block if device.startswith("cuda") else None
        out.append(PlannedModule(m.name, "PSF map analysis on the device", m,
                                 partial(_force_load_block, wp, m, b)))
    return out


def _force_load_block(wp: Any, module: Any, block: int | None, device: str) -> None:
    """Load ``module`` on ``device`` at the block size of its launches (None: the module's default)."""
    wp.force_load(device=device, modules=[module], block_dim=block, max_workers=0)


def start_preload(lens: Any, options: ReportOptions, device: str, skip: Sequence[str] = ()):
    """Start compiling the report's plan in the background; returns ``(plan, Preload)``, or
    ``([], None)`` when preloading is off or the plan cannot be made (the report then compiles on use)."""
    if not preload_enabled():
        return [], None
    workers = default_workers()  # a bad LENSRT_COMPILE_WORKERS is the user's error: LensrtError, said once
    try:
        plan = report_plan(lens, options, device, skip, workers)
        return plan, preload(plan, device, workers)
    except Exception:  # noqa: BLE001 - a plan is an optimisation: any failure means compile-on-use
        return [], None
