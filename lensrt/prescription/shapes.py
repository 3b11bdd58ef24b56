"""Surface shapes beyond the conic + even asphere: the description and its float64 sag and gradient.

A :class:`~lensrt.prescription.model.Surface` with ``shape=None`` is today's conic + even
asphere. A :class:`SurfaceShape` names one of :data:`SHAPE_KINDS` and carries its terms; the
surface's ``curvature_per_mm`` and ``conic`` stay the base (vertex-frame) conic, so every kind
starts its Newton intersection from the same base-conic root. Sags (mm), with r^2 = x^2 + y^2,
u = r / R_n (R_n = ``norm_radius_mm``), ``a_i`` = ``coefficients[i]`` and
``conic(c, k; r) = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2))``:

``odd`` -- Zemax ODDASPHE / EXTASPHE / XOSPHERE, CODE V ``SPS ODD``::

    z = conic(c, k; r) + sum_{i>=1} a_{i-1} u^i

``qbfs`` -- Forbes, "Shape specification for axially symmetric optical surfaces", Opt. Express
15, 5218 (2007), eq. (2.2)-(2.3), with the conic generalisation of Forbes, Opt. Express 19, 9923
(2011) (the same factor as optiland's ``ForbesQNormalSlopeGeometry``; 1 / sqrt(1 - c^2 r^2) for k = 0)::

    z = conic(c, k; r) + phi(r) u^2 (1 - u^2) sum_m a_m Q^bfs_m(u^2),
    phi = sqrt((1 - k c^2 r^2) / (1 - (1 + k) c^2 r^2))

``qcon`` -- Forbes (2007) eq. (2.5), ``Q^con_m(x) = P_m^(0,4)(2 x - 1)`` (Jacobi)::

    z = conic(c, k; r) + u^4 sum_m a_m Q^con_m(u^2)

``biconic`` -- Zemax BICONICX: y curvature/conic are the surface's, x ones the shape's::

    z = (cx x^2 + cy y^2) / (1 + sqrt(1 - (1 + kx) cx^2 x^2 - (1 + ky) cy^2 y^2))

``toroidal`` -- Zemax TOROIDAL: the y-profile ``g(y) = conic(c, k; y) + sum_j asphere_j y^(2j+2)``
swept about an axis parallel to y at z = R_x = 1 / cx (cx = 0: a cylinder along x)::

    z = g + cx x^2 / (w + sqrt(w^2 - cx^2 x^2)),   w = 1 - cx g

``xy`` -- Zemax XPOLYNOM (extended polynomial), u = x / R_n, v = y / R_n, terms in the order
x, y, x^2, x y, y^2, x^3, x^2 y, ... (degree by degree, falling powers of x)::

    z = conic(c, k; r) + sum_j asphere_j r^(2j+2) + sum_i a_i u^p_i v^q_i

``zernike`` -- Zemax SZERNSAG (Zernike standard sag): ``coefficients`` on Noll's normalised
Zernike polynomials Z_1, Z_2, ... (Noll, JOSA 66, 207 (1976): Z_j = sqrt(n + 1) R_n^0 for m = 0,
sqrt(2 (n + 1)) R_n^|m| cos(m theta) (even j) or sin(|m| theta) (odd j)) of (rho, theta) with
rho = r / R_n, theta from +x toward +y::

    z = conic(c, k; r) + sum_j asphere_j r^(2j+2) + sum_j A_j Z_j(rho, theta)

``zernike_fringe`` -- Zemax FZERNSAG (Zernike fringe sag): ``coefficients`` on the fringe (University
of Arizona) Zernike polynomials F_1, F_2, ... (Wyant & Creath, "Basic wavefront aberration theory for
optical metrology", Applied Optics and Optical Engineering XI (1992), Table 2; OpticStudio's "Zernike
Fringe" order: F_j = R_n^|m|(rho) cos(m theta) (m > 0), sin(|m| theta) (m < 0), R_n^0 (m = 0), with
j = (1 + (n + |m|) / 2)^2 - 2 |m| + (m < 0), not normalised; F_2 = rho cos(theta), F_4 = 2 rho^2 - 1,
F_9 = 6 rho^4 - 6 rho^2 + 1)::

    z = conic(c, k; r) + sum_j asphere_j r^(2j+2) + sum_j A_j F_j(rho, theta)

All three are evaluated as one polynomial in (u, v) (:func:`zernike_to_xy` expands the Zernike terms
once per surface -- fringe ones after :func:`fringe_to_noll` moves them to Noll's order and
normalisation), by Horner's rule in u within Horner's rule in v.

The Q polynomials are summed by Clenshaw's recurrence: Q^bfs after Forbes's change of basis to
P_m (P_{m+1} = (2 - 4x) P_m - P_{m-1}; :func:`qbfs_to_p_basis`, done once per surface), Q^con by
the Jacobi three-term recurrence (DLMF 18.9.2). Both the NumPy reference tracer
(:mod:`lensrt.trace.ray_shapes`) and the Warp kernels use these forms. The polynomial terms are
not clipped at u = 1: the sag continues smoothly beyond the normalisation radius.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

from ..errors import PrescriptionError

__all__ = ["SHAPE_KINDS", "ROTATIONAL_KINDS", "POLYNOMIAL_KINDS", "MAX_SHAPE_TERMS", "MAX_FRINGE_TERMS",
           "poly_degree", "noll_nm", "fringe_nm", "fringe_to_noll", "zernike_to_xy", "SurfaceShape", "Profile", "profile_of",
           "sag_grad", "qbfs_to_p_basis", "qbfs_sum", "qcon_sum", "jacobi04_abc", "vertex_expansion"]

#: the surface kinds a :class:`SurfaceShape` may name
SHAPE_KINDS = ("odd", "qbfs", "qcon", "biconic", "toroidal", "xy", "zernike", "zernike_fringe")
#: kinds whose sag depends on r only
ROTATIONAL_KINDS = ("odd", "qbfs", "qcon")
#: kinds evaluated as a polynomial in (x, y) over the conic + even asphere
POLYNOMIAL_KINDS = ("xy", "zernike", "zernike_fringe")
#: most terms a shape may carry (Zemax's extended surfaces allow up to 480; 66 is an XY polynomial of degree 10)
MAX_SHAPE_TERMS = 66
#: terms of the fringe Zernike set (OpticStudio's Zernike Fringe Sag takes up to 37)
MAX_FRINGE_TERMS = 37


def _num(v: object, what: str) -> float:
    try:
        f = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise PrescriptionError(f"{what} {v!r} is not a number") from None
    if not math.isfinite(f):
        raise PrescriptionError(f"{what} is {v!r}", hint="give a finite number")
    return f


@dataclass(frozen=True)
class SurfaceShape:
    """The terms of a surface kind beyond the conic + even asphere (module docstring).

    ``kind`` in :data:`SHAPE_KINDS`; ``coefficients`` the kind's terms (odd: u^1, u^2, ...;
    qbfs/qcon: a_0, a_1, ...; unused by biconic/toroidal); ``norm_radius_mm`` R_n (> 0; odd
    defaults to 1 mm, i.e. plain powers of r); ``curvature_x_per_mm`` the biconic's x
    curvature or the toroid's 1 / R_x (0: a cylinder); ``conic_x`` the biconic's x conic.
    """

    kind: str
    coefficients: tuple[float, ...] = ()
    norm_radius_mm: float = 1.0
    curvature_x_per_mm: float = 0.0
    conic_x: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in SHAPE_KINDS:
            raise PrescriptionError(f"unknown surface shape {self.kind!r}", hint=f"use one of {', '.join(SHAPE_KINDS)}")
        coef = tuple(_num(a, f"{self.kind} coefficient") for a in self.coefficients)
        while coef and coef[-1] == 0.0:
            coef = coef[:-1]
        if len(coef) > MAX_SHAPE_TERMS:
            raise PrescriptionError(f"{self.kind} surface with {len(coef)} terms; lensrt takes at most "
                                    f"{MAX_SHAPE_TERMS}", hint="drop the trailing (zero) terms")
        if len(coef) > MAX_FRINGE_TERMS and self.kind == "zernike_fringe":
            raise PrescriptionError(f"fringe Zernike surface with {len(coef)} terms; the fringe set has "
                                    f"{MAX_FRINGE_TERMS}", hint="drop the trailing (zero) terms")
        if len(coef) > MAX_SHAPE_TERMS - 1 and self.kind == "xy":
            raise PrescriptionError(f"xy surface with {len(coef)} terms; lensrt takes at most {MAX_SHAPE_TERMS - 1}",
                                    hint="drop the trailing (zero) terms")
        if coef and self.kind in ("biconic", "toroidal"):
            raise PrescriptionError(f"a {self.kind} surface takes no polynomial coefficients",
                                    hint="give the y-profile's even asphere terms as the surface's asphere")
        rn = _num(self.norm_radius_mm, "normalisation radius")
        if rn <= 0.0:
            raise PrescriptionError(f"normalisation radius {rn:g} mm must be positive")
        cx = _num(self.curvature_x_per_mm, "x curvature")
        kx = _num(self.conic_x, "x conic")
        if kx != 0.0 and self.kind != "biconic":
            raise PrescriptionError(f"an x conic on a {self.kind} surface", hint="only a biconic has an x conic")
        if cx != 0.0 and self.kind not in ("biconic", "toroidal"):
            raise PrescriptionError(f"an x curvature on a {self.kind} surface",
                                    hint="only biconic and toroidal surfaces have an x curvature")
        object.__setattr__(self, "coefficients", coef)
        object.__setattr__(self, "norm_radius_mm", rn)
        object.__setattr__(self, "curvature_x_per_mm", cx)
        object.__setattr__(self, "conic_x", kx)

    def mirrored_in_z(self) -> "SurfaceShape":
        """The shape seen with z reversed (every sag term changes sign; the x conic stays)."""
        return SurfaceShape(self.kind, tuple(-a for a in self.coefficients), self.norm_radius_mm,
                            -self.curvature_x_per_mm, self.conic_x)

    @property
    def rotational(self) -> bool:
        """True when the sag depends on r only."""
        return self.kind in ROTATIONAL_KINDS


@dataclass(frozen=True)
class Profile:
    """A surface's sag, ready to evaluate (float64): what :func:`sag_grad` and the packer read.

    ``terms`` are the kernel-ready coefficients: the odd powers' a_i, Q^bfs in the P_m basis
    (:func:`qbfs_to_p_basis`), Q^con's a_m.
    """

    kind: str
    c: float
    k: float
    asphere: tuple[float, ...]
    terms: tuple[float, ...]
    rn: float
    cx: float
    kx: float


@lru_cache(maxsize=256)
def _f_g_h(m: int) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """Forbes (2007) eq. (A.14)-(A.16): f_n, g_n, h_n of the Q^bfs -> P change of basis, n <= m."""
    f, g, h = [2.0], [], []
    if m >= 1:
        g.append(-0.5)
        f.append(math.sqrt(19.0) / 2.0)
    for n in range(2, m + 1):
        h.append(-n * (n - 1) / (2.0 * f[n - 2]))
        g.append(-(1.0 + g[n - 2] * h[n - 2]) / f[n - 1])
        f.append(math.sqrt(n * (n + 1) + 3.0 - g[n - 1] ** 2 - h[n - 2] ** 2))
    return tuple(f), tuple(g), tuple(h)


def qbfs_to_p_basis(a: Sequence[float]) -> tuple[float, ...]:
    """Coefficients b_m with sum a_m Q^bfs_m = 2 (alpha_0 + alpha_1) of Clenshaw on P_m (Forbes 2007, App. A)."""
    m = len(a) - 1
    if m < 0:
        return ()
    f, g, h = _f_g_h(m)
    b = [0.0] * (m + 1)
    b[m] = a[m] / f[m]
    if m >= 1:
        b[m - 1] = (a[m - 1] - g[m - 1] * b[m]) / f[m - 1]
    for i in range(m - 2, -1, -1):
        b[i] = (a[i] - g[i] * b[i + 1] - h[i] * b[i + 2]) / f[i]
    return tuple(b)


def qbfs_sum(b: Sequence[float], x: float) -> tuple[float, float]:
    """sum a_m Q^bfs_m(x) and its derivative d/dx, from the P-basis ``b`` (Clenshaw)."""
    m = len(b) - 1
    if m < 0:
        return 0.0, 0.0
    p = 2.0 - 4.0 * x
    a1 = a2 = d1 = d2 = 0.0  # alpha_{n+1}, alpha_{n+2} and their x-derivatives
    for n in range(m, -1, -1):
        a0 = b[n] + p * a1 - a2
        d0 = p * d1 - 4.0 * a1 - d2
        a2, a1, d2, d1 = a1, a0, d1, d0
    if m == 0:
        return 2.0 * a1, 2.0 * d1
    return 2.0 * (a1 + a2), 2.0 * (d1 + d2)


def jacobi04_abc(n: int) -> tuple[float, float, float]:
    """DLMF 18.9.2 for P^(0,4): P_{n+1}(t) = (A_n t + B_n) P_n(t) - C_n P_{n-1}(t)."""
    A = (2 * n + 5) * (2 * n + 6) / (2.0 * (n + 1) * (n + 5))
    B = -8.0 * (2 * n + 5) / ((n + 1) * (n + 5) * (2 * n + 4))
    C = n * (n + 4) * (2 * n + 6) / ((n + 1) * (n + 5) * (2.0 * n + 4))
    return A, B, C


def qcon_sum(a: Sequence[float], x: float) -> tuple[float, float]:
    """sum a_m P_m^(0,4)(2x - 1) and its derivative d/dx (Clenshaw on the Jacobi recurrence)."""
    t = 2.0 * x - 1.0
    b1 = b2 = d1 = d2 = 0.0
    for n in range(len(a) - 1, -1, -1):
        A, B, _ = jacobi04_abc(n)
        C = jacobi04_abc(n + 1)[2]
        b0 = a[n] + (A * t + B) * b1 - C * b2
        d0 = A * b1 + (A * t + B) * d1 - C * d2
        b2, b1, d2, d1 = b1, b0, d1, d0
    return b1, 2.0 * d1


def profile_of(surface: object, sign: float = 1.0) -> Profile:
    """The :class:`Profile` of a :class:`~lensrt.prescription.model.Surface`, seen in the frame mirrored in z
    when ``sign`` = -1 (every sag term changes sign; conics stay)."""
    sh = getattr(surface, "shape")
    c, k = float(getattr(surface, "curvature_per_mm")), float(getattr(surface, "conic"))
    asph = tuple(getattr(surface, "asphere"))
    if sh is None:
        return Profile("even", sign * c, k, tuple(sign * a for a in asph), (), 1.0, 0.0, 0.0)
    if sh.kind == "qbfs":
        terms = qbfs_to_p_basis(sh.coefficients)
    elif sh.kind == "xy":  # the constant term first, then padded to a whole triangle of degrees
        terms = _triangle((0.0,) + sh.coefficients)
    elif sh.kind == "zernike":
        terms = zernike_to_xy(sh.coefficients)
    elif sh.kind == "zernike_fringe":
        terms = zernike_to_xy(fringe_to_noll(sh.coefficients))
    else:
        terms = sh.coefficients
    return Profile(sh.kind, sign * c, k, tuple(sign * a for a in asph), tuple(sign * a for a in terms),
                   sh.norm_radius_mm, sign * sh.curvature_x_per_mm, sh.conic_x)


def _triangle(t: Sequence[float]) -> tuple[float, ...]:
    """``t`` padded with zeros to (D + 1)(D + 2) / 2 terms: every monomial of degree <= D."""
    d = poly_degree(len(t))
    return tuple(t) + (0.0,) * ((d + 1) * (d + 2) // 2 - len(t))


def poly_degree(n_terms: int) -> int:
    """Smallest degree D whose triangle (D + 1)(D + 2) / 2 holds ``n_terms`` monomials."""
    d = 0
    while (d + 1) * (d + 2) // 2 < n_terms:
        d += 1
    return d


def noll_nm(j: int) -> tuple[int, int]:
    """Radial order n and signed azimuthal order m of Noll's Z_j (j >= 1; m < 0: sin, m > 0: cos)."""
    n = int((math.isqrt(8 * (j - 1) + 1) - 1) // 2)
    p = j - n * (n + 1) // 2
    k = n % 2
    m = 2 * ((p + k) // 2) - k
    return n, (m if j % 2 == 0 else -m) if m else 0


def fringe_nm(j: int) -> tuple[int, int]:
    """Radial order n and signed azimuthal order m of the fringe Zernike F_j (j >= 1; m < 0: sin, m > 0: cos).

    The fringe order runs through the radial shells ``s = (n + |m|) / 2 = 0, 1, 2, ...``; shell s holds
    j = s^2 + 1 .. (s + 1)^2: |m| = s, s, s - 1, s - 1, ..., 1, 1, 0, cos before sin. The set stops at
    :data:`MAX_FRINGE_TERMS` = 37, whose last term is the 12th-order spherical term (n = 12, m = 0), not
    the (6, 6) that the shell pattern would give next (Wyant & Creath Table 2; OpticStudio's table).
    """
    if not 1 <= j <= MAX_FRINGE_TERMS:
        raise PrescriptionError(f"fringe Zernike index {j} is outside 1..{MAX_FRINGE_TERMS}")
    if j == MAX_FRINGE_TERMS:
        return 12, 0
    s = math.isqrt(j - 1)
    i = j - s * s - 1  # 0 .. 2 s within the shell
    am = s - i // 2
    return 2 * s - am, am if i % 2 == 0 else -am


def fringe_to_noll(coefficients: Sequence[float]) -> tuple[float, ...]:
    """Coefficients on Noll's normalised Z_j of ``sum_j A_j F_j`` (fringe order, not normalised)."""
    if not coefficients:
        return ()
    nm = [fringe_nm(j + 1) for j in range(len(coefficients))]
    deg = max(n for n, _ in nm)
    where = {noll_nm(j): j for j in range(1, (deg + 1) * (deg + 2) // 2 + 1)}
    out = [0.0] * ((deg + 1) * (deg + 2) // 2)
    for a, (n, m) in zip(coefficients, nm):
        norm = math.sqrt(n + 1.0) if m == 0 else math.sqrt(2.0 * (n + 1.0))
        out[where[(n, m)] - 1] += a / norm
    return tuple(out)


def zernike_to_xy(coefficients: Sequence[float]) -> tuple[float, ...]:
    """Monomial coefficients (u^(d-k) v^k at d (d + 1) / 2 + k) of sum_j A_j Z_j (Noll, normalised)."""
    if not coefficients:
        return ()
    deg = max(noll_nm(j + 1)[0] for j in range(len(coefficients)))
    out = [0.0] * ((deg + 1) * (deg + 2) // 2)
    for j, a in enumerate(coefficients):
        if a == 0.0:
            continue
        n, m = noll_nm(j + 1)
        am = abs(m)
        norm = math.sqrt(n + 1.0) if m == 0 else math.sqrt(2.0 * (n + 1.0))
        # (u + i v)^|m|: its real (cos) or imaginary (sin) part, as {power of v: coefficient} with u^(|m| - b)
        ang = {b: math.comb(am, b) * (1, 0, -1, 0)[b % 4] for b in range(0, am + 1) if b % 2 == 0} if m >= 0 else \
            {b: math.comb(am, b) * (0, 1, 0, -1)[b % 4] for b in range(1, am + 1, 2)}
        for s_ in range((n - am) // 2 + 1):
            rad = (-1) ** s_ * math.factorial(n - s_) / (
                math.factorial(s_) * math.factorial((n + am) // 2 - s_) * math.factorial((n - am) // 2 - s_))
            q = (n - 2 * s_ - am) // 2  # rho^(n - 2s) = rho^|m| (u^2 + v^2)^q
            for t in range(q + 1):  # (u^2 + v^2)^q = sum C(q, t) u^(2(q-t)) v^(2t)
                for b, cb in ang.items():
                    pv = 2 * t + b
                    d = 2 * q + am
                    out[d * (d + 1) // 2 + pv] += a * norm * rad * math.comb(q, t) * cb
    return tuple(out)


def _poly_xy(terms: Sequence[float], u: float, v: float) -> tuple[float, float, float]:
    """P(u, v) = sum t_(d,k) u^(d-k) v^k and its partial derivatives (Horner in u within Horner in v)."""
    deg = poly_degree(len(terms))
    p = pu = pv = 0.0
    for k in range(deg, -1, -1):
        q = dq = 0.0
        for d in range(deg, k - 1, -1):
            dq = dq * u + q
            q = q * u + terms[d * (d + 1) // 2 + k]
        pv = pv * v + p
        p = p * v + q
        pu = pu * v + dq
    return p, pu, pv


def _conic(c: float, k: float, r2: float) -> tuple[float, float] | None:
    """conic sag and dz/d(r^2) at r^2; None beyond its extent."""
    q = 1.0 - (1.0 + k) * c * c * r2
    if q < 0.0:
        return None
    root = math.sqrt(q)
    if root == 0.0:
        return None
    return c * r2 / (1.0 + root), c / (2.0 * root)


def _even(asph: Sequence[float], r2: float) -> tuple[float, float]:
    poly = dpoly = 0.0
    for j in range(len(asph) - 1, -1, -1):
        poly = poly * r2 + asph[j]
        dpoly = dpoly * r2 + (j + 1) * asph[j]
    return poly * r2, dpoly


def _radial(p: Profile, r2: float) -> tuple[float, float] | None:
    """z(r) and dz/dr / r of a rotational profile (the gradient is that times (x, y))."""
    base = _conic(p.c, p.k, r2)
    if base is None:
        return None
    z, dz_dr2 = base
    ez, edz = _even(p.asphere, r2)
    z, g = z + ez, 2.0 * (dz_dr2 + edz)  # g = (dz/dr) / r
    x = r2 / (p.rn * p.rn)
    if p.kind == "odd":
        r = math.sqrt(r2)
        u = r / p.rn
        poly = dpoly = 0.0  # sum a_{i-1} u^i = u * P(u), Horner
        for i in range(len(p.terms), 0, -1):
            poly = poly * u + p.terms[i - 1]
            dpoly = dpoly * u + i * p.terms[i - 1]
        z += poly * u
        if r > 0.0:
            g += dpoly / (p.rn * r)  # d/dr (u P(u)) = (sum i a u^(i-1)) / R_n
    elif p.kind == "qbfs":
        s, ds = qbfs_sum(p.terms, x)
        c2 = p.c * p.c
        num, den = 1.0 - p.k * c2 * r2, 1.0 - (1.0 + p.k) * c2 * r2
        phi = math.sqrt(num / den)
        dphi_r = c2 / (math.sqrt(num) * den ** 1.5)  # (d phi / dr) / r
        d = x * (1.0 - x) * s
        dd = (1.0 - 2.0 * x) * s + x * (1.0 - x) * ds  # dD/dx
        z += phi * d
        g += dphi_r * d + phi * dd * 2.0 / (p.rn * p.rn)
    elif p.kind == "qcon":
        s, ds = qcon_sum(p.terms, x)
        z += x * x * s
        g += (2.0 * x * s + x * x * ds) * 2.0 / (p.rn * p.rn)
    return z, g


def sag_grad(p: Profile, x: float, y: float) -> tuple[float, float, float] | None:
    """Sag z(x, y) and its gradient (dz/dx, dz/dy), float64; None where the surface does not exist."""
    if p.kind in ("even", "odd", "qbfs", "qcon") + POLYNOMIAL_KINDS:
        out = _radial(p, x * x + y * y)
        if out is None:
            return None
        if p.kind in POLYNOMIAL_KINDS:
            pz, pu, pv = _poly_xy(p.terms, x / p.rn, y / p.rn)
            return out[0] + pz, out[1] * x + pu / p.rn, out[1] * y + pv / p.rn
        return out[0], out[1] * x, out[1] * y
    if p.kind == "biconic":
        qx, qy = (1.0 + p.kx) * p.cx * p.cx * x * x, (1.0 + p.k) * p.c * p.c * y * y
        s2 = 1.0 - qx - qy
        if s2 <= 0.0:
            return None
        s = math.sqrt(s2)
        num = p.cx * x * x + p.c * y * y
        z = num / (1.0 + s)
        common = num / (s * (1.0 + s) ** 2)
        zx = 2.0 * p.cx * x / (1.0 + s) + common * (1.0 + p.kx) * p.cx * p.cx * x
        zy = 2.0 * p.c * y / (1.0 + s) + common * (1.0 + p.k) * p.c * p.c * y
        return z, zx, zy
    # toroidal: the y-profile g(y) swept about the axis at z = 1 / cx
    base = _conic(p.c, p.k, y * y)
    if base is None:
        return None
    ez, edz = _even(p.asphere, y * y)
    gy, dg = base[0] + ez, 2.0 * y * (base[1] + edz)
    w = 1.0 - p.cx * gy
    s2 = w * w - p.cx * p.cx * x * x
    if s2 < 0.0 or w <= 0.0:
        return None
    s = math.sqrt(s2)
    if s == 0.0:
        return None
    z = gy + p.cx * x * x / (w + s)
    return z, p.cx * x / s, w * dg / s


def vertex_expansion(p: Profile) -> tuple[float, float]:
    """(a2, a4): the r^2 and r^4 coefficients of the sag's Taylor series at the vertex (the y-section for
    biconic and toroidal surfaces; the odd powers r^1, r^3, ... of an odd asphere are left out).

    The paraxial curvature is ``2 a2``; ``a4`` enters the third-order (Seidel) aspheric term.
    """
    c, k = p.c, p.k
    a2 = c / 2.0 + (p.asphere[0] if p.asphere else 0.0)
    a4 = (1.0 + k) * c ** 3 / 8.0 + (p.asphere[1] if len(p.asphere) > 1 else 0.0)
    rn2 = p.rn * p.rn
    if p.kind == "odd":
        t = p.terms
        a2 += (t[1] if len(t) > 1 else 0.0) / rn2
        a4 += (t[3] if len(t) > 3 else 0.0) / (rn2 * rn2)
    elif p.kind == "qbfs":
        s0, s1 = qbfs_sum(p.terms, 0.0)
        a2 += s0 / rn2
        a4 += (s1 - s0) / (rn2 * rn2) + s0 * c * c / (2.0 * rn2)
    elif p.kind == "qcon":
        a4 += qcon_sum(p.terms, 0.0)[0] / (rn2 * rn2)
    elif p.kind in POLYNOMIAL_KINDS:  # the y-section's v^2 and v^4 terms (constant, tilt and odd terms left out)
        t = p.terms
        a2 += (t[5] if len(t) > 5 else 0.0) / rn2
        a4 += (t[14] if len(t) > 14 else 0.0) / (rn2 * rn2)
    return a2, a4
