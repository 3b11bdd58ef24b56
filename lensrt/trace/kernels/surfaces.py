"""Warp ``@wp.func`` surface code: index, intersection, apertures, refraction, the trace loop.

One generic source serves float32 and float64 (Warp generics: ``typing.Any`` arguments, the
scalar type of a constant taken from an argument, ``type(x)(0.5)``); Warp instantiates each
function for the precision of the kernel that calls it (:mod:`.generic`). The mathematics is
that of :mod:`lensrt.trace.reference` (read it there; the comments here only mark the steps),
in the vertex frame of each surface and in the cancellation-free forms, so that nearly flat
surfaces and long transfers keep their digits in float32.

Packed data (:mod:`lensrt.trace.pack`): ``surf`` rows per surface (and one for the image
surface), ``media`` rows per medium, ``iris`` the stop's shape.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..pack import (IRIS_BLADES, IRIS_COS_HALF, IRIS_HALF, IRIS_OBSTRUCTION, IRIS_RADIUS, IRIS_ROTATION,
                    IRIS_ROUNDNESS, IRIS_STOP, MEDIUM_CONSTANT, S_ASPH, S_AXES, S_C, S_KIND, S_KP1,
                    S_MIRROR, S_NASPH, S_ORIGIN, S_SD2, S_SIGN, S_THICK, S_APER, MAX_SURFACE_APERTURES,
                    APERTURE_COLS, S_IDEAL, S_X, X_CX, X_KXP1, X_NT, X_RN, X_TERMS)
from ..reference import NEWTON_MAX_ITER
from ..status import INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED
from . import NEWTON_TOL_F32_MM, NEWTON_TOL_F64_MM

__all__ = ["SymmetricLens", "GeneralLens", "is_general", "newton_tol_mm", "newton_rel_tol", "medium_index", "conic_t",
           "sag_slope", "even_terms", "radial_terms", "poly_xy", "shape_sag_grad", "intersect_shape", "intersect",
           "intersect_variant", "refract", "reflect", "ideal_lens", "bend_general", "to_local", "to_global",
           "passes_apertures", "inside_iris", "trace_ray", "write_ray"]

wp.set_module_options({"enable_backward": False})


# The kernel variant, chosen by the type of one kernel argument (a Warp overload per type, so the
# choice is made at compile time and the symmetric variant carries none of the general code):
# SymmetricLens -- coaxial refracting surfaces in vertex frames (every lens without mirrors, frames
# or surface apertures); GeneralLens -- mirrors, coordinate transforms, surface apertures, ideal paraxial lenses.
@wp.struct
class SymmetricLens:
    tag: int


@wp.struct
class GeneralLens:
    tag: int


@wp.func
def is_general(variant: SymmetricLens) -> bool:
    return False


@wp.func
def is_general(variant: GeneralLens) -> bool:  # noqa: F811 -- a Warp overload
    return True


# the Newton step that ends the iteration on an aspheric sag, per precision (overloads by type)
@wp.func
def newton_tol_mm(x: wp.float64) -> wp.float64:
    return wp.float64(NEWTON_TOL_F64_MM)


@wp.func
def newton_tol_mm(x: wp.float32) -> wp.float32:  # noqa: F811 -- a Warp overload
    return wp.float32(NEWTON_TOL_F32_MM)


# the part of the Newton stop that grows with |sag| on a shaped surface (intersect_shape): 0 in float64 (the
# reference's absolute 1e-12 mm), 4 ulp of the sag in float32, where a deep sag's rounding keeps the step
# above NEWTON_TOL_F32_MM (e.g. the ASL5040-UV Q-type asphere, sag ~ 15 mm at its rim)
@wp.func
def newton_rel_tol(x: wp.float64) -> wp.float64:
    return wp.float64(0.0)


@wp.func
def newton_rel_tol(x: wp.float32) -> wp.float32:  # noqa: F811 -- a Warp overload
    return wp.float32(4.8e-7)


@wp.func
def medium_index(media: wp.array2d(dtype=Any), m: int, w2: Any):
    # general dispersion formula of materials.index_from_packed; w2 = wavelength^2 in um^2
    if media[m, 0] == type(w2)(MEDIUM_CONSTANT):
        return media[m, 1]
    n2 = media[m, 1] + w2 * (media[m, 2] + w2 * media[m, 3])
    inv = type(w2)(1.0) / w2
    acc = inv
    for k in range(6):
        n2 = n2 + media[m, 4 + k] * acc
        acc = acc * inv
    for j in range(3):
        b = media[m, 10 + j]
        if b != type(w2)(0.0):
            n2 = n2 + b * w2 / (w2 - media[m, 13 + j])
    if n2 > type(w2)(0.0):
        return wp.sqrt(n2)
    return type(w2)(-1.0)


@wp.func
def conic_t(c: Any, kp1: Any, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any):
    # roots t1 = F / q, t2 = q / A with q = B + sign(B) sqrt(B^2 - A F); the vertex-branch one
    # (1 - c (1 + k) z > 0); when both are, the one where the ray crosses toward the surface's
    # +z side (d . n = sign(B) sqrt(disc) at t1: t1 when B >= 0); ok = 0 when there is none
    F = c * (x * x + y * y) + c * kp1 * z * z - type(c)(2.0) * z
    B = N - c * (x * L + y * M + kp1 * z * N)
    A = c * (L * L + M * M + kp1 * N * N)
    disc = B * B - A * F
    t = type(c)(0.0)
    ok = int(0)
    if disc >= type(c)(0.0):
        root = wp.sqrt(disc)
        q = B + root
        if B < type(c)(0.0):
            q = B - root
        ok1 = int(0)
        t1 = type(c)(0.0)
        if q != type(c)(0.0):
            t1 = F / q
            if c * kp1 * (z + t1 * N) < type(c)(1.0):
                ok1 = int(1)
        ok2 = int(0)
        t2 = type(c)(0.0)
        if A != type(c)(0.0):
            t2 = q / A
            if c * kp1 * (z + t2 * N) < type(c)(1.0):
                ok2 = int(1)
        if ok1 != 0 and (ok2 == 0 or B >= type(c)(0.0)):
            t = t1
            ok = int(1)
        elif ok2 != 0:
            t = t2
            ok = int(1)
    return ok, t


@wp.func
def sag_slope(surf: wp.array2d(dtype=Any), i: int, c: Any, kp1: Any, r2: Any):
    # sag z(r) and dz/d(r^2); ok = 0 beyond the conic's extent
    q = type(c)(1.0) - kp1 * c * c * r2
    sag = type(c)(0.0)
    slope = type(c)(0.0)
    ok = int(0)
    if q > type(c)(0.0):
        root = wp.sqrt(q)
        sag = c * r2 / (type(c)(1.0) + root)
        slope = c / (type(c)(2.0) * root)
        nasph = int(surf[i, S_NASPH])
        poly = type(c)(0.0)
        dpoly = type(c)(0.0)
        for jj in range(nasph):
            j = nasph - 1 - jj
            a = surf[i, S_ASPH + j]
            poly = poly * r2 + a
            dpoly = dpoly * r2 + type(c)(j + 1) * a
        sag = sag + poly * r2
        slope = slope + dpoly
        ok = int(1)
    return ok, sag, slope


@wp.func
def even_terms(surf: wp.array2d(dtype=Any), i: int, r2: Any):
    # sum a_j r^(2j+2) and its derivative d/d(r^2) (the even asphere block), Horner
    nasph = int(surf[i, S_NASPH])
    poly = type(r2)(0.0)
    dpoly = type(r2)(0.0)
    for jj in range(nasph):
        j = nasph - 1 - jj
        a = surf[i, S_ASPH + j]
        poly = poly * r2 + a
        dpoly = dpoly * r2 + type(r2)(j + 1) * a
    return poly * r2, dpoly


@wp.func
def radial_terms(surf: wp.array2d(dtype=Any), i: int, kind: int, c: Any, kp1: Any, r2: Any):
    # a rotational shape's departure from the conic and (d/dr) / r of it (lensrt.prescription.shapes._radial)
    rn = surf[i, S_X + X_RN]
    nt = int(surf[i, S_X + X_NT])
    x = r2 / (rn * rn)
    z = type(r2)(0.0)
    g = type(r2)(0.0)
    if kind == 3:  # odd: sum a_{i-1} u^i
        r = wp.sqrt(r2)
        u = r / rn
        poly = type(r2)(0.0)
        dpoly = type(r2)(0.0)
        for jj in range(nt):
            j = nt - jj
            a = surf[i, S_X + X_TERMS + j - 1]
            poly = poly * u + a
            dpoly = dpoly * u + type(r2)(j) * a
        z = poly * u
        if r > type(r2)(0.0):
            g = dpoly / (rn * r)
    elif kind == 4:  # Q^bfs: Clenshaw on P_m (terms already in the P basis)
        p = type(r2)(2.0) - type(r2)(4.0) * x
        a1 = type(r2)(0.0)
        a2 = type(r2)(0.0)
        d1 = type(r2)(0.0)
        d2 = type(r2)(0.0)
        for jj in range(nt):
            b = surf[i, S_X + X_TERMS + nt - 1 - jj]
            a0 = b + p * a1 - a2
            d0 = p * d1 - type(r2)(4.0) * a1 - d2
            a2 = a1
            a1 = a0
            d2 = d1
            d1 = d0
        sq = type(r2)(2.0) * a1
        dsq = type(r2)(2.0) * d1
        if nt > 1:
            sq = sq + type(r2)(2.0) * a2
            dsq = dsq + type(r2)(2.0) * d2
        c2 = c * c
        num = type(r2)(1.0) - (kp1 - type(r2)(1.0)) * c2 * r2
        den = type(r2)(1.0) - kp1 * c2 * r2
        phi = wp.sqrt(num / den)
        dphi = c2 / (wp.sqrt(num) * den * wp.sqrt(den))
        d = x * (type(r2)(1.0) - x) * sq
        dd = (type(r2)(1.0) - type(r2)(2.0) * x) * sq + x * (type(r2)(1.0) - x) * dsq
        z = phi * d
        g = dphi * d + phi * dd * type(r2)(2.0) / (rn * rn)
    else:  # Q^con: Clenshaw on the Jacobi P^(0,4) recurrence in t = 2x - 1 (shapes.jacobi04_abc)
        t = type(r2)(2.0) * x - type(r2)(1.0)
        b1 = type(r2)(0.0)
        b2 = type(r2)(0.0)
        d1 = type(r2)(0.0)
        d2 = type(r2)(0.0)
        for jj in range(nt):
            n = nt - 1 - jj
            fn = type(r2)(n)
            A = (type(r2)(2.0) * fn + type(r2)(5.0)) * (type(r2)(2.0) * fn + type(r2)(6.0)) / (
                type(r2)(2.0) * (fn + type(r2)(1.0)) * (fn + type(r2)(5.0)))
            B = type(r2)(-8.0) * (type(r2)(2.0) * fn + type(r2)(5.0)) / (
                (fn + type(r2)(1.0)) * (fn + type(r2)(5.0)) * (type(r2)(2.0) * fn + type(r2)(4.0)))
            f1 = fn + type(r2)(1.0)
            C = f1 * (f1 + type(r2)(4.0)) * (type(r2)(2.0) * f1 + type(r2)(6.0)) / (
                (f1 + type(r2)(1.0)) * (f1 + type(r2)(5.0)) * (type(r2)(2.0) * f1 + type(r2)(4.0)))
            a = surf[i, S_X + X_TERMS + n]
            b0 = a + (A * t + B) * b1 - C * b2
            d0 = A * b1 + (A * t + B) * d1 - C * d2
            b2 = b1
            b1 = b0
            d2 = d1
            d1 = d0
        z = x * x * b1
        g = (type(r2)(2.0) * x * b1 + x * x * type(r2)(2.0) * d1) * type(r2)(2.0) / (rn * rn)
    return z, g


@wp.func
def poly_xy(surf: wp.array2d(dtype=Any), i: int, u: Any, v: Any):
    # sum t_(d,k) u^(d-k) v^k and its partial derivatives (shapes._poly_xy: Horner in u within Horner in v)
    nt = int(surf[i, S_X + X_NT])
    deg = int(0)
    while (deg + 1) * (deg + 2) // 2 < nt:
        deg = deg + 1
    p = type(u)(0.0)
    pu = type(u)(0.0)
    pv = type(u)(0.0)
    for kk in range(deg + 1):
        k = deg - kk
        q = type(u)(0.0)
        dq = type(u)(0.0)
        for dd in range(deg - k + 1):
            d = deg - dd
            dq = dq * u + q
            q = q * u + surf[i, S_X + X_TERMS + d * (d + 1) // 2 + k]
        pv = pv * v + p
        p = p * v + q
        pu = pu * v + dq
    return p, pu, pv


@wp.func
def shape_sag_grad(surf: wp.array2d(dtype=Any), i: int, kind: int, c: Any, kp1: Any, x: Any, y: Any):
    # sag z(x, y) and gradient of a surface kind >= 3 (lensrt.prescription.shapes.sag_grad); ok = 0 where
    # the surface does not exist
    ok = int(0)
    z = type(x)(0.0)
    zx = type(x)(0.0)
    zy = type(x)(0.0)
    one = type(x)(1.0)
    if kind == 6:  # biconic
        cx = surf[i, S_X + X_CX]
        qx = surf[i, S_X + X_KXP1] * cx * cx * x * x
        qy = kp1 * c * c * y * y
        s2 = one - qx - qy
        if s2 > type(x)(0.0):
            s = wp.sqrt(s2)
            num = cx * x * x + c * y * y
            z = num / (one + s)
            common = num / (s * (one + s) * (one + s))
            zx = type(x)(2.0) * cx * x / (one + s) + common * surf[i, S_X + X_KXP1] * cx * cx * x
            zy = type(x)(2.0) * c * y / (one + s) + common * kp1 * c * c * y
            ok = int(1)
    elif kind == 7:  # toroidal: the y-profile swept about the axis at z = 1 / cx
        y2 = y * y
        q = one - kp1 * c * c * y2
        if q > type(x)(0.0):
            root = wp.sqrt(q)
            ez, edz = even_terms(surf, i, y2)
            gy = c * y2 / (one + root) + ez
            dg = type(x)(2.0) * y * (c / (type(x)(2.0) * root) + edz)
            cx = surf[i, S_X + X_CX]
            w = one - cx * gy
            s2 = w * w - cx * cx * x * x
            if s2 > type(x)(0.0) and w > type(x)(0.0):
                s = wp.sqrt(s2)
                z = gy + cx * x * x / (w + s)
                zx = cx * x / s
                zy = w * dg / s
                ok = int(1)
    else:  # odd, Q^bfs, Q^con, xy, Zernike over the conic + even asphere
        r2 = x * x + y * y
        q = one - kp1 * c * c * r2
        if q > type(x)(0.0):
            root = wp.sqrt(q)
            ez, edz = even_terms(surf, i, r2)
            dz = type(x)(0.0)
            g = type(x)(0.0)
            if kind < 8:
                dz, g = radial_terms(surf, i, kind, c, kp1, r2)
            g = g + type(x)(2.0) * (c / (type(x)(2.0) * root) + edz)
            z = c * r2 / (one + root) + ez + dz
            zx = g * x
            zy = g * y
            if kind == 8:  # xy polynomial / Zernike (as monomials) in (x, y) / R_n
                rn = surf[i, S_X + X_RN]
                pz, pu, pv = poly_xy(surf, i, x / rn, y / rn)
                z = z + pz
                zx = zx + pu / rn
                zy = zy + pv / rn
            ok = int(1)
    return ok, z, zx, zy


@wp.func
def intersect_shape(surf: wp.array2d(dtype=Any), i: int, kind: int, x: Any, y: Any, z: Any, L: Any, M: Any,
                    N: Any):
    # Newton in 3-D from the base conic's root (lensrt.trace.ray_shapes); status, t, normal (nx, ny, 1)
    c = surf[i, S_C]
    kp1 = surf[i, S_KP1]
    status = int(OK)
    ok, t = conic_t(c, kp1, x, y, z, L, M, N)
    if ok == 0:
        if N == type(x)(0.0):
            status = int(MISSED)
        else:
            t = -z / N
    converged = int(0)
    it = int(0)
    while status == int(OK) and converged == 0 and it < NEWTON_MAX_ITER:
        oks, sag, zx, zy = shape_sag_grad(surf, i, kind, c, kp1, x + t * L, y + t * M)
        if oks == 0:
            status = int(MISSED)
        else:
            df = N - (zx * L + zy * M)
            if df == type(x)(0.0):
                status = int(NO_CONVERGE)
            else:
                dt = (z + t * N - sag) / df
                t = t - dt
                if wp.abs(dt) <= newton_tol_mm(x) + newton_rel_tol(x) * wp.abs(sag):
                    converged = int(1)
        it = it + 1
    nx = type(x)(0.0)
    ny = type(x)(0.0)
    if status == int(OK):
        if converged == 0:
            status = int(NO_CONVERGE)
        else:
            oks, sag, zx, zy = shape_sag_grad(surf, i, kind, c, kp1, x + t * L, y + t * M)
            if oks == 0:
                status = int(MISSED)
            nx = -zx
            ny = -zy
    return status, t, nx, ny  # the normal (nx, ny, 1), not normalised


@wp.func
def intersect(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any):
    # returns status, t, unit normal (nx, ny, nz) toward +z
    c = surf[i, S_C]
    kp1 = surf[i, S_KP1]
    kind = int(surf[i, S_KIND])
    status = int(OK)
    t = type(x)(0.0)
    nx = type(x)(0.0)
    ny = type(x)(0.0)
    nz = type(x)(1.0)
    if kind < 2:
        ok, t = conic_t(c, kp1, x, y, z, L, M, N)
        if ok == 0:
            status = int(MISSED)
        else:
            px = x + t * L
            py = y + t * M
            pz = z + t * N
            nx = -c * px
            ny = -c * py
            nz = type(x)(1.0) - c * kp1 * pz
    else:
        ok, t = conic_t(c, kp1, x, y, z, L, M, N)
        if ok == 0:
            if N == type(x)(0.0):
                status = int(MISSED)
            else:
                t = -z / N
        converged = int(0)
        it = int(0)
        while status == int(OK) and converged == 0 and it < NEWTON_MAX_ITER:
            px = x + t * L
            py = y + t * M
            pz = z + t * N
            oks, sag, slope = sag_slope(surf, i, c, kp1, px * px + py * py)
            if oks == 0:
                status = int(MISSED)
            else:
                df = N - type(x)(2.0) * slope * (px * L + py * M)
                if df == type(x)(0.0):
                    status = int(NO_CONVERGE)
                else:
                    dt = (pz - sag) / df
                    t = t - dt
                    if wp.abs(dt) <= newton_tol_mm(x):
                        converged = int(1)
            it = it + 1
        if status == int(OK):
            if converged == 0:
                status = int(NO_CONVERGE)
            else:
                px = x + t * L
                py = y + t * M
                oks, sag, slope = sag_slope(surf, i, c, kp1, px * px + py * py)
                if oks == 0:
                    status = int(MISSED)
                nx = type(x)(-2.0) * slope * px
                ny = type(x)(-2.0) * slope * py
                nz = type(x)(1.0)
    inv = type(x)(1.0) / wp.sqrt(nx * nx + ny * ny + nz * nz)
    return status, t, nx * inv, ny * inv, nz * inv


@wp.func
def intersect_variant(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any,
                      variant: Any):
    # intersect(), or intersect_shape() for a surface kind of prescription.shapes -- general lenses only
    # (pack.pack_geometry), so the symmetric variant leaves the shape code out at compile time
    shaped = False
    if is_general(variant):
        if surf[i, S_KIND] >= type(x)(3.0):
            shaped = True
    st = int(OK)
    t = type(x)(0.0)
    nx = type(x)(0.0)
    ny = type(x)(0.0)
    nz = type(x)(1.0)
    if shaped:
        st, t, nx, ny = intersect_shape(surf, i, int(surf[i, S_KIND]), x, y, z, L, M, N)
        inv = type(x)(1.0) / wp.sqrt(nx * nx + ny * ny + type(x)(1.0))
        nx = nx * inv
        ny = ny * inv
        nz = inv
    else:
        st, t, nx, ny, nz = intersect(surf, i, x, y, z, L, M, N)
    return st, t, nx, ny, nz


@wp.func
def refract(L: Any, M: Any, N: Any, nx: Any, ny: Any, nz: Any, n1: Any, n2: Any, angles: int):
    # vector Snell's law (Field Guide p. 1); returns status, L', M', N', I, I' (angles only when
    # asked), min(cos I, cos I') (near 90 deg either way the ray is ill-conditioned)
    cos_i = L * nx + M * ny + N * nz
    sx = nx
    sy = ny
    sz = nz
    if cos_i < type(L)(0.0):
        sx = -nx
        sy = -ny
        sz = -nz
        cos_i = -cos_i
    mu = n1 / n2
    k = type(L)(1.0) - mu * mu * (type(L)(1.0) - cos_i * cos_i)
    status = int(OK)
    L2 = L
    M2 = M
    N2 = N
    ang_i = type(L)(0.0)
    ang_r = type(L)(0.0)
    sin_i = type(L)(0.0)
    if angles != 0:
        cx = M * sz - N * sy
        cy = N * sx - L * sz
        cz = L * sy - M * sx
        sin_i = wp.sqrt(cx * cx + cy * cy + cz * cz)
        ang_i = wp.atan2(sin_i, cos_i)
    cos_min = cos_i
    if k < type(L)(0.0):
        status = int(TIR)
    else:
        cos_r = wp.sqrt(k)
        cos_min = wp.min(cos_i, cos_r)
        g = cos_r - mu * cos_i
        L2 = mu * L + g * sx
        M2 = mu * M + g * sy
        N2 = mu * N + g * sz
        inv = type(L)(1.0) / wp.sqrt(L2 * L2 + M2 * M2 + N2 * N2)
        L2 = L2 * inv
        M2 = M2 * inv
        N2 = N2 * inv
        if angles != 0:
            ang_r = wp.atan2(mu * sin_i, cos_r)
    return status, L2, M2, N2, ang_i, ang_r, cos_min


@wp.func
def reflect(L: Any, M: Any, N: Any, nx: Any, ny: Any, nz: Any, angles: int):
    # vector law of reflection d' = d - 2 (d . n) n; returns status, L', M', N', I, I, cos I
    cos_i = L * nx + M * ny + N * nz
    L2 = L - type(L)(2.0) * cos_i * nx
    M2 = M - type(L)(2.0) * cos_i * ny
    N2 = N - type(L)(2.0) * cos_i * nz
    inv = type(L)(1.0) / wp.sqrt(L2 * L2 + M2 * M2 + N2 * N2)
    ang = type(L)(0.0)
    if angles != 0:
        cx = M * nz - N * ny
        cy = N * nx - L * nz
        cz = L * ny - M * nx
        ang = wp.atan2(wp.sqrt(cx * cx + cy * cy + cz * cz), wp.abs(cos_i))
    return int(OK), L2 * inv, M2 * inv, N2 * inv, ang, ang, wp.abs(cos_i)


@wp.func
def ideal_lens(L: Any, M: Any, N: Any, x: Any, y: Any, power: Any, n1: Any, n2: Any):
    # an ideal paraxial lens (ray_surface.ideal_lens): n' t' = n t - (x, y) Phi on the direction tangents;
    # returns status, L', M', N', I, I', min(cos I, cos I'), the optical path the perfect lens adds
    # (N > 0 always here: a ray that meets the plane from behind or along it is MISSED before)
    status = int(MISSED)
    L2 = L
    M2 = M
    N2 = N
    ang_i = type(L)(0.0)
    ang_r = type(L)(0.0)
    added = type(L)(0.0)
    if N > type(L)(0.0):
        tx = (n1 * L / N - x * power) / n2
        ty = (n1 * M / N - y * power) / n2
        t2 = tx * tx + ty * ty
        N2 = type(L)(1.0) / wp.sqrt(type(L)(1.0) + t2)
        L2 = tx * N2
        M2 = ty * N2
        fp = n2 / power
        h2 = x * x + y * y
        added = -n2 * wp.sign(fp) * h2 / (wp.abs(fp) + wp.sqrt(h2 + fp * fp))
        ang_i = wp.atan2(wp.sqrt(L * L + M * M), N)
        ang_r = wp.atan(wp.sqrt(t2))
        status = int(OK)
    return status, L2, M2, N2, ang_i, ang_r, wp.min(N, N2), added


@wp.func
def bend_general(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any, L: Any, M: Any, N: Any, nx: Any, ny: Any,
                 nz: Any, n1: Any, n2: Any, record: int):
    # the general variant's surfaces that do not refract: a mirror reflects, an ideal paraxial lens bends as a
    # perfect lens; returns status, L', M', N', I, I', min(cos I, cos I'), the optical path added (ideal lens)
    st = int(OK)
    L2 = L
    M2 = M
    N2 = N
    ang_i = type(L)(0.0)
    ang_r = type(L)(0.0)
    cos_ir = type(L)(1.0)
    added = type(L)(0.0)
    if surf[i, S_MIRROR] != type(L)(0.0):
        st, L2, M2, N2, ang_i, ang_r, cos_ir = reflect(L, M, N, nx, ny, nz, record)
    else:
        st, L2, M2, N2, ang_i, ang_r, cos_ir, added = ideal_lens(L, M, N, x, y, surf[i, S_IDEAL], n1, n2)
    return st, L2, M2, N2, ang_i, ang_r, cos_ir, added


@wp.func
def to_local(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any):
    # global point and direction into surface i's frame, mirrored in z when light travels toward -z
    # there: p_local = A^T (p - o), d_local = A^T d (A's columns are the local axes; row-major storage)
    sgn = surf[i, S_SIGN]
    dx = x - surf[i, S_ORIGIN]
    dy = y - surf[i, S_ORIGIN + 1]
    dz = z - surf[i, S_ORIGIN + 2]
    xl = surf[i, S_AXES] * dx + surf[i, S_AXES + 3] * dy + surf[i, S_AXES + 6] * dz
    yl = surf[i, S_AXES + 1] * dx + surf[i, S_AXES + 4] * dy + surf[i, S_AXES + 7] * dz
    zl = sgn * (surf[i, S_AXES + 2] * dx + surf[i, S_AXES + 5] * dy + surf[i, S_AXES + 8] * dz)
    Ll = surf[i, S_AXES] * L + surf[i, S_AXES + 3] * M + surf[i, S_AXES + 6] * N
    Ml = surf[i, S_AXES + 1] * L + surf[i, S_AXES + 4] * M + surf[i, S_AXES + 7] * N
    Nl = sgn * (surf[i, S_AXES + 2] * L + surf[i, S_AXES + 5] * M + surf[i, S_AXES + 8] * N)
    return xl, yl, zl, Ll, Ml, Nl


@wp.func
def to_global(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any):
    # the inverse of to_local: p = o + A p_local, d = A d_local (z unmirrored first)
    zs = surf[i, S_SIGN] * z
    Ns = surf[i, S_SIGN] * N
    xg = surf[i, S_ORIGIN] + surf[i, S_AXES] * x + surf[i, S_AXES + 1] * y + surf[i, S_AXES + 2] * zs
    yg = surf[i, S_ORIGIN + 1] + surf[i, S_AXES + 3] * x + surf[i, S_AXES + 4] * y + surf[i, S_AXES + 5] * zs
    zg = surf[i, S_ORIGIN + 2] + surf[i, S_AXES + 6] * x + surf[i, S_AXES + 7] * y + surf[i, S_AXES + 8] * zs
    Lg = surf[i, S_AXES] * L + surf[i, S_AXES + 1] * M + surf[i, S_AXES + 2] * Ns
    Mg = surf[i, S_AXES + 3] * L + surf[i, S_AXES + 4] * M + surf[i, S_AXES + 5] * Ns
    Ng = surf[i, S_AXES + 6] * L + surf[i, S_AXES + 7] * M + surf[i, S_AXES + 8] * Ns
    return xg, yg, zg, Lg, Mg, Ng


@wp.func
def passes_apertures(surf: wp.array2d(dtype=Any), i: int, x: Any, y: Any) -> int:
    # surface apertures (pack.S_APER): a clear aperture passes its inside, an obscuration blocks it
    passed = int(1)
    for k in range(MAX_SURFACE_APERTURES):
        col = S_APER + k * APERTURE_COLS
        shape = int(surf[i, col])
        if shape != 0:
            a = surf[i, col + 1]
            b = surf[i, col + 2]
            du = x - surf[i, col + 3]
            dv = y - surf[i, col + 4]
            cr = surf[i, col + 5]
            sr = surf[i, col + 6]
            u = cr * du + sr * dv
            v = cr * dv - sr * du
            inside = int(0)
            r2 = u * u + v * v
            if shape == 1:
                if r2 <= a * a:
                    inside = int(1)
            elif shape == 2:
                if r2 <= a * a and r2 >= b * b:
                    inside = int(1)
            elif shape == 3:
                if wp.abs(u) <= a and wp.abs(v) <= b:
                    inside = int(1)
            elif (u / a) * (u / a) + (v / b) * (v / b) <= type(x)(1.0):
                inside = int(1)
            if surf[i, col + 7] != type(x)(0.0):
                inside = 1 - inside
            if inside == 0:
                passed = int(0)
    return passed


@wp.func
def inside_iris(iris: wp.array(dtype=Any), x: Any, y: Any) -> int:
    # circle or regular N-gon (vertex at the rotation angle), roundness, central obstruction
    r = wp.sqrt(x * x + y * y)
    limit = iris[IRIS_RADIUS]
    inside = int(1)
    if r < iris[IRIS_OBSTRUCTION]:
        inside = int(0)
    blades = iris[IRIS_BLADES]
    if blades == type(x)(0.0):
        if r > limit:
            inside = int(0)
    elif r > limit:
        inside = int(0)
    elif r > limit * iris[IRIS_COS_HALF]:  # only the ring between the in- and circumcircle needs the angle
        half = iris[IRIS_HALF]
        phi = wp.atan2(y, x) - iris[IRIS_ROTATION]
        phi = phi - type(x)(2.0) * half * wp.floor(phi / (type(x)(2.0) * half))
        rho = limit * iris[IRIS_COS_HALF] / wp.cos(phi - half)
        rho = rho + iris[IRIS_ROUNDNESS] * (limit - rho)
        if r > rho:
            inside = int(0)
    return inside


@wp.func
def trace_ray(surf: wp.array2d(dtype=Any), media: wp.array2d(dtype=Any), iris: wp.array(dtype=Any),
              n_surfaces: int, x0: Any, y0: Any, z0: Any, L0: Any, M0: Any, N0: Any, w2: Any,
              index_table: wp.array2d(dtype=Any), table_row: int, end: int, clip: int, plane_dz: Any,
              record: int, rec: wp.array3d(dtype=Any), ray: int, variant: Any):
    """Trace one ray; returns status, surface, x, y, z (frame of the last surface met), L, M, N, opl,
    and the smallest cos of the angles of incidence and refraction met (grazing rays are
    ill-conditioned).

    Refracts at surfaces 0 .. end-1 and stops on surface ``end`` (``end = n_surfaces``:
    the plane ``plane_dz`` behind the image surface). ``table_row >= 0`` takes indices
    from ``index_table`` instead of the dispersion formula. ``variant`` (:class:`SymmetricLens`
    or :class:`GeneralLens`) selects the code at compile time: a general lens only when the
    packed lens needs it (``PackedLens.general``).
    """
    x = x0
    y = y0
    z = z0
    L = L0
    M = M0
    N = N0
    norm = wp.sqrt(L * L + M * M + N * N)
    status = int(OK)
    where = int(-1)
    opl = type(x0)(0.0)
    min_cos = type(x0)(1.0)
    if not (norm > type(x0)(0.0)) or not wp.isfinite(norm) or not wp.isfinite(x + y + z):
        status = int(INVALID)
        where = int(0)
    else:
        L = L / norm
        M = M / norm
        N = N / norm
    n1 = type(x0)(0.0)
    if table_row >= 0:
        n1 = index_table[table_row, 0]
    else:
        n1 = medium_index(media, 0, w2)
    if status == int(OK) and not (n1 > type(x0)(0.0)):
        status = int(INVALID)
        where = int(0)
    # mirrors or coordinate transforms: the ray travels in global coordinates between surfaces and is
    # met in each surface's (z-mirrored after odd mirrors) local frame, as in reference_general
    geom = is_general(variant)
    sgn = type(x0)(1.0)
    i = int(0)
    while status == int(OK) and i <= end:
        if geom:
            sgn = surf[i, S_SIGN]
            x, y, z, L, M, N = to_local(surf, i, x, y, z, L, M, N)
        if i == n_surfaces:
            z = z - sgn * plane_dz  # the plane may stand apart from the image surface
        st, t, nx, ny, nz = intersect_variant(surf, i, x, y, z, L, M, N, variant)
        if st == int(OK) and L * nx + M * ny + N * nz < type(x0)(0.0):
            st = int(MISSED)  # met from behind (from the medium after it): no sequential path
        if st != int(OK):
            status = st
            where = i
        else:
            x = x + t * L
            y = y + t * M
            z = z + t * N
            opl = opl + n1 * t
            ang_i = type(x0)(0.0)
            ang_r = type(x0)(0.0)
            if i < end:
                if clip != 0:
                    passed = int(1)
                    if geom:
                        passed = passes_apertures(surf, i, x, y)
                    if passed != 0:
                        if i == int(iris[IRIS_STOP]):
                            if iris[IRIS_RADIUS] > type(x0)(0.0):
                                passed = inside_iris(iris, x, y)
                        else:
                            sd2 = surf[i, S_SD2]
                            if sd2 >= type(x0)(0.0) and x * x + y * y > sd2:
                                passed = int(0)
                    if passed == 0:
                        status = int(VIGNETTED)
                        where = i
                if status == int(OK):
                    n2 = type(x0)(0.0)
                    if table_row >= 0:
                        n2 = index_table[table_row, i + 1]
                    else:
                        n2 = medium_index(media, i + 1, w2)
                    if not (n2 > type(x0)(0.0)):
                        status = int(INVALID)
                        where = i
                    elif geom and (surf[i, S_MIRROR] != type(x0)(0.0) or surf[i, S_IDEAL] != type(x0)(0.0)):
                        st, L, M, N, ang_i, ang_r, cos_ir, added = bend_general(surf, i, x, y, L, M, N, nx, ny, nz,
                                                                                n1, n2, record)
                        min_cos = wp.min(min_cos, cos_ir)
                        opl = opl + added
                        n1 = n2
                    else:
                        st, L, M, N, ang_i, ang_r, cos_ir = refract(L, M, N, nx, ny, nz, n1, n2, record)
                        min_cos = wp.min(min_cos, cos_ir)
                        if st != int(OK):
                            status = st
                            where = i
                        n1 = n2
            if record != 0:
                rec[ray, i, 0] = x
                rec[ray, i, 1] = y
                rec[ray, i, 2] = sgn * z
                rec[ray, i, 3] = L
                rec[ray, i, 4] = M
                rec[ray, i, 5] = sgn * N
                rec[ray, i, 6] = ang_i
                rec[ray, i, 7] = ang_r
                rec[ray, i, 8] = t
            if status == int(OK) and i < end:
                if geom:
                    x, y, z, L, M, N = to_global(surf, i, x, y, z, L, M, N)
                else:
                    z = z - surf[i, S_THICK]  # into the next vertex frame
        i = i + 1
    # the end state in the local frame of the last surface met (unmirrored)
    return status, where, x, y, sgn * z, L, M, sgn * N, opl, min_cos


@wp.func
def write_ray(out: wp.array2d(dtype=Any), status: wp.array(dtype=wp.int32), surface: wp.array(dtype=wp.int32), r: int,
              st: int, where: int, x: Any, y: Any, z: Any, L: Any, M: Any, N: Any, opl: Any, min_cos: Any):
    """A traced ray's end state into the store kernels' outputs (``RAY_OUT_COLS`` columns)."""
    out[r, 0] = x
    out[r, 1] = y
    out[r, 2] = z
    out[r, 3] = L
    out[r, 4] = M
    out[r, 5] = N
    out[r, 6] = opl
    out[r, 7] = min_cos
    status[r] = st
    surface[r] = where
