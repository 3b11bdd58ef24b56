"""The reference real-ray tracer: one ray at a time, float64, plain Python ``math``.

This is the oracle the Warp kernels are tested against, written to be read
beside the Field Guide (p. 1-4) rather than to be fast. Each surface is met in
its own vertex frame (x, y as in the lens frame, z measured from the vertex),
which keeps every coordinate small.

Intersection with the conic ``c r^2 + c (1 + k) z^2 - 2 z = 0`` (the implicit
form of the sag ``z = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2))``): a ray
``P + t d`` gives ``A t^2 - 2 B t + F = 0`` with

    F = c (x^2 + y^2) + c (1 + k) z^2 - 2 z
    B = N - c (x L + y M + (1 + k) z N)
    A = c (L^2 + M^2 + (1 + k) N^2)

and its roots in the form that does not cancel as c -> 0 (a plane: t = -z / N)
or for long transfers (Spencer & Murty, JOSA 52, 672, 1962; Welford,
*Aberrations of Optical Systems*, 4.3; Press et al., *Numerical Recipes* 5.6):

    q = B + sign(B) sqrt(B^2 - A F),   t1 = F / q,   t2 = q / A,

keeping the one on the vertex branch (1 - c (1 + k) z > 0: the half of a sphere
or ellipsoid that holds the vertex; when both qualify, the one where the ray
crosses toward the surface's +z side, see :func:`conic_t`).

An even asphere is met by Newton's method on the sag, started from the base
conic's intersection; no convergence within :data:`NEWTON_MAX_ITER` steps is
the status ``NO_CONVERGE``. Refraction is the vector form of Snell's law
n' sin I' = n sin I (p. 1):

    d' = mu d + (cos I' - mu cos I) n_hat,   mu = n / n',
    cos I' = sqrt(1 - mu^2 (1 - cos^2 I)),

and a negative radicand is total internal reflection (``TIR``).

A sequential ray crosses every surface from the medium before it to the medium
after it: toward the surface's +z side (d . n >= 0 with the normal n toward
+z). A ray that could meet a surface only from behind -- a beam from beyond
90 deg that would have to pass the lens backwards, or a ray that crossed the
surface's far branch first -- is ``MISSED`` there. Segments may still run
backwards (t < 0: a stop plane inside a surface's sag, an image plane in front
of the last vertex): that is the usual virtual propagation of sequential tracers.

A ray's optical path length is counted from its origin; :mod:`.aiming`
places origins on the object-space wavefront through the first vertex.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..prescription.model import Iris
from .status import APERTURE_TOLERANCE, MISSED, NO_CONVERGE, OK, TIR

__all__ = ["NEWTON_MAX_ITER", "NEWTON_TOL_MM", "SurfaceHit", "ReferenceRay", "intersect", "refract", "reflect",
           "ideal_lens", "inside_iris", "sag_and_slope", "conic_t"]

#: Newton iterations allowed on an aspheric sag, and the step (mm) that ends them
NEWTON_MAX_ITER = 32
NEWTON_TOL_MM = 1e-12


@dataclass(frozen=True)
class SurfaceHit:
    """Where a ray met a surface (vertex frame: ``z_mm`` is the sag there) and where it went on."""

    x_mm: float
    y_mm: float
    z_mm: float
    #: direction cosines after refraction
    L: float
    M: float
    N: float
    #: angles of incidence and refraction (rad, >= 0)
    incidence_rad: float
    refraction_rad: float
    #: distance from the previous point along the ray (mm)
    length_mm: float


@dataclass
class ReferenceRay:
    """End state of one traced ray (lens frame: z from the first vertex)."""

    status: int
    surface: int
    x_mm: float
    y_mm: float
    z_mm: float
    L: float
    M: float
    N: float
    opl_mm: float
    hits: list[SurfaceHit] = field(default_factory=list)

    @property
    def min_cos_incidence(self) -> float:
        """Smallest cos of the angles of incidence and refraction over the surfaces the ray refracted at
        (near 90 deg either way -- grazing incidence, or refraction just short of TIR -- the ray is
        ill-conditioned; see :data:`~lensrt.trace.status.GRAZING_INCIDENCE_DEG`)."""
        refracted = [h for h in self.hits if h.incidence_rad > 0.0 or h.refraction_rad > 0.0]
        return min((min(math.cos(h.incidence_rad), math.cos(h.refraction_rad)) for h in refracted), default=1.0)


def sag_and_slope(c: float, kp1: float, asphere: tuple[float, ...], r2: float) -> tuple[float, float] | None:
    """Sag z(r) and its derivative dz/d(r^2) at r^2 = ``r2``; None beyond the conic's extent."""
    q = 1.0 - kp1 * c * c * r2
    if q <= 0.0:
        return None
    root = math.sqrt(q)
    z = c * r2 / (1.0 + root)
    dz = c / (2.0 * root)
    # even asphere terms a_j r^(2j+2), j = 0.. (asphere[0] is the r^2 term), by Horner's rule
    poly, dpoly = 0.0, 0.0
    for j in range(len(asphere) - 1, -1, -1):
        poly = poly * r2 + asphere[j]
        dpoly = dpoly * r2 + (j + 1) * asphere[j]
    return z + poly * r2, dz + dpoly


def conic_t(c: float, kp1: float, x: float, y: float, z: float, L: float, M: float, N: float) -> float | None:
    """Ray parameter t of the intersection with the base conic's vertex branch, or None.

    Both roots in the form that does not cancel: q = B + sign(B) sqrt(B^2 - A F),
    t1 = F / q, t2 = q / A. A root lies on the vertex branch when
    1 - c (1 + k) z > 0 there (the half of a sphere or ellipsoid that holds the
    vertex). When both do (paraboloids, hyperboloids, and a sphere's cap met by
    a ray steeper than its rim: a fisheye's front beyond 90 deg), the ray enters
    the branch at one and leaves at the other; the one kept is where it crosses
    toward the surface's +z side, the side of the medium after the surface: there
    d . n = B - A t > 0 with n = (-c x, -c y, 1 - c (1 + k) z), and
    B - A t1 = sign(B) sqrt(B^2 - A F) = -(B - A t2), so it is t1 when B >= 0.
    """
    F = c * (x * x + y * y) + c * kp1 * z * z - 2.0 * z
    B = N - c * (x * L + y * M + kp1 * z * N)
    A = c * (L * L + M * M + kp1 * N * N)
    disc = B * B - A * F
    if disc < 0.0:
        return None
    root = math.sqrt(disc)
    q = B + root if B >= 0.0 else B - root
    t1 = F / q if q != 0.0 else None
    t2 = q / A if A != 0.0 else None
    ok1 = t1 is not None and c * kp1 * (z + t1 * N) < 1.0
    ok2 = t2 is not None and c * kp1 * (z + t2 * N) < 1.0
    if ok1 and ok2:
        return t1 if B >= 0.0 else t2
    return t1 if ok1 else (t2 if ok2 else None)


def intersect(c: float, kp1: float, asphere: tuple[float, ...], x: float, y: float, z: float,
              L: float, M: float, N: float) -> tuple[int, float, tuple[float, float, float]]:
    """Intersect the ray (x, y, z) + t (L, M, N) (vertex frame) with a surface.

    Returns ``(status, t, unit_normal)``; the normal points to +z on the vertex
    branch.
    """
    if not asphere:
        t = conic_t(c, kp1, x, y, z, L, M, N)
        if t is None:
            return MISSED, 0.0, (0.0, 0.0, 1.0)
        px, py, pz = x + t * L, y + t * M, z + t * N
        nx, ny, nz = -c * px, -c * py, 1.0 - c * kp1 * pz
        inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
        return OK, t, (nx * inv, ny * inv, nz * inv)
    # asphere: Newton on f(t) = z(t) - sag(r(t)), from the base conic (or the vertex plane)
    t = conic_t(c, kp1, x, y, z, L, M, N)
    if t is None:
        if N == 0.0:
            return MISSED, 0.0, (0.0, 0.0, 1.0)
        t = -z / N
    for _ in range(NEWTON_MAX_ITER):
        px, py, pz = x + t * L, y + t * M, z + t * N
        s = sag_and_slope(c, kp1, asphere, px * px + py * py)
        if s is None:
            return MISSED, 0.0, (0.0, 0.0, 1.0)
        sag, slope = s
        df = N - 2.0 * slope * (px * L + py * M)
        if df == 0.0:
            return NO_CONVERGE, 0.0, (0.0, 0.0, 1.0)
        dt = (pz - sag) / df
        t -= dt
        if abs(dt) <= NEWTON_TOL_MM:
            px, py = x + t * L, y + t * M
            s = sag_and_slope(c, kp1, asphere, px * px + py * py)
            if s is None:
                return MISSED, 0.0, (0.0, 0.0, 1.0)
            nx, ny, nz = -2.0 * s[1] * px, -2.0 * s[1] * py, 1.0
            inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
            return OK, t, (nx * inv, ny * inv, nz * inv)
    return NO_CONVERGE, 0.0, (0.0, 0.0, 1.0)


def refract(L: float, M: float, N: float, normal: tuple[float, float, float], n1: float,
            n2: float) -> tuple[int, float, float, float, float, float]:
    """Vector Snell's law. Returns ``(status, L', M', N', I, I')`` with angles in rad."""
    nx, ny, nz = normal
    cos_i = L * nx + M * ny + N * nz
    if cos_i < 0.0:  # the ray meets the surface from its +z side: turn the normal toward the ray
        nx, ny, nz, cos_i = -nx, -ny, -nz, -cos_i
    mu = n1 / n2
    k = 1.0 - mu * mu * (1.0 - cos_i * cos_i)
    # |d x n| is sin I without the cancellation of sqrt(1 - cos^2) near normal incidence
    cx, cy, cz = M * nz - N * ny, N * nx - L * nz, L * ny - M * nx
    sin_i = math.sqrt(cx * cx + cy * cy + cz * cz)
    if k < 0.0:
        return TIR, L, M, N, math.atan2(sin_i, cos_i), 0.0
    cos_r = math.sqrt(k)
    g = cos_r - mu * cos_i
    L2, M2, N2 = mu * L + g * nx, mu * M + g * ny, mu * N + g * nz
    inv = 1.0 / math.sqrt(L2 * L2 + M2 * M2 + N2 * N2)
    return OK, L2 * inv, M2 * inv, N2 * inv, math.atan2(sin_i, cos_i), math.atan2(mu * sin_i, cos_r)


def ideal_lens(L: float, M: float, N: float, x: float, y: float, power_per_mm: float, n1: float,
               n2: float) -> tuple[int, float, float, float, float, float, float]:
    """An ideal paraxial lens of power Phi at the plane z = 0 (OpticStudio's ``TYPE PARAXIAL``).

    The ray's direction tangents (L/N, M/N) change as the paraxial ray's slope does,
    exactly, at any height and angle::

        n' (L'/N') = n (L/N) - x Phi,    n' (M'/N') = n (M/N) - y Phi

    (the paraxial surface of OpticStudio and optiland's thin lens). Linear in the
    tangents and in (x, y), this images every plane perfectly onto its Gaussian
    conjugate plane (n'/s' + n/s = Phi): every ray from a point of the front focal
    plane leaves parallel, every parallel bundle meets in one point of the back focal
    plane, with no distortion. The optical path gains the phase of a perfect lens for
    an axial object at infinity, -n' sign(f') h^2 / (|f'| + sqrt(h^2 + f'^2)) with
    f' = n'/Phi and h^2 = x^2 + y^2 (so the axial wavefront at infinite conjugates is
    exact; elsewhere it is an approximation, as OpticStudio's OPD modes are).

    Returns ``(status, L', M', N', I, I', opl_added_mm)``; ``MISSED`` for a ray
    parallel to the plane (N <= 0).
    """
    if not N > 0.0:
        return MISSED, L, M, N, 0.5 * math.pi, 0.0, 0.0
    tx = (n1 * L / N - x * power_per_mm) / n2
    ty = (n1 * M / N - y * power_per_mm) / n2
    t2 = tx * tx + ty * ty
    N2 = 1.0 / math.sqrt(1.0 + t2)
    fp = n2 / power_per_mm
    h2 = x * x + y * y
    added = -n2 * math.copysign(1.0, fp) * h2 / (abs(fp) + math.sqrt(h2 + fp * fp))
    return OK, tx * N2, ty * N2, N2, math.atan2(math.hypot(L, M), N), math.atan(math.sqrt(t2)), added


def reflect(L: float, M: float, N: float, normal: tuple[float, float, float]
            ) -> tuple[int, float, float, float, float, float]:
    """Vector law of reflection d' = d - 2 (d . n) n. Returns ``(OK, L', M', N', I, I)`` (rad)."""
    nx, ny, nz = normal
    cos_i = L * nx + M * ny + N * nz
    L2, M2, N2 = L - 2.0 * cos_i * nx, M - 2.0 * cos_i * ny, N - 2.0 * cos_i * nz
    inv = 1.0 / math.sqrt(L2 * L2 + M2 * M2 + N2 * N2)
    cx, cy, cz = M * nz - N * ny, N * nx - L * nz, L * ny - M * nx
    angle = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), abs(cos_i))
    return OK, L2 * inv, M2 * inv, N2 * inv, angle, angle


def inside_iris(x: float, y: float, radius_mm: float, iris: Iris) -> bool:
    """True when (x, y) (stop frame) passes a stop of ``radius_mm`` shaped by ``iris``.

    A regular N-gon inscribed in the circle with a vertex at ``iris.rotation_rad``;
    ``roundness`` blends its boundary radius toward the circle; a central
    obstruction of ``obstruction_ratio * radius_mm`` blocks the middle.
    """
    r = math.hypot(x, y)
    limit = radius_mm * (1.0 + APERTURE_TOLERANCE)
    if r < iris.obstruction_ratio * radius_mm:
        return False
    if iris.blades == 0 or r > limit:
        return r <= limit
    half = math.pi / iris.blades
    if r <= limit * math.cos(half):  # inside the inscribed circle
        return True
    phi = math.atan2(y, x) - iris.rotation_rad
    phi = phi - 2.0 * half * math.floor(phi / (2.0 * half))  # angle from the last vertex, [0, 2 half)
    # the edge between two vertices is at distance R cos(half) from the centre
    rho = limit * math.cos(half) / math.cos(phi - half)
    rho = rho + iris.roundness * (limit - rho)
    return r <= rho


