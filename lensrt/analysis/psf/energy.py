"""Encircled and ensquared energy, centroid and second moments of a sampled PSF.

Two readings of a sampled PSF: a *histogram* (each value the mean over its
bin: geometric PSFs), where pixels that a circle cuts are split into
``supersample``^2 sub-pixels so the encircled-energy curve is continuous in
the radius; and *point samples* of a band-limited function (diffraction
PSFs), integrated exactly through their Fourier interpolant (``points=True``).
Energies are absolute: sum(psf) x pixel area, so a unit-volume PSF (p. 111)
whose light partly falls off the grid never reaches 1.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ...errors import LensrtError
from ..grid import ImageGrid

__all__ = ["centroid_mm", "second_moments_mm2", "encircled_energy", "encircled_energy_function",
           "ensquared_energy", "radius_for_energy"]


def _check(psf: np.ndarray, grid: ImageGrid) -> np.ndarray:
    a = np.asarray(psf, dtype=np.float64)
    if a.shape != grid.shape:
        raise LensrtError(f"PSF shape {a.shape} does not match its grid {grid.shape}")
    return a


def centroid_mm(psf: np.ndarray, grid: ImageGrid) -> tuple[float, float]:
    """Intensity-weighted centre (x, y) of the PSF on the sensor plane (mm)."""
    a = _check(psf, grid)
    tot = a.sum()
    if not tot > 0:
        raise LensrtError("the PSF holds no light: no centroid")
    return float(a.sum(axis=0) @ grid.x_mm / tot), float(a.sum(axis=1) @ grid.y_mm / tot)


def second_moments_mm2(psf: np.ndarray, grid: ImageGrid, sheppard: bool = True) -> tuple[float, float, float]:
    """Central second moments (var_x, cov_xy, var_y) in mm^2 about the centroid.

    ``sheppard`` subtracts pitch^2/12 from each variance: the spread a
    histogram's bin width adds (Sheppard's correction); leave it off for
    point-sampled PSFs.
    """
    a = _check(psf, grid)
    cx, cy = centroid_mm(a, grid)
    gx, gy = grid.mesh_mm()
    dx, dy = gx - cx, gy - cy
    tot = a.sum()
    corr = grid.pitch_mm ** 2 / 12.0 if sheppard else 0.0
    return (float((a * dx * dx).sum() / tot - corr), float((a * dx * dy).sum() / tot),
            float((a * dy * dy).sum() / tot - corr))


class Rings:
    """Pixel geometry about a centre, reused for many radii."""

    def __init__(self, grid: ImageGrid, centre_mm: tuple[float, float], supersample: int,
                 pixels: np.ndarray | None = None) -> None:
        gx, gy = (v.ravel() for v in grid.mesh_mm())
        if pixels is not None:  # only these pixels (flat indices): fractions() then has one entry each
            gx, gy = gx[pixels], gy[pixels]
        self.ax, self.ay = np.abs(gx - centre_mm[0]), np.abs(gy - centre_mm[1])
        self.h = 0.5 * grid.pitch_mm
        self.dmin = np.hypot(np.maximum(self.ax - self.h, 0.0), np.maximum(self.ay - self.h, 0.0))
        self.dmax = np.hypot(self.ax + self.h, self.ay + self.h)
        self._subsamples(grid, supersample)

    @classmethod
    def many(cls, grids: Sequence[ImageGrid], centres_mm: np.ndarray, supersample: int) -> list[Rings]:
        """The Rings of many (grid, centre) pairs of one grid shape, the pixel geometry computed for all
        in whole-array passes (the same numbers as one at a time); ``centres_mm`` (n, 2)."""
        c = np.asarray(centres_mm, dtype=np.float64)
        rows, cols = grids[0].shape
        xs = np.stack([g.x_mm for g in grids])[:, None, :]
        ys = np.stack([g.y_mm for g in grids])[:, :, None]
        ax = np.broadcast_to(np.abs(xs - c[:, 0, None, None]), (len(grids), rows, cols)).reshape(len(grids), -1)
        ay = np.broadcast_to(np.abs(ys - c[:, 1, None, None]), (len(grids), rows, cols)).reshape(len(grids), -1)
        h = np.array([0.5 * g.pitch_mm for g in grids])[:, None]
        dmin = np.hypot(np.maximum(ax - h, 0.0), np.maximum(ay - h, 0.0))
        dmax = np.hypot(ax + h, ay + h)
        out = []
        for k, g in enumerate(grids):
            r = cls.__new__(cls)
            r.ax, r.ay, r.h, r.dmin, r.dmax = ax[k], ay[k], float(h[k, 0]), dmin[k], dmax[k]
            r._subsamples(g, supersample)
            out.append(r)
        return out

    def _subsamples(self, grid: ImageGrid, supersample: int) -> None:
        s = max(1, int(supersample))
        off = ((np.arange(s) + 0.5) / s - 0.5) * 2.0 * self.h
        self.ox, self.oy = (v.ravel() for v in np.meshgrid(off, off))
        self.area = grid.pixel_area_mm2

    def fractions(self, r: float) -> np.ndarray:
        """Fraction of each pixel (flattened) inside the circle of radius r (sub-sampled where it cuts)."""
        frac = (self.dmax <= r).astype(np.float64)
        cut = np.nonzero((self.dmin < r) & (self.dmax > r))[0]
        if cut.size:
            sx = self.ax[cut, None] + self.ox[None, :]
            sy = self.ay[cut, None] + self.oy[None, :]
            frac[cut] = np.mean(sx * sx + sy * sy <= r * r, axis=1)
        return frac

    def energy(self, flat: np.ndarray, r: float) -> float:
        return float(flat @ self.fractions(r)) * self.area


class _Fourier:
    """Disc integrals of the band-limited (periodic) interpolant of point samples.

    p(x) = sum_k c_k exp(2 pi i nu_k . x) integrates over a disc of radius r
    about c to sum_k c_k exp(2 pi i nu_k . c) r J1(2 pi r |nu_k|) / |nu_k|
    (pi r^2 at nu = 0): exact for a PSF sampled at or above Nyquist whose
    light lies inside the grid's period, e.g. an FFT diffraction PSF.
    """

    def __init__(self, psf: np.ndarray, grid: ImageGrid, centre_mm: tuple[float, float]) -> None:
        rows, cols = grid.shape
        fx = np.fft.fftfreq(cols, grid.pitch_mm)
        fy = np.fft.fftfreq(rows, grid.pitch_mm)
        FX, FY = np.meshgrid(fx, fy)
        # math orientation (row index grows with y); sample (0, 0) is the bottom-left pixel
        spec = np.fft.fft2(np.flipud(psf)) / (rows * cols)
        dx, dy = centre_mm[0] - grid.x_mm[0], centre_mm[1] - grid.y_mm[-1]
        self.coef = (spec * np.exp(2j * np.pi * (FX * dx + FY * dy))).ravel()
        self.nu = np.hypot(FX, FY).ravel()

    def energy(self, r: float) -> float:
        from scipy.special import j1

        if r <= 0:
            return 0.0
        nu = np.where(self.nu == 0, 1.0, self.nu)
        g = np.where(self.nu == 0, np.pi * r * r, r * j1(2 * np.pi * r * nu) / nu)
        return float(np.real(self.coef @ g))


def encircled_energy_function(psf: np.ndarray, grid: ImageGrid, centre_mm: tuple[float, float] | None = None,
                              points: bool = False, supersample: int = 8) -> Callable[[float], float]:
    """EE(r): a function of the radius (mm), for evaluating one PSF at many radii (see :func:`encircled_energy`)."""
    a = _check(psf, grid)
    c = centroid_mm(a, grid) if centre_mm is None else centre_mm
    if points:
        return _Fourier(a, grid, c).energy
    rings, flat = Rings(grid, c, supersample), a.ravel()
    return lambda r: rings.energy(flat, r)


def encircled_energy(psf: np.ndarray, grid: ImageGrid, radii_mm: Sequence[float] | float,
                     centre_mm: tuple[float, float] | None = None, supersample: int = 8,
                     points: bool = False) -> np.ndarray | float:
    """Energy within circles of ``radii_mm`` about ``centre_mm`` (default: the centroid).

    ``points`` = False (histograms: each value is its bin's mean): sum of
    pixel values times the fraction of each pixel inside the circle.
    ``points`` = True (point samples of a band-limited PSF, e.g. a diffraction
    PSF at pitch <= lambda N / 2): integral of the Fourier interpolant, exact
    where the pixel-fraction sum errs by O(pitch) at bright radii.
    Returns a float for a scalar radius, else an array like ``radii_mm``.
    """
    energy = encircled_energy_function(psf, grid, centre_mm, points, supersample)
    r = np.asarray(radii_mm, dtype=np.float64)
    out = np.array([energy(float(v)) for v in r.ravel()]).reshape(r.shape)
    return float(out) if out.ndim == 0 else out


def ensquared_energy(psf: np.ndarray, grid: ImageGrid, half_widths_mm: Sequence[float] | float,
                     centre_mm: tuple[float, float] | None = None) -> np.ndarray | float:
    """Energy within axis-aligned squares of half-width ``half_widths_mm`` (exact pixel overlaps)."""
    a = _check(psf, grid)
    c = centroid_mm(a, grid) if centre_mm is None else centre_mm
    h = 0.5 * grid.pitch_mm
    xs, ys = grid.x_mm - c[0], grid.y_mm - c[1]
    hw = np.asarray(half_widths_mm, dtype=np.float64)
    out = []
    for w in hw.ravel():
        fx = np.clip(np.minimum(xs + h, w) - np.maximum(xs - h, -w), 0.0, None) / (2 * h)
        fy = np.clip(np.minimum(ys + h, w) - np.maximum(ys - h, -w), 0.0, None) / (2 * h)
        out.append(float(fy @ a @ fx) * grid.pixel_area_mm2)
    res = np.array(out).reshape(hw.shape)
    return float(res) if res.ndim == 0 else res


def radius_for_energy(psf: np.ndarray, grid: ImageGrid, fraction: float,
                      centre_mm: tuple[float, float] | None = None, relative: bool = True,
                      supersample: int = 8, tol_mm: float = 1e-7, points: bool = False) -> float:
    """Radius (mm) of the circle holding ``fraction`` of the light (e.g. 0.8 for r80).

    ``relative``: the fraction is of the light on the grid (default), else
    of unit volume. Bisection on the continuous encircled-energy curve;
    ``points`` as in :func:`encircled_energy`.
    """
    a = _check(psf, grid)
    c = centroid_mm(a, grid) if centre_mm is None else centre_mm
    energy = encircled_energy_function(a, grid, c, points, supersample)
    target = fraction * (a.sum() * grid.pixel_area_mm2 if relative else 1.0)
    gx, gy = grid.mesh_mm()
    hi = float(np.hypot(np.abs(gx - c[0]) + grid.pitch_mm, np.abs(gy - c[1]) + grid.pitch_mm).max())
    if not 0.0 < fraction <= 1.0 or (not points and energy(hi) < target * (1 - 1e-12)):
        raise LensrtError(f"no circle on this grid holds {fraction:g} of the light")
    lo = 0.0
    while hi - lo > tol_mm:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if energy(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)
