"""The surface ``@wp.func`` s, at their old address: they live in :mod:`lensrt.trace.kernels.surfaces`.

``surface_funcs`` (the former per-precision factory) gives them in a namespace; the functions
are generic (Warp instantiates them per precision), so its arguments are ignored.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from .kernels import N_RECORD, NEWTON_TOL_F32_MM, NEWTON_TOL_F64_MM
from .kernels.surfaces import (conic_t, inside_iris, intersect, medium_index, newton_tol_mm, refract, sag_slope,
                               trace_ray)

__all__ = ["surface_funcs", "NEWTON_TOL_F32_MM", "NEWTON_TOL_F64_MM", "N_RECORD", "medium_index", "conic_t",
           "sag_slope", "intersect", "refract", "inside_iris", "trace_ray", "newton_tol_mm"]


def surface_funcs(wp: Any = None, real: Any = None, module: str | None = None) -> SimpleNamespace:
    """The generic surface functions in a namespace (compatibility: every argument is ignored)."""
    return SimpleNamespace(medium_index=medium_index, conic_t=conic_t, sag_slope=sag_slope, intersect=intersect,
                           refract=refract, inside_iris=inside_iris, trace_ray=trace_ray)
