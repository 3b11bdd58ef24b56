"""Stage 3: real rays through the lens, in Warp kernels (store and stream shapes), float64 and float32.

See :mod:`lensrt.trace.api` (store: every ray's end state), :mod:`lensrt.trace.stream`
(stream: rays generated, traced and accumulated in the kernel), :mod:`lensrt.trace.aiming`
(rays named by field and pupil coordinates), :mod:`lensrt.trace.reference` (the float64
oracle), :mod:`lensrt.trace.status` (ray status codes) and :mod:`lensrt.trace.preload` (the
Warp modules a job's calls will launch, compiled up front and side by side).
"""
from __future__ import annotations

from .api import RayBatch, RayResult, chief_ray, kernel_to_stop, make_rays, rays_from_pupil, trace
from .reverse import from_reversed, reversed_lens, to_reversed
from .status import INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED, RayStatus, count_statuses, describe_status

__all__ = ["RayBatch", "RayResult", "trace", "make_rays", "rays_from_pupil", "chief_ray", "kernel_to_stop",
           "RayStatus", "OK", "MISSED", "VIGNETTED", "TIR", "NO_CONVERGE", "INVALID", "count_statuses",
           "describe_status", "reversed_lens", "to_reversed", "from_reversed"]
