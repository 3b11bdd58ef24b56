"""Warp ``@wp.func`` surface code: index, intersection, apertures, refraction, the trace loop.

The same source serves float32 and float64: :func:`surface_funcs` builds the
functions for one scalar type ``real`` inside the Warp module of that
precision (see :mod:`.kernels`). The mathematics is that of
:mod:`.reference` (read it there; the comments here only mark the steps), in
the vertex frame of each surface and in the cancellation-free forms, so that
nearly flat surfaces and long transfers keep their digits in float32.

Packed data (:mod:`.pack`): ``surf`` rows per surface (and one for the image
surface), ``media`` rows per medium, ``iris`` the stop's shape.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations of the
# functions built below as objects (the scalar type ``real`` is a closure variable).

from types import SimpleNamespace
from typing import Any

from .pack import (IRIS_COS_HALF, IRIS_HALF, IRIS_OBSTRUCTION, IRIS_RADIUS, IRIS_ROTATION, IRIS_ROUNDNESS,
                   IRIS_BLADES, IRIS_STOP, MEDIUM_CONSTANT, S_ASPH, S_C, S_KIND, S_KP1, S_NASPH,
                   S_SD2, S_THICK)
from .reference import NEWTON_MAX_ITER
from .status import INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED

__all__ = ["surface_funcs", "NEWTON_TOL_F32_MM", "NEWTON_TOL_F64_MM", "N_RECORD"]

#: Newton step (mm) that ends the iteration on an aspheric sag, per precision
NEWTON_TOL_F64_MM = 1e-12
NEWTON_TOL_F32_MM = 2e-6
#: values recorded per surface when a trace records: x y z(sag) L M N I I' length
N_RECORD = 9


def surface_funcs(wp: Any, real: Any, module: str) -> SimpleNamespace:
    """Build the surface ``@wp.func`` s for scalar type ``real`` in Warp module ``module``."""
    is64 = real is wp.float64
    newton_tol = NEWTON_TOL_F64_MM if is64 else NEWTON_TOL_F32_MM
    ns = SimpleNamespace()
    func = wp.func(module=module)

    @func
    def medium_index(media: wp.array2d(dtype=real), m: int, w2: real) -> real:
        # general dispersion formula of materials.index_from_packed; w2 = wavelength^2 in um^2
        if media[m, 0] == real(MEDIUM_CONSTANT):
            return media[m, 1]
        n2 = media[m, 1] + w2 * (media[m, 2] + w2 * media[m, 3])
        inv = real(1.0) / w2
        acc = inv
        for k in range(6):
            n2 = n2 + media[m, 4 + k] * acc
            acc = acc * inv
        for j in range(3):
            b = media[m, 10 + j]
            if b != real(0.0):
                n2 = n2 + b * w2 / (w2 - media[m, 13 + j])
        if n2 > real(0.0):
            return wp.sqrt(n2)
        return real(-1.0)

    @func
    def conic_t(c: real, kp1: real, x: real, y: real, z: real, L: real, M: real, N: real):
        # roots t1 = F / q, t2 = q / A with q = B + sign(B) sqrt(B^2 - A F); the vertex-branch one
        # (1 - c (1 + k) z > 0); when both are, the one where the ray crosses toward the surface's
        # +z side (d . n = sign(B) sqrt(disc) at t1: t1 when B >= 0); ok = 0 when there is none
        F = c * (x * x + y * y) + c * kp1 * z * z - real(2.0) * z
        B = N - c * (x * L + y * M + kp1 * z * N)
        A = c * (L * L + M * M + kp1 * N * N)
        disc = B * B - A * F
        t = real(0.0)
        ok = int(0)
        if disc >= real(0.0):
            root = wp.sqrt(disc)
            q = B + root
            if B < real(0.0):
                q = B - root
            ok1 = int(0)
            t1 = real(0.0)
            if q != real(0.0):
                t1 = F / q
                if c * kp1 * (z + t1 * N) < real(1.0):
                    ok1 = int(1)
            ok2 = int(0)
            t2 = real(0.0)
            if A != real(0.0):
                t2 = q / A
                if c * kp1 * (z + t2 * N) < real(1.0):
                    ok2 = int(1)
            if ok1 != 0 and (ok2 == 0 or B >= real(0.0)):
                t = t1
                ok = int(1)
            elif ok2 != 0:
                t = t2
                ok = int(1)
        return ok, t

    @func
    def sag_slope(surf: wp.array2d(dtype=real), i: int, c: real, kp1: real, r2: real):
        # sag z(r) and dz/d(r^2); ok = 0 beyond the conic's extent
        q = real(1.0) - kp1 * c * c * r2
        sag = real(0.0)
        slope = real(0.0)
        ok = int(0)
        if q > real(0.0):
            root = wp.sqrt(q)
            sag = c * r2 / (real(1.0) + root)
            slope = c / (real(2.0) * root)
            nasph = int(surf[i, S_NASPH])
            poly = real(0.0)
            dpoly = real(0.0)
            for jj in range(nasph):
                j = nasph - 1 - jj
                a = surf[i, S_ASPH + j]
                poly = poly * r2 + a
                dpoly = dpoly * r2 + real(j + 1) * a
            sag = sag + poly * r2
            slope = slope + dpoly
            ok = int(1)
        return ok, sag, slope

    @func
    def intersect(surf: wp.array2d(dtype=real), i: int, x: real, y: real, z: real, L: real, M: real, N: real):
        # returns status, t, unit normal (nx, ny, nz) toward +z
        c = surf[i, S_C]
        kp1 = surf[i, S_KP1]
        kind = int(surf[i, S_KIND])
        status = int(OK)
        t = real(0.0)
        nx = real(0.0)
        ny = real(0.0)
        nz = real(1.0)
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
                nz = real(1.0) - c * kp1 * pz
        else:
            ok, t = conic_t(c, kp1, x, y, z, L, M, N)
            if ok == 0:
                if N == real(0.0):
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
                    df = N - real(2.0) * slope * (px * L + py * M)
                    if df == real(0.0):
                        status = int(NO_CONVERGE)
                    else:
                        dt = (pz - sag) / df
                        t = t - dt
                        if wp.abs(dt) <= real(newton_tol):
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
                    nx = real(-2.0) * slope * px
                    ny = real(-2.0) * slope * py
                    nz = real(1.0)
        inv = real(1.0) / wp.sqrt(nx * nx + ny * ny + nz * nz)
        return status, t, nx * inv, ny * inv, nz * inv

    @func
    def refract(L: real, M: real, N: real, nx: real, ny: real, nz: real, n1: real, n2: real, angles: int):
        # vector Snell's law (Field Guide p. 1); returns status, L', M', N', I, I' (angles only when
        # asked), min(cos I, cos I') (near 90 deg either way the ray is ill-conditioned)
        cos_i = L * nx + M * ny + N * nz
        sx = nx
        sy = ny
        sz = nz
        if cos_i < real(0.0):
            sx = -nx
            sy = -ny
            sz = -nz
            cos_i = -cos_i
        mu = n1 / n2
        k = real(1.0) - mu * mu * (real(1.0) - cos_i * cos_i)
        status = int(OK)
        L2 = L
        M2 = M
        N2 = N
        ang_i = real(0.0)
        ang_r = real(0.0)
        sin_i = real(0.0)
        if angles != 0:
            cx = M * sz - N * sy
            cy = N * sx - L * sz
            cz = L * sy - M * sx
            sin_i = wp.sqrt(cx * cx + cy * cy + cz * cz)
            ang_i = wp.atan2(sin_i, cos_i)
        cos_min = cos_i
        if k < real(0.0):
            status = int(TIR)
        else:
            cos_r = wp.sqrt(k)
            cos_min = wp.min(cos_i, cos_r)
            g = cos_r - mu * cos_i
            L2 = mu * L + g * sx
            M2 = mu * M + g * sy
            N2 = mu * N + g * sz
            inv = real(1.0) / wp.sqrt(L2 * L2 + M2 * M2 + N2 * N2)
            L2 = L2 * inv
            M2 = M2 * inv
            N2 = N2 * inv
            if angles != 0:
                ang_r = wp.atan2(mu * sin_i, cos_r)
        return status, L2, M2, N2, ang_i, ang_r, cos_min

    @func
    def inside_iris(iris: wp.array(dtype=real), x: real, y: real) -> int:
        # circle or regular N-gon (vertex at the rotation angle), roundness, central obstruction
        r = wp.sqrt(x * x + y * y)
        limit = iris[IRIS_RADIUS]
        inside = int(1)
        if r < iris[IRIS_OBSTRUCTION]:
            inside = int(0)
        blades = iris[IRIS_BLADES]
        if blades == real(0.0):
            if r > limit:
                inside = int(0)
        elif r > limit:
            inside = int(0)
        elif r > limit * iris[IRIS_COS_HALF]:  # only the ring between the in- and circumcircle needs the angle
            half = iris[IRIS_HALF]
            phi = wp.atan2(y, x) - iris[IRIS_ROTATION]
            phi = phi - real(2.0) * half * wp.floor(phi / (real(2.0) * half))
            rho = limit * iris[IRIS_COS_HALF] / wp.cos(phi - half)
            rho = rho + iris[IRIS_ROUNDNESS] * (limit - rho)
            if r > rho:
                inside = int(0)
        return inside

    @func
    def trace_ray(surf: wp.array2d(dtype=real), media: wp.array2d(dtype=real), iris: wp.array(dtype=real),
                  n_surfaces: int, x0: real, y0: real, z0: real, L0: real, M0: real, N0: real, w2: real,
                  index_table: wp.array2d(dtype=real), table_row: int, end: int, clip: int, plane_dz: real,
                  record: int, rec: wp.array3d(dtype=real), ray: int):
        """Trace one ray; returns status, surface, x, y, z (frame of the last surface met), L, M, N, opl,
        and the smallest cos of the angles of incidence and refraction met (grazing rays are
        ill-conditioned).

        Refracts at surfaces 0 .. end-1 and stops on surface ``end`` (``end = n_surfaces``:
        the plane ``plane_dz`` behind the image surface). ``table_row >= 0`` takes indices
        from ``index_table`` instead of the dispersion formula.
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
        opl = real(0.0)
        min_cos = real(1.0)
        if not (norm > real(0.0)) or not wp.isfinite(norm) or not wp.isfinite(x + y + z):
            status = int(INVALID)
            where = int(0)
        else:
            L = L / norm
            M = M / norm
            N = N / norm
        n1 = real(0.0)
        if table_row >= 0:
            n1 = index_table[table_row, 0]
        else:
            n1 = medium_index(media, 0, w2)
        if status == int(OK) and not (n1 > real(0.0)):
            status = int(INVALID)
            where = int(0)
        i = int(0)
        while status == int(OK) and i <= end:
            if i == n_surfaces:
                z = z - plane_dz  # the plane may stand apart from the image surface
            st, t, nx, ny, nz = intersect(surf, i, x, y, z, L, M, N)
            if st == int(OK) and L * nx + M * ny + N * nz < real(0.0):
                st = int(MISSED)  # met from behind (from the medium after it): no sequential path
            if st != int(OK):
                status = st
                where = i
            else:
                x = x + t * L
                y = y + t * M
                z = z + t * N
                opl = opl + n1 * t
                ang_i = real(0.0)
                ang_r = real(0.0)
                if i < end:
                    if clip != 0:
                        passed = int(1)
                        if i == int(iris[IRIS_STOP]):
                            if iris[IRIS_RADIUS] > real(0.0):
                                passed = inside_iris(iris, x, y)
                        else:
                            sd2 = surf[i, S_SD2]
                            if sd2 >= real(0.0) and x * x + y * y > sd2:
                                passed = int(0)
                        if passed == 0:
                            status = int(VIGNETTED)
                            where = i
                    if status == int(OK):
                        n2 = real(0.0)
                        if table_row >= 0:
                            n2 = index_table[table_row, i + 1]
                        else:
                            n2 = medium_index(media, i + 1, w2)
                        if not (n2 > real(0.0)):
                            status = int(INVALID)
                            where = i
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
                    rec[ray, i, 2] = z
                    rec[ray, i, 3] = L
                    rec[ray, i, 4] = M
                    rec[ray, i, 5] = N
                    rec[ray, i, 6] = ang_i
                    rec[ray, i, 7] = ang_r
                    rec[ray, i, 8] = t
                if status == int(OK) and i < end:
                    z = z - surf[i, S_THICK]  # into the next vertex frame
            i = i + 1
        return status, where, x, y, z, L, M, N, opl, min_cos

    ns.medium_index = medium_index
    ns.conic_t = conic_t
    ns.sag_slope = sag_slope
    ns.intersect = intersect
    ns.refract = refract
    ns.inside_iris = inside_iris
    ns.trace_ray = trace_ray
    return ns
