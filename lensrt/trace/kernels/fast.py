"""The shape-independent pieces of the lens-specialised trace (:mod:`lensrt.trace.specialised`).

Generic over the precision (``typing.Any`` arguments; ``lazy_div`` is a native snippet with one
overload per precision). The rearrangements against :mod:`.surfaces` are listed in the
docstring of :mod:`lensrt.trace.specialised`.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

__all__ = ["lazy_div", "quadric_t", "unit_near_one", "refract_unit"]

wp.set_module_options({"enable_backward": False})

_LAZY_DIV = """
    if (c) return a / b;
    return a - a;
"""


# lazy_div(c, a, b): a / b where c, else 0 -- a division that a warp skips when no thread needs
# it, without a Warp variable that only one branch defines (native snippet, one per precision)
@wp.func_native(_LAZY_DIV)
def lazy_div(c: bool, a: wp.float64, b: wp.float64) -> wp.float64:
    ...


@wp.func_native(_LAZY_DIV)
def lazy_div(c: bool, a: wp.float32, b: wp.float32) -> wp.float32:  # noqa: F811 -- a Warp overload
    ...


@wp.func
def quadric_t(c: Any, kp1: Any, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any):
    # the roots of surfaces.conic_t (t1 = F / q, t2 = q / A; the vertex-branch one; when both
    # are, the one where the ray crosses toward the surface's +z side: t1 when B >= 0);
    # q / A is divided out only where it is on the vertex branch
    F = c * (x * x + y * y) + c * kp1 * z * z - type(c)(2.0) * z
    B = N - c * (x * L + y * M + kp1 * z * N)
    A = c * (L * L + M * M + kp1 * N * N)
    disc = B * B - A * F
    real_roots = disc >= type(c)(0.0)
    root = wp.sqrt(wp.max(disc, type(c)(0.0)))
    q = wp.where(B < type(c)(0.0), B - root, B + root)
    u = c * kp1
    t1 = F / wp.where(q != type(c)(0.0), q, type(c)(1.0))
    v1 = real_roots and q != type(c)(0.0) and u * (z + t1 * N) < type(c)(1.0)
    lhs = u * (z * A + q * N)  # u (z + (q / A) N) < 1, multiplied by A
    v2 = real_roots and A != type(c)(0.0) and wp.where(A > type(c)(0.0), lhs < A, lhs > A)
    t2 = lazy_div(v2, q, A)
    use2 = v2 and ((not v1) or B < type(c)(0.0))
    t = wp.where(use2, t2, wp.where(v1, t1, type(c)(0.0)))
    return v1 or v2, t


@wp.func
def unit_near_one(x: Any, y: Any, z: Any):
    # (x, y, z) / |(x, y, z)| for |(x, y, z)| = 1 up to rounding: one Newton step from 1
    f = type(x)(1.5) - type(x)(0.5) * (x * x + y * y + z * z)
    return x * f, y * f, z * f


@wp.func
def refract_unit(L: Any, M: Any, N: Any, nx: Any, ny: Any, nz: Any, mu: Any):
    # surfaces.refract with the ratio mu = n1 / n2 given, no angles, the result renormalised
    # by unit_near_one; returns total internal reflection, L', M', N', min(cos I, cos I')
    ci = L * nx + M * ny + N * nz
    sg = wp.where(ci < type(L)(0.0), type(L)(-1.0), type(L)(1.0))
    cos_i = ci * sg
    k = type(L)(1.0) - mu * mu * (type(L)(1.0) - cos_i * cos_i)
    cos_r = wp.sqrt(wp.max(k, type(L)(0.0)))
    g = cos_r - mu * cos_i
    L2, M2, N2 = unit_near_one(mu * L + g * sg * nx, mu * M + g * sg * ny, mu * N + g * sg * nz)
    return k < type(L)(0.0), L2, M2, N2, wp.where(k < type(L)(0.0), cos_i, wp.min(cos_i, cos_r))
