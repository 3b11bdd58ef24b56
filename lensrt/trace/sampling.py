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
density). This module is the host side (names, codes, spectra); the Warp functions are in
:mod:`lensrt.trace.kernels.sampling`, and :func:`lensrt.trace.kernels.generic.sample_unit_square`
runs them for tests.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError

__all__ = ["SAMPLERS", "sampler_code", "Spectrum", "spectrum_discrete", "spectrum_continuous", "R2_ALPHA_U32",
           "SPECTRUM_DISCRETE", "SPECTRUM_CONTINUOUS"]

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
