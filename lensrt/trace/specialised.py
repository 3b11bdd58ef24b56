"""Lens-specialised trace kernels: the surface loop generated per lens shape, fully unrolled.

The generic kernels (:mod:`.kernels`) loop over the surfaces at run time and read
each surface's packed row from memory, so one compiled module serves every lens.
The kernels here are generated per :class:`~lensrt.trace.shape.LensShape` with
``wp.static``: the loop over surfaces is unrolled at code generation, each surface
runs only the code of its kind (a plane needs no square root, a sphere no
normalisation of its normal, only aspheres iterate), apertures only where they
clip, the iris test only at the stop, the dispersion formula of each glass only
with the terms it uses -- once per ray and medium, air being a constant -- and the
refraction between two identical constant media not at all. The lens's numbers
are one vector of constants passed as a kernel parameter (a struct): on a GPU it
lives in the constant bank, read directly by the arithmetic that uses it.

The mathematics is that of :mod:`.surfaces` (and :mod:`.reference`), rearranged
only where the result is unchanged to rounding:

* a sphere's normal (-c x, -c y, 1 - c z) is a unit vector on the surface, and the
  refracted direction of unit vectors is a unit vector; both are renormalised by
  the first-order step ``v * (1.5 - 0.5 |v|^2)``, exact to O((|v|^2 - 1)^2) (rounding
  level), instead of a square root and a division;
* the second root of the quadric, q / A, is divided out only when it lies on the
  vertex branch (rarely: it is the far side of a sphere);
* Snell's ratio n1 / n2 is n1 * (1 / n2) when n2 is a constant (1 / n2 computed on
  the host; exact for air);
* Sellmeier terms share one division: sum b_j w^2 / d_j = w^2 (sum b_j prod_{k != j} d_k) / prod d_j;
* the N-blade iris test uses the blades' normals (the largest projection of the
  point on them) instead of an arctangent and a cosine;
* per-slot ray counts are int32 (a slot never holds 2^31 rays).

Kernels are built on first use of a (precision, shape, options) key and cached
in-process (``lru_cache``) and on disk (a folder keyed by lensrt's sources and Warp, loaded
without Warp's code generation: :func:`ready`, :mod:`.kernel_cache`);
:func:`lensrt.trace.stream.stream` and :func:`lensrt.trace.api.trace` choose
between them and the generic kernels (``kernel="auto"``; see there).
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations of the
# functions built below as objects (the scalar type ``real`` is a closure variable).

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from types import SimpleNamespace

from .kernels import NEWTON_TOL_F32_MM, NEWTON_TOL_F64_MM, RAY_OUT_COLS
from .pack import real_dtype
from .shape import ASPHERE, CONIC, IRIS_NONE, IRIS_POLYGON, PLANE, SPHERE, Layout, LensShape
from .status import INVALID, MISSED, NO_CONVERGE, OK, TIR, VIGNETTED
from .reference import NEWTON_MAX_ITER

__all__ = ["StreamOptions", "Tuning", "DEFAULT_TUNING", "GPU_TUNING", "stream_kernel", "store_kernel", "module_tag",
           "ready"]


@dataclass(frozen=True)
class StreamOptions:
    """Compile-time options of a specialised stream kernel.

    sampler : int
        Sampler code (:data:`lensrt.trace.sampling.SAMPLERS`).
    table : bool
        Indices from the per-line table (discrete spectrum) instead of the dispersion formula.
    channels : bool
        Spectral channel table (else one channel of weight 1).
    histogram : bool
        Bin rays into the histogram (False: only counts and moments, e.g. for pupil areas).
    """

    sampler: int
    table: bool
    channels: bool
    histogram: bool = True


@dataclass(frozen=True)
class Tuning:
    """CUDA code-generation knobs of a specialised kernel (no effect on results).

    max_registers : int or None
        ``__maxnreg__`` cap per thread (more resident warps; None: the compiler's choice).
    grid_stride : bool
        Warp's grid-stride loop around the kernel body (False: one thread per launch index).
    consts : {'param', 'array'}
        The lens constants as a vector kernel parameter (constant bank) or a device array.
    """

    max_registers: int | None = None
    grid_stride: bool = False
    consts: str = "param"


DEFAULT_TUNING = Tuning()
#: the tuning the stream and store wrappers use on CUDA devices, per precision (measured on an
#: H100: float64 at 150 registers runs one 256-thread block per multiprocessor; capped at 128,
#: two, 38 % faster; float32 needs 92 and gains nothing from a cap)
GPU_TUNING = {"float32": Tuning(), "float64": Tuning(max_registers=128)}


def _kernel_kwargs(tuning: Tuning) -> dict:
    kw = {"enable_backward": False, "grid_stride": tuning.grid_stride}
    if tuning.max_registers is not None:
        kw["cuda_max_registers"] = int(tuning.max_registers)
    return kw


def module_tag(*key) -> str:
    """A short stable digest of a kernel key (module names)."""
    return hashlib.sha1(repr(key).encode()).hexdigest()[:12]


def _consts_type(wp, real, size: int, mode: str):
    """Type of the constants argument: a vector kernel parameter ('param') or a device array ('array')."""
    if mode == "param":
        return wp.types.vector(length=size, dtype=real)
    return wp.array(dtype=real)


def _make_sag(wp, real, module, shape, lay, Consts, i: int):
    """``sag_slope`` of asphere ``i`` (its coefficients at fixed offsets of the constants)."""
    na = shape.n_asphere[i]
    base = lay.asph[i]

    def sag_slope(P: Consts, c: real, kp1: real, r2: real):
        # surfaces.sag_slope: sag z(r) and dz/d(r^2); ok false beyond the conic's extent
        q = real(1.0) - kp1 * c * c * r2
        root = wp.sqrt(wp.max(q, real(0.0)))
        poly = real(0.0)
        dpoly = real(0.0)
        for jj in range(wp.static(na)):
            a = P[wp.static(base + na - 1 - jj)]
            poly = poly * r2 + a
            dpoly = dpoly * r2 + real(wp.static(float(na - jj))) * a
        sag = c * r2 / (real(1.0) + root) + poly * r2
        slope = c / (real(2.0) * wp.where(q > real(0.0), root, real(1.0))) + dpoly
        return q > real(0.0), sag, slope

    return wp.func(sag_slope, module=module, name=f"sag_slope_s{i}")


def _make_asphere(wp, real, module, shape, lay, Consts, i: int, quadric_t):
    """``intersect_asphere`` of surface ``i``."""
    newton_tol = NEWTON_TOL_F64_MM if real is wp.float64 else NEWTON_TOL_F32_MM
    sag_slope = _make_sag(wp, real, module, shape, lay, Consts, i)
    co, ko = lay.c[i], lay.kp1[i]

    def intersect_asphere(P: Consts, x: real, y: real, z: real, L: real, M: real, N: real):
        # surfaces.intersect for kind 2: Newton on the sag from the conic's root; returns
        # status, t, unit normal
        c = real(0.0)
        if wp.static(co >= 0):
            c = P[wp.static(co)]
        kp1 = P[wp.static(ko)]
        ok, t = quadric_t(c, kp1, x, y, z, L, M, N)
        status = wp.where(ok or N != real(0.0), int(OK), int(MISSED))
        t = wp.where(ok, t, -z / wp.where(N != real(0.0), N, real(1.0)))
        converged = int(0)
        it = int(0)
        while status == int(OK) and converged == 0 and it < NEWTON_MAX_ITER:
            px = x + t * L
            py = y + t * M
            pz = z + t * N
            oks, sag, slope = sag_slope(P, c, kp1, px * px + py * py)
            df = N - real(2.0) * slope * (px * L + py * M)
            dt = (pz - sag) / wp.where(df != real(0.0), df, real(1.0))
            status = wp.where(oks, wp.where(df == real(0.0), int(NO_CONVERGE), int(OK)), int(MISSED))
            step = status == int(OK)
            t = wp.where(step, t - dt, t)
            converged = wp.where(step and wp.abs(dt) <= real(newton_tol), 1, 0)
            it = it + 1
        status = wp.where(status == int(OK) and converged == 0, int(NO_CONVERGE), status)
        px = x + t * L
        py = y + t * M
        oks, sag, slope = sag_slope(P, c, kp1, px * px + py * py)
        status = wp.where(status == int(OK) and not oks, int(MISSED), status)
        nx = real(-2.0) * slope * px
        ny = real(-2.0) * slope * py
        inv = real(1.0) / wp.sqrt(nx * nx + ny * ny + real(1.0))
        return status, t, nx * inv, ny * inv, inv

    return wp.func(intersect_asphere, module=module, name=f"intersect_asphere_s{i}")


def _make_medium(wp, real, module, shape, lay, Consts, m: int):
    """``medium_n`` of medium ``m`` with its terms only (None for a constant index)."""
    ms = shape.media[m]
    if ms.constant:
        return None
    p = lay.p[m]
    b = lay.b[m]
    cs = lay.cs[m]
    top = max(ms.inverse) if ms.inverse else 0
    sell = list(ms.sellmeier)
    ns = len(sell)
    b0 = b[sell[0]] if ns > 0 else -1
    b1 = b[sell[1]] if ns > 1 else -1
    b2 = b[sell[2]] if ns > 2 else -1
    c0 = cs[sell[0]] if ns > 0 else -1
    c1 = cs[sell[1]] if ns > 1 else -1
    c2 = cs[sell[2]] if ns > 2 else -1

    def medium_n(P: Consts, w2: real, inv: real) -> real:
        # n(w) of materials.index_from_packed with this medium's terms only; -1 where n^2 <= 0
        n2 = real(0.0)
        if wp.static(p[0] >= 0):
            n2 = P[wp.static(p[0])]
        if wp.static(p[2] >= 0):
            n2 = n2 + w2 * w2 * P[wp.static(p[2])]
        if wp.static(p[1] >= 0):
            n2 = n2 + w2 * P[wp.static(p[1])]
        if wp.static(top > 0):
            # sum_k p_k inv^(k - 2), k = 3 .. top, by Horner
            acc = real(0.0)
            for kk in range(wp.static(top - 2)):
                acc = acc * inv
                if wp.static(p[top - kk] >= 0):
                    acc = acc + P[wp.static(p[top - kk])]
            n2 = n2 + acc * inv
        if wp.static(ns == 1):
            n2 = n2 + P[wp.static(b0)] * w2 / (w2 - P[wp.static(c0)])
        elif wp.static(ns == 2):
            d0 = w2 - P[wp.static(c0)]
            d1 = w2 - P[wp.static(c1)]
            n2 = n2 + w2 * (P[wp.static(b0)] * d1 + P[wp.static(b1)] * d0) / (d0 * d1)
        elif wp.static(ns == 3):
            d0 = w2 - P[wp.static(c0)]
            d1 = w2 - P[wp.static(c1)]
            d2 = w2 - P[wp.static(c2)]
            num = P[wp.static(b0)] * d1 * d2 + P[wp.static(b1)] * d0 * d2 + P[wp.static(b2)] * d0 * d1
            n2 = n2 + w2 * num / (d0 * d1 * d2)
        return wp.where(n2 > real(0.0), wp.sqrt(wp.max(n2, real(0.0))), real(-1.0))

    return wp.func(medium_n, module=module, name=f"medium_n_m{m}")


def _make_inside_stop(wp, real, module, shape, lay, Consts):
    """``inside_stop``: the iris test at the stop (None when the lens has no iris)."""
    iris = shape.iris
    blades = shape.blades
    if iris == IRIS_NONE:
        return None

    def inside_stop(P: Consts, x: real, y: real) -> bool:
        # surfaces.inside_iris: circle or regular N-gon (blade normals), roundness, obstruction
        r2 = x * x + y * y
        inside = r2 <= P[wp.static(lay.iris_limit2)]
        if wp.static(shape.obstruction):
            inside = inside and not (r2 < P[wp.static(lay.iris_obs2)])
        if wp.static(iris == IRIS_POLYGON):
            # the largest projection on the blades' outward normals is r cos(phi - half) in the
            # nearest blade's sector; outside when r > rho + roundness (limit - rho), rho = a r / p
            p = x * P[wp.static(lay.blade_cos)] + y * P[wp.static(lay.blade_sin)]
            for k in range(wp.static(blades - 1)):
                p = wp.max(p, x * P[wp.static(lay.blade_cos + 1 + k)] + y * P[wp.static(lay.blade_sin + 1 + k)])
            a = P[wp.static(lay.iris_apothem)]
            if wp.static(shape.rounded):
                r = wp.sqrt(r2)
                rnd = P[wp.static(lay.iris_round)]
                inside = inside and not (r * p > (real(1.0) - rnd) * a * r + rnd * P[wp.static(lay.iris_limit)] * p)
            else:
                inside = inside and not (p > a)
        return inside

    return wp.func(inside_stop, module=module)


def _make_trace_fast(wp, real, module, shape, lay, Consts, table, quadric_t, unit_near_one, refract_unit,
                     medium_fns, asphere_fns, inside_stop):
    """``trace_fast``: one ray through the unrolled surface loop of ``shape``."""
    n = shape.n_surfaces
    kinds = tuple(shape.kinds) + (PLANE,)
    is_const = [ms.constant for ms in shape.media]
    iris = shape.iris
    stop = shape.stop

    def trace_fast(P: Consts, x0: real, y0: real, z0: real, L0: real, M0: real, N0: real, w2: real,
                   index_table: wp.array2d(dtype=real), row: int, plane_dz: real):
        """Trace one ray (surfaces.trace_ray with end = n_surfaces, no record); returns status,
        surface, x, y, z (frame of the last surface met), L, M, N, opl, smallest cos of the angles of
        incidence and refraction."""
        norm = wp.sqrt(L0 * L0 + M0 * M0 + N0 * N0)
        good = norm > real(0.0) and wp.isfinite(norm) and wp.isfinite(x0 + y0 + z0)
        x = x0
        y = y0
        z = z0
        sn = wp.where(good, norm, real(1.0))
        L = L0 / sn
        M = M0 / sn
        N = N0 / sn
        inv = real(1.0)
        if wp.static(not table):
            inv = real(1.0) / w2
        n1 = real(1.0)
        if wp.static(is_const[0]):
            n1 = P[wp.static(lay.n[0])]
        elif wp.static(table):
            n1 = index_table[row, 0]
        else:
            n1 = wp.static(medium_fns[0])(P, w2, inv)
        good = good and n1 > real(0.0)
        status = wp.where(good, int(OK), int(INVALID))
        where = wp.where(good, int(-1), int(0))
        opl = real(0.0)
        min_cos = real(1.0)
        for i in range(wp.static(n + 1)):
            alive = status == int(OK)
            if wp.static(i == n):
                z = wp.where(alive, z - plane_dz, z)
            st = int(OK)
            t = real(0.0)
            nx = real(0.0)
            ny = real(0.0)
            nz = real(1.0)
            if wp.static(kinds[i] == PLANE):
                st = wp.where(N == real(0.0), int(MISSED), int(OK))
                t = -z / wp.where(N == real(0.0), real(1.0), N)
            elif wp.static(kinds[i] == SPHERE or kinds[i] == CONIC):
                c = P[wp.static(lay.c[i])]
                kp1 = real(1.0)
                if wp.static(kinds[i] == CONIC):
                    kp1 = P[wp.static(lay.kp1[i])]
                ok, t = quadric_t(c, kp1, x, y, z, L, M, N)
                st = wp.where(ok, int(OK), int(MISSED))
                nx = -c * (x + t * L)
                ny = -c * (y + t * M)
                nz = real(1.0) - c * kp1 * (z + t * N)
                if wp.static(kinds[i] == SPHERE):
                    nx, ny, nz = unit_near_one(nx, ny, nz)
                else:
                    ninv = real(1.0) / wp.sqrt(nx * nx + ny * ny + nz * nz)
                    nx = nx * ninv
                    ny = ny * ninv
                    nz = nz * ninv
            else:
                st, t, nx, ny, nz = wp.static(asphere_fns[i])(P, x, y, z, L, M, N)
            # met from behind (from the medium after it): no sequential path (surfaces.trace_ray)
            st = wp.where(st == int(OK) and L * nx + M * ny + N * nz < real(0.0), int(MISSED), st)
            hit = alive and st == int(OK)
            status = wp.where(alive and not hit, st, status)
            where = wp.where(alive and not hit, i, where)
            x = wp.where(hit, x + t * L, x)
            y = wp.where(hit, y + t * M, y)
            z = wp.where(hit, z + t * N, z)
            opl = wp.where(hit, opl + n1 * t, opl)
            if wp.static(i < n):
                passed = hit
                if wp.static(i == stop and iris != IRIS_NONE):
                    passed = hit and wp.static(inside_stop)(P, x, y)
                elif wp.static(shape.clips[i] if i < n else False):
                    passed = hit and x * x + y * y <= P[wp.static(lay.sd2[i] if i < n else 0)]
                status = wp.where(hit and not passed, int(VIGNETTED), status)
                where = wp.where(hit and not passed, i, where)
                if wp.static(shape.same_index[i] if i < n else False):
                    # the same constant index on both sides: the direction goes on
                    min_cos = wp.where(passed, wp.min(min_cos, wp.abs(L * nx + M * ny + N * nz)), min_cos)
                    z = wp.where(passed, z - P[wp.static(lay.thick[i] if i < n else 0)], z)
                else:
                    n2 = real(1.0)
                    mu = real(1.0)
                    if wp.static(is_const[i + 1] if i < n else True):
                        n2 = P[wp.static(lay.n[i + 1] if i < n else 0)]
                        mu = n1 * P[wp.static(lay.inv_n[i + 1] if i < n else 0)]
                    else:
                        if wp.static(table):
                            n2 = index_table[row, i + 1]
                        else:
                            n2 = wp.static(medium_fns[i + 1] if i < n else None)(P, w2, inv)
                        mu = n1 / n2
                    valid = n2 > real(0.0)
                    status = wp.where(passed and not valid, int(INVALID), status)
                    where = wp.where(passed and not valid, i, where)
                    tir, L2, M2, N2, cos_ir = refract_unit(L, M, N, nx, ny, nz, mu)
                    go = passed and valid
                    min_cos = wp.where(go, wp.min(min_cos, cos_ir), min_cos)
                    status = wp.where(go and tir, int(TIR), status)
                    where = wp.where(go and tir, i, where)
                    go = go and not tir
                    L = wp.where(go, L2, L)
                    M = wp.where(go, M2, M)
                    N = wp.where(go, N2, N)
                    n1 = wp.where(go, n2, n1)
                    z = wp.where(go, z - P[wp.static(lay.thick[i] if i < n else 0)], z)
        return status, where, x, y, z, L, M, N, opl, min_cos

    return wp.func(trace_fast, module=module)


def _build_trace(wp, real, module, shape, table, Consts):
    """The specialised ``@wp.func`` s of ``shape``; ``trace_fast`` traces one ray.

    The code is branch-free (``wp.where`` selects, no ``if`` that assigns): every value is
    defined on every path, so a kernel looping over rays keeps no value of one ray alive
    into the next (with branches, Warp's code generation leaves values that only one branch
    defines, which the CUDA compiler must carry around the loop -- hundreds of registers).
    A warp runs every branch its threads take anyway; failed rays keep their last state.
    """
    lay = Layout(shape)
    n = shape.n_surfaces
    kinds = tuple(shape.kinds) + (PLANE,)
    from .kernels.fast import quadric_t, refract_unit, unit_near_one
    medium_fns = [_make_medium(wp, real, module, shape, lay, Consts, m) for m in range(n + 1)]
    asphere_fns = [_make_asphere(wp, real, module, shape, lay, Consts, i, quadric_t) if kinds[i] == ASPHERE else None
                   for i in range(n)] + [None]
    inside_stop = _make_inside_stop(wp, real, module, shape, lay, Consts)
    trace_fast = _make_trace_fast(wp, real, module, shape, lay, Consts, table, quadric_t, unit_near_one,
                                  refract_unit, medium_fns, asphere_fns, inside_stop)
    return SimpleNamespace(trace_fast=trace_fast, quadric_t=quadric_t, refract_unit=refract_unit,
                           inside_stop=inside_stop, medium_fns=medium_fns)



def _module(kind: str, precision: str, key) -> str:
    return f"lensrt_fast_{kind}_{precision}_{module_tag(precision, key)}"


@lru_cache(maxsize=64)
def store_kernel(precision: str, shape: LensShape, tuning: Tuning = DEFAULT_TUNING) -> SimpleNamespace:
    """The specialised store kernel of ``shape`` (to the image plane, formula indices, no record)."""
    from ..device import warp
    wp = warp()
    real = real_dtype(wp, precision)
    mod = _module("store", precision, (shape, tuning))
    wp.set_module_options({"enable_backward": False}, module=mod)
    lay = Layout(shape)
    Consts = _consts_type(wp, real, lay.size, tuning.consts)
    trace_fast = _build_trace(wp, real, mod, shape, False, Consts).trace_fast
    from .kernels.surfaces import write_ray

    @wp.kernel(module=mod, **_kernel_kwargs(tuning))
    def trace_store_fast(P: Consts, rays: wp.array2d(dtype=real), plane_dz: real,
                         index_table: wp.array2d(dtype=real), ray_base: int, out: wp.array2d(dtype=real),
                         status: wp.array(dtype=wp.int32), surface: wp.array(dtype=wp.int32)):
        r = wp.tid() + ray_base
        w_um = rays[r, 6] * real(1.0e-3)
        st, where, x, y, z, L, M, N, opl, min_cos = trace_fast(
            P, rays[r, 0], rays[r, 1], rays[r, 2], rays[r, 3], rays[r, 4], rays[r, 5], w_um * w_um,
            index_table, -1, plane_dz)
        write_ray(out, status, surface, r, st, where, x, y, z, L, M, N, opl, min_cos)

    assert RAY_OUT_COLS == 8
    return SimpleNamespace(kernel=trace_store_fast, Consts=Consts, consts_mode=tuning.consts, module=mod, real=real,
                           layout=lay, trace_fast=trace_fast, key=repr(("store", precision, shape, tuning)))


def _fast_samples(wp, real, module: str, sampler: int):
    """``samples(i, sl, bseed, wseed, rseed)``: ray i's pupil point (u0, u1) and wavelength sample,
    the sampler fixed at compile time (the generic kernel's ``generic_samples``, branch-free)."""
    from .kernels import sampling as sm
    from .kernels import stream_body as sb

    def samples(i: int, sl: sb.Slots, bseed: wp.uint32, wseed: wp.uint32, rseed: int):
        u0 = real(0.0)
        u1 = real(0.0)
        uw = real(0.0)
        if wp.static(sampler == 2):
            u0, u1 = sm.sobol_2d(wp.uint32(i), bseed, real(0.0))
            uw = sm.sobol_1d(wp.uint32(i), wseed, real(0.0))
        elif wp.static(sampler == 3):
            state = wp.rand_init(rseed, i)
            u0, u1 = sm.r2_2d(wp.uint32(i), bseed, real(0.0))
            uw = real(wp.randf(state))
        else:
            state = wp.rand_init(rseed, i)
            u0 = real(wp.randf(state))
            u1 = real(wp.randf(state))
            uw = real(wp.randf(state))
            if wp.static(sampler == 1):
                # n_wstrata wavelength strata, each with an n_strata^2 jittered pupil grid
                n_cells = sl.n_strata * sl.n_strata
                strat = i < n_cells * sl.n_wstrata
                cell = i % n_cells
                u0 = wp.where(strat, (real(cell % sl.n_strata) + u0) / real(sl.n_strata), u0)
                u1 = wp.where(strat, (real(cell // sl.n_strata) + u1) / real(sl.n_strata), u1)
                uw = wp.where(strat, (real(i // n_cells) + uw) / real(sl.n_wstrata), uw)
        return u0, u1, uw

    return wp.func(samples, module=module, name=f"samples_{sampler}")


@lru_cache(maxsize=64)
def stream_kernel(precision: str, shape: LensShape, opts: StreamOptions,
                  tuning: Tuning = DEFAULT_TUNING) -> SimpleNamespace:
    """The specialised stream kernel of ``shape`` with ``opts`` (the generic trace_stream's contract
    and per-ray body, :mod:`lensrt.trace.kernels.stream_body`; only the samples and the trace differ)."""
    from ..device import warp
    from .kernels import stream_body as sb
    wp = warp()
    real = real_dtype(wp, precision)
    mod = _module("stream", precision, (shape, opts, tuning))
    wp.set_module_options({"enable_backward": False}, module=mod)
    lay = Layout(shape)
    Consts = _consts_type(wp, real, lay.size, tuning.consts)
    trace_fast = _build_trace(wp, real, mod, shape, opts.table, Consts).trace_fast
    samples = _fast_samples(wp, real, mod, int(opts.sampler))
    table, channels, histogram = int(opts.table), int(opts.channels), bool(opts.histogram)

    Source = sb.SOURCE[precision]

    @wp.kernel(module=mod, **_kernel_kwargs(tuning))
    def trace_stream_fast(P: Consts, sources: wp.array(dtype=Source), src_int: wp.array2d(dtype=wp.int32),
                          spec_nm: wp.array(dtype=real), spec_cdf: wp.array(dtype=real),
                          index_table: wp.array2d(dtype=real), chan: wp.array2d(dtype=real), chan_nm0: real,
                          chan_dnm: real, h: sb.Histogram, sl: sb.Slots, stats: wp.array2d(dtype=wp.float64),
                          counts: wp.array2d(dtype=wp.int64)):
        # one thread per slot (the generic trace_stream's contract and body)
        tid = wp.tid() + sl.tid_base
        q, src, batch, rep = sb.slot_of(tid, sl, h)
        bseed, wseed, rseed = sb.batch_seeds(src_int, src, sl, batch)
        s = sources[src]
        base = sb.hist_base(h, s, rep, batch)
        plane_dz = s.plane_dz_mm
        sums = sb.SlotSums()
        k = q * sl.slot_rays
        k_end = wp.min(k + sl.slot_rays, sl.count)
        while k < k_end:
            # branch-free like trace_fast (see _build_trace): no value of one ray outlives it
            i = sl.start + k
            u0, u1, uw = samples(i, sl, bseed, wseed, rseed)
            wl, row = sb.pick_wavelength(uw, wp.static(table), spec_nm, spec_cdf, src_int[src, 2], src_int[src, 3])
            px, py, pz, dx, dy, dz, weight = sb.ray_from_source(s, u0, u1)
            w_um = wl * real(1.0e-3)
            st, where, x, y, z, L, M, N, opl, min_cos = trace_fast(
                P, px, py, pz, dx, dy, dz, w_um * w_um, index_table, row, plane_dz)
            sums, on_grid, fx, fy = sb.accumulate(sums, st, min_cos, x, y, weight, s, h)
            if wp.static(histogram):
                if on_grid:
                    sb.bin_ray(h, base, fx, fy, weight, wl, wp.static(channels), chan, chan_nm0, chan_dnm)
            k = k + 1
        sb.store_slot(stats, counts, tid, sums)

    return SimpleNamespace(kernel=trace_stream_fast, Consts=Consts, consts_mode=tuning.consts, module=mod, real=real,
                           layout=lay, trace_fast=trace_fast, key=repr(("stream", precision, shape, opts, tuning)))


def ready(kernels: SimpleNamespace, device: str) -> str:
    """Load the module of a :func:`store_kernel` / :func:`stream_kernel` on ``device`` before its first launch,
    from lensrt's keyed folder without Warp's code generation where it can (:mod:`.kernel_cache`); returns how
    (``"cached"``, ``"compiled"`` or ``"warp"``)."""
    from .kernel_cache import load_module
    return load_module(kernels.module, kernels.key, device)
