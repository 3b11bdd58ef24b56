"""Reference intersection with the surface kinds of :mod:`lensrt.prescription.shapes` (float64, one ray).

Newton's method in 3-D on f(t) = z(t) - sag(x(t), y(t)) along the ray (x, y, z) + t (L, M, N)
in the surface's vertex frame, with f'(t) = N - (dz/dx L + dz/dy M), started from the base
conic's root (:func:`~.ray_surface.conic_t`: the surface's own curvature and conic, the
y-section's for biconic and toroidal surfaces) or the vertex plane. It stops when a step is
below :data:`~.ray_surface.NEWTON_TOL_MM`; no convergence within
:data:`~.ray_surface.NEWTON_MAX_ITER` steps is ``NO_CONVERGE``, a point where the surface does
not exist ``MISSED``. The normal is (-dz/dx, -dz/dy, 1), normalised (toward +z).
"""
from __future__ import annotations

import math

from ..prescription.shapes import Profile, sag_grad
from .ray_surface import NEWTON_MAX_ITER, NEWTON_TOL_MM, conic_t
from .status import MISSED, NO_CONVERGE, OK

__all__ = ["intersect_profile"]


def intersect_profile(p: Profile, x: float, y: float, z: float, L: float, M: float, N: float,
                      tol_mm: float = NEWTON_TOL_MM) -> tuple[int, float, tuple[float, float, float]]:
    """``(status, t, unit_normal)`` of the ray with the surface ``p`` (module docstring)."""
    t = conic_t(p.c, 1.0 + p.k, x, y, z, L, M, N)
    if t is None:
        if N == 0.0:
            return MISSED, 0.0, (0.0, 0.0, 1.0)
        t = -z / N
    for _ in range(NEWTON_MAX_ITER):
        px, py, pz = x + t * L, y + t * M, z + t * N
        s = sag_grad(p, px, py)
        if s is None:
            return MISSED, 0.0, (0.0, 0.0, 1.0)
        df = N - (s[1] * L + s[2] * M)
        if df == 0.0:
            return NO_CONVERGE, 0.0, (0.0, 0.0, 1.0)
        dt = (pz - s[0]) / df
        t -= dt
        if abs(dt) <= tol_mm:
            s = sag_grad(p, x + t * L, y + t * M)
            if s is None:
                return MISSED, 0.0, (0.0, 0.0, 1.0)
            inv = 1.0 / math.sqrt(s[1] * s[1] + s[2] * s[2] + 1.0)
            return OK, t, (-s[1] * inv, -s[2] * inv, inv)
    return NO_CONVERGE, 0.0, (0.0, 0.0, 1.0)
