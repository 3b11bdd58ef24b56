"""The ring of a reflex lens's defocused axial point from real rays: the oracle of the ring-bokeh tests.

In the meridional plane the rays from an axial point that pass the lens form one band of angles:
its lower edge grazes the central obscuration, its upper edge the stop. The two edge rays (float64
reference tracer, bisection to float64 resolution) land on the sensor at the ring's inner and
outer radius.
"""
from __future__ import annotations

import math

import numpy as np

from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

__all__ = ["edge_rays", "D_LINE_NM"]

D_LINE_NM = 587.6


def _ray(lens, source_mm: float, angle_rad: float):
    return trace_reference(lens, (0.0, 0.0, -source_mm), (0.0, math.sin(angle_rad), math.cos(angle_rad)),
                           D_LINE_NM)


def _edge(lens, source_mm: float, inside: float, outside: float) -> float:
    """The angle between a passing (``inside``) and a blocked (``outside``) ray where passing ends."""
    for _ in range(60):
        mid = 0.5 * (inside + outside)
        if _ray(lens, source_mm, mid).status == OK:
            inside = mid
        else:
            outside = mid
    return inside


def edge_rays(lens, source_mm: float) -> tuple[float, float, float, float]:
    """(inner angle, outer angle, inner sensor radius, outer sensor radius) of the passing band."""
    angles = np.linspace(0.0, math.atan(1.2 * lens.surfaces[0].semi_diameter_mm / source_mm), 241)
    ok = np.array([_ray(lens, source_mm, a).status == OK for a in angles])
    assert not ok[0] and ok.any(), "the axial ray is blocked and some ray passes"
    first, last = int(np.argmax(ok)), len(ok) - 1 - int(np.argmax(ok[::-1]))
    assert ok[first:last + 1].all(), "one band of passing angles"
    t_in = _edge(lens, source_mm, angles[first], angles[first - 1])
    t_out = _edge(lens, source_mm, angles[last], angles[last + 1])
    return t_in, t_out, _ray(lens, source_mm, t_in).y_mm, _ray(lens, source_mm, t_out).y_mm
