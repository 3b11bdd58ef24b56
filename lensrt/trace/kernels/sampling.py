"""Samplers as generic Warp functions: point sets on the unit square, maps from it, spectra.

The samplers themselves are described in :mod:`lensrt.trace.sampling` (host side: names,
codes, spectra). Functions whose result has no argument of the real type to take it from
(``to_unit`` and the point sets) take ``like``: any value of the wanted scalar type (float32
or float64); Warp instantiates them per type (``to_unit`` is two overloads, as its code
differs by precision).
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..sampling import R2_ALPHA_U32

__all__ = ["i32", "hash_u32", "reverse_bits", "laine_karras", "owen", "sobol_dim1_reversed", "sobol_dim1",
           "to_unit", "sobol_2d", "sobol_1d", "r2_2d", "unit_square", "box", "concentric_disk", "sample_spectrum",
           "sample_cdf"]

wp.set_module_options({"enable_backward": False})


def i32(x: int) -> int:
    """The int32 with the bit pattern of the uint32 ``x`` (Warp emits integer literals as int32)."""
    x &= 0xFFFFFFFF
    return x - (1 << 32) if x >= (1 << 31) else x


# 32-bit constants as int32 bit patterns
K_00FF00FF = i32(0x00FF00FF)
K_0F0F0F0F = i32(0x0F0F0F0F)
K_33333333 = i32(0x33333333)
K_55555555 = i32(0x55555555)
K_6C50B47C = i32(0x6C50B47C)
K_7FEB352D = i32(0x7FEB352D)
K_0000FFFF = i32(0x0000FFFF)
K_846CA68B = i32(0x846CA68B)
K_85EBCA6B = i32(0x85EBCA6B)
K_8D22F6E6 = i32(0x8D22F6E6)
K_9E3779B9 = i32(0x9E3779B9)
K_B82F1E52 = i32(0xB82F1E52)
K_C7AFE638 = i32(0xC7AFE638)
R2_A1, R2_A2 = (i32(v) for v in R2_ALPHA_U32)

_REVERSE_BITS_SNIPPET = """
#if defined(__CUDA_ARCH__)
    return __brev(x);
#else
    uint32_t v = x;
    v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
    v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
    v = ((v >> 4) & 0x0F0F0F0Fu) | ((v & 0x0F0F0F0Fu) << 4);
    v = ((v >> 8) & 0x00FF00FFu) | ((v & 0x00FF00FFu) << 8);
    return (v >> 16) | (v << 16);
#endif
"""


@wp.func
def hash_u32(x: wp.uint32) -> wp.uint32:
    # lowbias32 (C. Wellons): a good 32-bit integer hash
    x = x ^ (x >> wp.uint32(16))
    x = x * wp.uint32(K_7FEB352D)
    x = x ^ (x >> wp.uint32(15))
    x = x * wp.uint32(K_846CA68B)
    x = x ^ (x >> wp.uint32(16))
    return x


# one instruction on a GPU (__brev), five swap steps elsewhere -- the same bits (a native snippet;
# the decorator must be spelled @wp.func_native for Warp to read the return type)
@wp.func_native(_REVERSE_BITS_SNIPPET)
def reverse_bits(x: wp.uint32) -> wp.uint32:
    ...


@wp.func
def laine_karras(x: wp.uint32, seed: wp.uint32) -> wp.uint32:
    x = x + seed
    x = x ^ (x * wp.uint32(K_6C50B47C))
    x = x ^ (x * wp.uint32(K_B82F1E52))
    x = x ^ (x * wp.uint32(K_C7AFE638))
    x = x ^ (x * wp.uint32(K_8D22F6E6))
    return x


@wp.func
def owen(x: wp.uint32, seed: wp.uint32) -> wp.uint32:
    # nested uniform scramble of x read as a binary fraction (most significant bit first)
    return reverse_bits(laine_karras(reverse_bits(x), seed))


@wp.func
def sobol_dim1_reversed(i: wp.uint32) -> wp.uint32:
    # the second Sobol' dimension (direction numbers v_1 = 2^31, v_k = v_{k-1} ^ (v_{k-1} >> 1)),
    # bit-reversed: its generator is the Pascal matrix mod 2, so output bit m is the parity of
    # the bits j of i with m a bit-subset of j (Lucas) -- a superset sum over the 5 index bits
    y = i
    y = y ^ ((y >> wp.uint32(1)) & wp.uint32(K_55555555))
    y = y ^ ((y >> wp.uint32(2)) & wp.uint32(K_33333333))
    y = y ^ ((y >> wp.uint32(4)) & wp.uint32(K_0F0F0F0F))
    y = y ^ ((y >> wp.uint32(8)) & wp.uint32(K_00FF00FF))
    y = y ^ ((y >> wp.uint32(16)) & wp.uint32(K_0000FFFF))
    return y


@wp.func
def sobol_dim1(i: wp.uint32) -> wp.uint32:
    return reverse_bits(sobol_dim1_reversed(i))


# [0, 1) without rounding up to 1 in float32: one overload per precision
@wp.func
def to_unit(x: wp.uint32, like: wp.float64) -> wp.float64:
    return wp.float64(x) * wp.float64(2.3283064365386963e-10)


@wp.func
def to_unit(x: wp.uint32, like: wp.float32) -> wp.float32:  # noqa: F811 -- a Warp overload
    return wp.float32(x >> wp.uint32(8)) * wp.float32(5.9604644775390625e-08)


@wp.func
def sobol_2d(i: wp.uint32, seed: wp.uint32, like: Any):
    # owen(reverse_bits(idx), s1) and owen(sobol_dim1(idx), s2), with owen = rev o LK o rev
    # and rev o rev = id: the same points with fewer reversals
    idx = owen(i, hash_u32(seed))
    s1 = hash_u32(seed ^ wp.uint32(K_9E3779B9))
    s2 = hash_u32(s1)
    return (to_unit(reverse_bits(laine_karras(idx, s1)), like),
            to_unit(reverse_bits(laine_karras(sobol_dim1_reversed(idx), s2)), like))


@wp.func
def sobol_1d(i: wp.uint32, seed: wp.uint32, like: Any):
    idx = owen(i, hash_u32(seed))
    return to_unit(reverse_bits(laine_karras(idx, hash_u32(seed ^ wp.uint32(K_85EBCA6B)))), like)


@wp.func
def r2_2d(i: wp.uint32, seed: wp.uint32, like: Any):
    s1 = hash_u32(seed)
    s2 = hash_u32(s1)
    return to_unit(s1 + i * wp.uint32(R2_A1), like), to_unit(s2 + i * wp.uint32(R2_A2), like)


@wp.func
def unit_square(kind: int, i: int, n_strata_x: int, n_strata_y: int, seed: wp.uint32, state: wp.uint32, like: Any):
    """Point i of a batch: kind 0 random, 1 stratified, 2 sobol, 3 r2 (see SAMPLERS).

    Returns u0, u1 (the type of ``like``) and the advanced random state (Warp passes scalars by value).
    """
    u0 = type(like)(0.0)
    u1 = type(like)(0.0)
    if kind == 2:
        u0, u1 = sobol_2d(wp.uint32(i), seed, like)
    elif kind == 3:
        u0, u1 = r2_2d(wp.uint32(i), seed, like)
    else:
        u0 = type(like)(wp.randf(state))
        u1 = type(like)(wp.randf(state))
        if kind == 1 and i < n_strata_x * n_strata_y:
            cx = i % n_strata_x
            cy = i // n_strata_x
            u0 = (type(like)(cx) + u0) / type(like)(n_strata_x)
            u1 = (type(like)(cy) + u1) / type(like)(n_strata_y)
    return u0, u1, state


@wp.func
def box(u0: Any, u1: Any, a0: Any, a1: Any, b0: Any, b1: Any):
    """Uniform point in [a0, a1) x [b0, b1): returns a, b, pdf."""
    return a0 + u0 * (a1 - a0), b0 + u1 * (b1 - b0), type(u0)(1.0) / ((a1 - a0) * (b1 - b0))


@wp.func
def concentric_disk(u0: Any, u1: Any):
    """Shirley-Chiu concentric map to the unit disc: returns x, y, pdf = 1/pi."""
    ox = type(u0)(2.0) * u0 - type(u0)(1.0)
    oy = type(u0)(2.0) * u1 - type(u0)(1.0)
    x = type(u0)(0.0)
    y = type(u0)(0.0)
    quarter = type(u0)(0.7853981633974483)
    if ox != type(u0)(0.0) or oy != type(u0)(0.0):
        if wp.abs(ox) > wp.abs(oy):
            x = ox * wp.cos(quarter * oy / ox)
            y = ox * wp.sin(quarter * oy / ox)
        else:
            phi = type(u0)(2.0) * quarter - quarter * ox / oy
            x = oy * wp.cos(phi)
            y = oy * wp.sin(phi)
    return x, y, type(u0)(0.3183098861837907)


@wp.func
def sample_spectrum(u: Any, mode: int, nm: wp.array(dtype=Any), cdf: wp.array(dtype=Any), off: int, n: int):
    """Wavelength from spectrum entries off .. off + n of concatenated tables (one spectrum per
    source, :func:`lensrt.trace.stream.stream`): returns (wavelength_nm, table row, pdf) as
    :func:`sample_cdf` does with ``n`` lines or bins starting at ``off``."""
    lo = off
    hi = off + n
    while hi - lo > 1:  # the bin k with cdf[k] <= u < cdf[k + 1]
        mid = (lo + hi) // 2
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    width = cdf[lo + 1] - cdf[lo]
    if mode == 0:
        return nm[lo], lo, width
    f = type(u)(0.5)
    if width > type(u)(0.0):
        f = wp.clamp((u - cdf[lo]) / width, type(u)(0.0), type(u)(1.0))
    return nm[lo] + f * (nm[lo + 1] - nm[lo]), int(-1), width / (nm[lo + 1] - nm[lo])


@wp.func
def sample_cdf(u: Any, mode: int, nm: wp.array(dtype=Any), cdf: wp.array(dtype=Any)):
    """Wavelength from a spectrum: returns (wavelength_nm, line index or -1, pdf).

    mode 0: discrete lines nm[k] with cdf[k] <= u < cdf[k+1] (pdf = the line's probability);
    mode 1: bins [nm[k], nm[k+1]) with uniform density inside (pdf per nm).
    """
    return sample_spectrum(u, mode, nm, cdf, 0, cdf.shape[0] - 1)
