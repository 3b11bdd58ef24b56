"""Samplers for Monte Carlo rays: ``u in [0, 1)^n -> value, pdf``, as Warp functions.

Point sets on the unit square (one function per kind, selected by
:data:`SAMPLERS`):

``random``
    independent uniform points (Warp's PCG generator, ``wp.rand_init(seed, offset)``);
``stratified``
    jittered: the first ``nx * ny`` points of a batch (``nx = ny = floor(sqrt(n))``)
    take one random point in each cell of an nx x ny grid; any rest are random. The
    stream kernel stratifies the wavelength too: ``nw`` strata of the spectrum's CDF,
    each with its own ``nx * ny`` jittered pupil grid (a 3-D jittered grid; ``nw`` = the
    number of lines of a discrete spectrum, about n^(1/3) for a tabulated one:
    :func:`lensrt.trace.stream.strata`);
``sobol``
    the first two Sobol' dimensions with Owen scrambling and index shuffling
    (hash-based nested uniform scrambling, B. Burley, "Practical Hash-based Owen
    Scrambling", JCGT 9(4), 2020); each batch is an independent randomisation,
    so batch means give an honest standard error;
``r2``
    the R2 Kronecker sequence (M. Roberts 2018: alpha = (1/g, 1/g^2), g the plastic
    number) with a Cranley-Patterson rotation per batch, in 32-bit fixed point so
    that float32 keeps every point distinct.

Maps from the square: :func:`box` (uniform in a rectangle, pdf = 1/area),
:func:`concentric_disk` (Shirley & Chiu 1997, pdf = 1/pi), and wavelengths from
a tabulated spectrum (:func:`sample_cdf`: discrete lines or a piecewise-constant
density). Host-side helpers build the tables.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations of the
# functions built below as objects (the scalar type ``real`` is a closure variable).

from types import SimpleNamespace
from typing import Any

import numpy as np

from ..errors import LensrtError

__all__ = ["SAMPLERS", "sampler_code", "sampling_funcs", "sample_unit_square", "Spectrum", "spectrum_discrete",
           "spectrum_continuous", "R2_ALPHA_U32"]

SAMPLERS = ("random", "stratified", "sobol", "r2")
_PLASTIC = 1.324717957244746025960908854
#: R2 step in 32-bit fixed point
R2_ALPHA_U32 = (int(round((1.0 / _PLASTIC) * 2**32)) % 2**32, int(round((1.0 / _PLASTIC**2) * 2**32)) % 2**32)

SPECTRUM_DISCRETE, SPECTRUM_CONTINUOUS = 0, 1


def sampler_code(name: str) -> int:
    """Integer code of a sampler name (kernels take the code)."""
    if name not in SAMPLERS:
        raise LensrtError(f"unknown sampler {name!r}", hint=f"use one of {', '.join(SAMPLERS)}")
    return SAMPLERS.index(name)


class Spectrum:
    """A wavelength distribution to sample rays from: discrete lines or a tabulated density.

    ``mode`` 0: ``wavelength_nm`` are lines with probabilities from ``weights``;
    mode 1: ``wavelength_nm`` are bin edges, ``weights`` the power in each bin
    (uniform within a bin). ``cdf`` is normalised; ``total`` is the sum of weights
    (the integral of the spectrum), to scale estimates back.
    """

    def __init__(self, mode: int, wavelength_nm: np.ndarray, weights: np.ndarray) -> None:
        w = np.asarray(weights, dtype=np.float64)
        nm = np.asarray(wavelength_nm, dtype=np.float64)
        if w.ndim != 1 or len(w) == 0 or np.any(w < 0) or not np.all(np.isfinite(w)) or w.sum() <= 0:
            raise LensrtError("a spectrum needs non-negative finite weights with a positive sum")
        if mode == SPECTRUM_CONTINUOUS and (len(nm) != len(w) + 1 or np.any(np.diff(nm) <= 0)):
            raise LensrtError("a tabulated spectrum needs increasing bin edges, one more than its weights")
        if mode == SPECTRUM_DISCRETE and len(nm) != len(w):
            raise LensrtError("discrete wavelengths need one weight each")
        if np.any(nm < 200.0) or np.any(nm > 20000.0):
            raise LensrtError("wavelengths must lie within 200..20000 nm")
        self.mode = int(mode)
        self.wavelength_nm = nm
        self.weights = w
        self.total = float(w.sum())
        self.cdf = np.concatenate([[0.0], np.cumsum(w) / w.sum()])
        self.cdf[-1] = 1.0

    @property
    def lines_nm(self) -> np.ndarray:
        """The wavelengths of a discrete spectrum (bin centres of a tabulated one)."""
        if self.mode == SPECTRUM_DISCRETE:
            return self.wavelength_nm
        return 0.5 * (self.wavelength_nm[1:] + self.wavelength_nm[:-1])


def spectrum_discrete(wavelength_nm, weights=None) -> Spectrum:
    """Discrete lines (e.g. a lens file's wavelengths with their weights)."""
    nm = np.atleast_1d(np.asarray(wavelength_nm, dtype=np.float64))
    w = np.ones(len(nm)) if weights is None else np.atleast_1d(np.asarray(weights, dtype=np.float64))
    return Spectrum(SPECTRUM_DISCRETE, nm, w)


def spectrum_continuous(edges_nm, power) -> Spectrum:
    """A piecewise-constant spectral density: ``power[i]`` in the bin [edges[i], edges[i+1])."""
    return Spectrum(SPECTRUM_CONTINUOUS, edges_nm, power)


def _i32(x: int) -> int:
    """The int32 with the bit pattern of the uint32 ``x``."""
    x &= 0xFFFFFFFF
    return x - (1 << 32) if x >= (1 << 31) else x


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


_NATIVE: dict = {}


def _reverse_bits(wp: Any) -> Any:
    """``reverse_bits(x: uint32) -> uint32``: one instruction on a GPU (__brev), five swap steps
    elsewhere -- the same bits (a native snippet, defined once per process)."""
    if "reverse_bits" not in _NATIVE:
        # (the decorator must be spelled @wp.func_native for Warp to read the return type)
        @wp.func_native(_REVERSE_BITS_SNIPPET)
        def reverse_bits(x: wp.uint32) -> wp.uint32:
            ...

        _NATIVE["reverse_bits"] = reverse_bits
    return _NATIVE["reverse_bits"]


def sampling_funcs(wp: Any, real: Any, module: str) -> SimpleNamespace:
    """Build the sampler ``@wp.func`` s for scalar type ``real`` in Warp module ``module``."""
    func = wp.func(module=module)
    u32 = wp.uint32
    is64 = real is wp.float64
    # 32-bit constants as int32 bit patterns (Warp emits integer literals as int32)
    K_00FF00FF = _i32(0x00FF00FF)
    K_0F0F0F0F = _i32(0x0F0F0F0F)
    K_33333333 = _i32(0x33333333)
    K_55555555 = _i32(0x55555555)
    K_6C50B47C = _i32(0x6C50B47C)
    K_7FEB352D = _i32(0x7FEB352D)
    K_0000FFFF = _i32(0x0000FFFF)
    K_846CA68B = _i32(0x846CA68B)
    K_85EBCA6B = _i32(0x85EBCA6B)
    K_8D22F6E6 = _i32(0x8D22F6E6)
    K_9E3779B9 = _i32(0x9E3779B9)
    K_B82F1E52 = _i32(0xB82F1E52)
    K_C7AFE638 = _i32(0xC7AFE638)
    a1, a2 = (_i32(v) for v in R2_ALPHA_U32)

    @func
    def hash_u32(x: wp.uint32) -> wp.uint32:
        # lowbias32 (C. Wellons): a good 32-bit integer hash
        x = x ^ (x >> u32(16))
        x = x * u32(K_7FEB352D)
        x = x ^ (x >> u32(15))
        x = x * u32(K_846CA68B)
        x = x ^ (x >> u32(16))
        return x

    reverse_bits = _reverse_bits(wp)

    @func
    def laine_karras(x: wp.uint32, seed: wp.uint32) -> wp.uint32:
        x = x + seed
        x = x ^ (x * u32(K_6C50B47C))
        x = x ^ (x * u32(K_B82F1E52))
        x = x ^ (x * u32(K_C7AFE638))
        x = x ^ (x * u32(K_8D22F6E6))
        return x

    @func
    def owen(x: wp.uint32, seed: wp.uint32) -> wp.uint32:
        # nested uniform scramble of x read as a binary fraction (most significant bit first)
        return reverse_bits(laine_karras(reverse_bits(x), seed))

    @func
    def sobol_dim1_reversed(i: wp.uint32) -> wp.uint32:
        # the second Sobol' dimension (direction numbers v_1 = 2^31, v_k = v_{k-1} ^ (v_{k-1} >> 1)),
        # bit-reversed: its generator is the Pascal matrix mod 2, so output bit m is the parity of
        # the bits j of i with m a bit-subset of j (Lucas) -- a superset sum over the 5 index bits
        y = i
        y = y ^ ((y >> u32(1)) & u32(K_55555555))
        y = y ^ ((y >> u32(2)) & u32(K_33333333))
        y = y ^ ((y >> u32(4)) & u32(K_0F0F0F0F))
        y = y ^ ((y >> u32(8)) & u32(K_00FF00FF))
        y = y ^ ((y >> u32(16)) & u32(K_0000FFFF))
        return y

    @func
    def sobol_dim1(i: wp.uint32) -> wp.uint32:
        return reverse_bits(sobol_dim1_reversed(i))

    @func
    def to_unit(x: wp.uint32) -> real:
        # [0, 1) without rounding up to 1 in float32
        if wp.static(is64):
            return real(x) * real(2.3283064365386963e-10)
        return real(x >> u32(8)) * real(5.9604644775390625e-08)

    @func
    def sobol_2d(i: wp.uint32, seed: wp.uint32):
        # owen(reverse_bits(idx), s1) and owen(sobol_dim1(idx), s2), with owen = rev o LK o rev
        # and rev o rev = id: the same points with fewer reversals
        idx = owen(i, hash_u32(seed))
        s1 = hash_u32(seed ^ u32(K_9E3779B9))
        s2 = hash_u32(s1)
        return (to_unit(reverse_bits(laine_karras(idx, s1))),
                to_unit(reverse_bits(laine_karras(sobol_dim1_reversed(idx), s2))))

    @func
    def sobol_1d(i: wp.uint32, seed: wp.uint32) -> real:
        idx = owen(i, hash_u32(seed))
        return to_unit(reverse_bits(laine_karras(idx, hash_u32(seed ^ u32(K_85EBCA6B)))))

    @func
    def r2_2d(i: wp.uint32, seed: wp.uint32):
        s1 = hash_u32(seed)
        s2 = hash_u32(s1)
        return to_unit(s1 + i * u32(a1)), to_unit(s2 + i * u32(a2))

    @func
    def unit_square(kind: int, i: int, n_strata_x: int, n_strata_y: int, seed: wp.uint32, state: wp.uint32):
        """Point i of a batch: kind 0 random, 1 stratified, 2 sobol, 3 r2 (see SAMPLERS).

        Returns u0, u1 and the advanced random state (Warp passes scalars by value).
        """
        u0 = real(0.0)
        u1 = real(0.0)
        if kind == 2:
            u0, u1 = sobol_2d(u32(i), seed)
        elif kind == 3:
            u0, u1 = r2_2d(u32(i), seed)
        else:
            u0 = real(wp.randf(state))
            u1 = real(wp.randf(state))
            if kind == 1 and i < n_strata_x * n_strata_y:
                cx = i % n_strata_x
                cy = i // n_strata_x
                u0 = (real(cx) + u0) / real(n_strata_x)
                u1 = (real(cy) + u1) / real(n_strata_y)
        return u0, u1, state

    @func
    def box(u0: real, u1: real, a0: real, a1: real, b0: real, b1: real):
        """Uniform point in [a0, a1) x [b0, b1): returns a, b, pdf."""
        return a0 + u0 * (a1 - a0), b0 + u1 * (b1 - b0), real(1.0) / ((a1 - a0) * (b1 - b0))

    @func
    def concentric_disk(u0: real, u1: real):
        """Shirley-Chiu concentric map to the unit disc: returns x, y, pdf = 1/pi."""
        ox = real(2.0) * u0 - real(1.0)
        oy = real(2.0) * u1 - real(1.0)
        x = real(0.0)
        y = real(0.0)
        quarter = real(0.7853981633974483)
        if ox != real(0.0) or oy != real(0.0):
            if wp.abs(ox) > wp.abs(oy):
                x = ox * wp.cos(quarter * oy / ox)
                y = ox * wp.sin(quarter * oy / ox)
            else:
                phi = real(2.0) * quarter - quarter * ox / oy
                x = oy * wp.cos(phi)
                y = oy * wp.sin(phi)
        return x, y, real(0.3183098861837907)

    @func
    def sample_spectrum(u: real, mode: int, nm: wp.array(dtype=real), cdf: wp.array(dtype=real), off: int,
                        n: int):
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
        f = real(0.5)
        if width > real(0.0):
            f = wp.clamp((u - cdf[lo]) / width, real(0.0), real(1.0))
        return nm[lo] + f * (nm[lo + 1] - nm[lo]), int(-1), width / (nm[lo + 1] - nm[lo])

    @func
    def sample_cdf(u: real, mode: int, nm: wp.array(dtype=real), cdf: wp.array(dtype=real)):
        """Wavelength from a spectrum: returns (wavelength_nm, line index or -1, pdf).

        mode 0: discrete lines nm[k] with cdf[k] <= u < cdf[k+1] (pdf = the line's probability);
        mode 1: bins [nm[k], nm[k+1]) with uniform density inside (pdf per nm).
        """
        return sample_spectrum(u, mode, nm, cdf, 0, cdf.shape[0] - 1)

    ns = SimpleNamespace(hash_u32=hash_u32, sample_spectrum=sample_spectrum, reverse_bits=reverse_bits, owen=owen,
                         sobol_dim1=sobol_dim1,
                         sobol_dim1_reversed=sobol_dim1_reversed,
                         to_unit=to_unit, sobol_2d=sobol_2d, sobol_1d=sobol_1d, r2_2d=r2_2d,
                         unit_square=unit_square, box=box, concentric_disk=concentric_disk, sample_cdf=sample_cdf)
    return ns


def sample_unit_square(sampler: str, n: int, seed: int = 0, precision: str = "float64",
                       device: str | None = None) -> np.ndarray:
    """The first ``n`` points (n, 2) of ``sampler`` with ``seed``, computed by the kernel code (for tests)."""
    from ..device import resolve_device, warp
    from .kernels import get_kernels
    wp = warp()
    dev = resolve_device(device)
    k = get_kernels(precision)
    out = wp.zeros((n, 2), dtype=k.real, device=dev)
    wp.launch(k.sample_square, dim=n, device=dev,
              inputs=[sampler_code(sampler), int(np.sqrt(n)), int(seed) & 0x7FFFFFFF, out])
    return out.numpy().astype(np.float64)
