"""The ``shape`` key of a native TOML surface: surface kinds beyond the conic + even asphere.

::

    [[surface]]
    radius_mm = 17.373
    conic = -0.676
    shape = { kind = "qbfs", norm_radius_mm = 27.0, coefficients = [-0.8148, -0.3231, 0.1059] }

``kind`` is one of :data:`lensrt.prescription.shapes.SHAPE_KINDS`; ``coefficients`` (odd: on
u^1, u^2, ...; qbfs/qcon: a_0, a_1, ... in mm), ``norm_radius_mm`` (default 1),
``curvature_x_per_mm`` or ``radius_x_mm`` (biconic x curvature, toroid's 1 / R_x; default 0 = flat
in x / a cylinder) and ``conic_x`` (biconic) as in :class:`~lensrt.prescription.shapes.SurfaceShape`.
A toroid's y-profile even terms are the surface's ``asphere`` table.
"""
from __future__ import annotations

import math
from typing import Any, Callable

from ...errors import PrescriptionError
from ..shapes import SurfaceShape

__all__ = ["SHAPE_KEYS", "read_shape", "write_shape"]

#: the keys a ``shape`` table may have
SHAPE_KEYS = ("kind", "coefficients", "norm_radius_mm", "curvature_x_per_mm", "radius_x_mm", "conic_x")


def read_shape(value: Any) -> SurfaceShape | None:
    """The :class:`SurfaceShape` of a surface's ``shape`` table (None when absent)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise PrescriptionError("shape must be a table like { kind = \"odd\", coefficients = [0.0, 1e-3] }")
    bad = sorted(set(value) - set(SHAPE_KEYS))
    if bad:
        raise PrescriptionError(f"unknown key {bad[0]!r} in shape", hint=f"use {', '.join(SHAPE_KEYS)}")
    if "kind" not in value:
        raise PrescriptionError("shape has no kind", hint="add kind = \"odd\" (or qbfs, qcon, biconic, toroidal)")
    if "curvature_x_per_mm" in value and "radius_x_mm" in value:
        raise PrescriptionError("give radius_x_mm or curvature_x_per_mm in shape, not both")
    coef = value.get("coefficients", [])
    if not isinstance(coef, list):
        raise PrescriptionError("shape coefficients must be a list of numbers")
    cx = value.get("curvature_x_per_mm", 0.0)
    if "radius_x_mm" in value:
        try:
            r = float(value["radius_x_mm"])
        except (TypeError, ValueError):
            raise PrescriptionError(f"radius_x_mm {value['radius_x_mm']!r} is not a number") from None
        if r == 0.0 or math.isnan(r):
            raise PrescriptionError(f"radius_x_mm = {r!r} is not a radius", hint="use inf for flat in x")
        cx = 0.0 if math.isinf(r) else 1.0 / r
    if not isinstance(value["kind"], str):
        raise PrescriptionError(f"shape kind {value['kind']!r} is not a name")
    return SurfaceShape(value["kind"], tuple(coef), value.get("norm_radius_mm", 1.0), cx, value.get("conic_x", 0.0))


def write_shape(shape: SurfaceShape | None, fmt: Callable[[float], str]) -> list[str]:
    """The ``shape = { ... }`` line of a surface (none when ``shape`` is None), numbers written by ``fmt``."""
    if shape is None:
        return []
    parts = [f"kind = \"{shape.kind}\""]
    if shape.coefficients:
        parts.append("coefficients = [" + ", ".join(fmt(a) for a in shape.coefficients) + "]")
    if shape.norm_radius_mm != 1.0:
        parts.append(f"norm_radius_mm = {fmt(shape.norm_radius_mm)}")
    if shape.curvature_x_per_mm != 0.0:
        parts.append(f"curvature_x_per_mm = {fmt(shape.curvature_x_per_mm)}")
    if shape.conic_x != 0.0:
        parts.append(f"conic_x = {fmt(shape.conic_x)}")
    return ["shape = { " + ", ".join(parts) + " }"]
