"""Measurements on a bokeh spot: radial profile and rim/centre ratio, disc area, polygon orientation, rim colour.

All take a single-source :class:`lensrt.analysis.bokeh.entry.BokehImage` (from
:func:`lensrt.analysis.bokeh.entry.bokeh_spot`) and work in sensor-plane
coordinates (mm, +y up) about the spot's ray centroid. Standard errors are
delete-one-batch jackknives over the image's batch histograms
(:func:`lensrt.stats.jackknife`), so they need a spot traced with batch noise.

* "The disc's level": the median of the pixels above 20 % of the 99th percentile
  of the lit pixels (robust to a bright rim and to a soft edge).
* Radii are fractions of ``R99``, the radius about the centroid that holds 99 %
  of the spot's Y.
* The ring of an obscured lens (:func:`annulus_radii`): a uniformly lit annulus
  a <= r <= b has r^2 uniform on [a^2, b^2], so its mean and variance give
  a^2 + b^2 = 2 E[r^2] and b^2 - a^2 = sqrt(12 Var[r^2]); pixel binning is undone
  by Sheppard's correction (a pixel of pitch p adds p^2/6 to E[r^2] and E[r^2] p^2/3
  to Var[r^2]).
"""
from __future__ import annotations

import math

import numpy as np

from ...errors import LensrtError
from ...stats import jackknife

__all__ = ["polar", "disc_level", "disc_area_mm2", "radius_holding", "ring_ratio", "polygon_vertex_angle",
           "ring_chromaticity_shift", "annulus_radii"]


def polar(img) -> tuple[np.ndarray, np.ndarray]:
    """(r, phi) in mm and rad of every picture pixel about the spot's centroid, sensor coordinates."""
    rows, cols = np.indices((img.frame.ny, img.frame.nx))
    x, y = img.sensor_xy(rows, cols)
    cx, cy = img.sources[0]["centroid_mm"]
    return np.hypot(x - cx, y - cy), np.arctan2(y - cy, x - cx)


def disc_level(y: np.ndarray) -> float:
    """Typical interior level of a disc image (module docstring)."""
    lit = y[y > 0]
    if lit.size == 0:
        raise LensrtError("the spot has no light")
    return float(np.median(lit[lit > 0.2 * np.percentile(lit, 99.0)]))


def disc_area_mm2(img, window_px: int = 15) -> float:
    """Area (mm^2) of the pixels brighter than half the disc's *local* level.

    The local level is the mean of the interior pixels (those above 30 % of the disc's level)
    in a ``window_px`` square around each pixel, so an edge pixel is compared with the light
    just inside the edge: the count is unbiased for a disc whose irradiance varies slowly
    (a pixel counts when more than half of it is covered).
    """
    from scipy.ndimage import uniform_filter
    y = img.picture()[..., 1].astype(np.float64)
    inside = (y > 0.3 * disc_level(y)).astype(np.float64)
    share = uniform_filter(inside, window_px, mode="constant")
    near = share > 0.5 / window_px ** 2  # some interior pixel in the window (filter round-off aside)
    local = uniform_filter(y * inside, window_px, mode="constant") / np.where(near, share, 1.0)
    lit = near & (y > 0) & (y > 0.5 * local)
    return float(np.count_nonzero(lit) * img.frame.pitch_mm ** 2)


def radius_holding(img, fraction: float = 0.99) -> float:
    """Radius (mm) about the centroid that holds ``fraction`` of the spot's Y."""
    r, _ = polar(img)
    y = img.picture()[..., 1]
    order = np.argsort(r, axis=None)
    cum = np.cumsum(y.ravel()[order])
    k = int(np.searchsorted(cum, fraction * cum[-1]))
    return float(r.ravel()[order][min(k, len(order) - 1)])


def _batches(img) -> np.ndarray:
    """(B, rows, cols, 3) XYZ of each batch, upright."""
    b = img.picture_batches()
    if b is None:
        raise LensrtError("this measurement needs the spot's batch histograms (bokeh_spot(..., batch_noise=True))")
    return b.astype(np.float64)


def ring_ratio(img, inner: tuple[float, float] = (0.0, 0.3), outer: tuple[float, float] = (0.8, 0.95),
               r_ref_mm: float | None = None) -> tuple[float, float]:
    """Mean Y in the ring ``outer`` over the mean Y in ``inner`` (radii as fractions of ``r_ref_mm``,
    default R99), with its jackknife standard error.

    > 1: a bright rim (the foreground of under-corrected spherical aberration);
    < 1: bright centre and soft edge (its background).
    """
    r, _ = polar(img)
    ref = radius_holding(img) if r_ref_mm is None else float(r_ref_mm)
    ring_in = (r >= inner[0] * ref) & (r < inner[1] * ref)
    ring_out = (r >= outer[0] * ref) & (r < outer[1] * ref)
    b = _batches(img)[..., 1]
    sums = np.stack([b[:, ring_out].mean(axis=1), b[:, ring_in].mean(axis=1)], axis=1)
    return jackknife(sums, lambda s: s[0] / s[1])


def polygon_vertex_angle(img, blades: int, bins: int = 720) -> tuple[float, float]:
    """Direction of the polygon's vertices on the sensor (rad, in [0, 2 pi / blades)) and the
    relative amplitude of the ``blades``-fold harmonic of the outline r(phi).

    The outline is the largest radius, per angular bin, of the pixels above half the disc's
    level; a least-squares fit of a0 + a cos(N phi) + b sin(N phi) gives the vertex phase.
    """
    r, phi = polar(img)
    y = img.picture()[..., 1]
    inside = y > 0.5 * disc_level(y)
    k = ((phi[inside] + math.pi) / (2 * math.pi) * bins).astype(int) % bins
    rmax = np.zeros(bins)
    np.maximum.at(rmax, k, r[inside])
    ang = (np.arange(bins) + 0.5) / bins * 2 * math.pi - math.pi
    m = np.stack([np.ones(bins), np.cos(blades * ang), np.sin(blades * ang)], axis=1)
    a0, a, b = np.linalg.lstsq(m, rmax, rcond=None)[0]
    return (math.atan2(b, a) / blades) % (2 * math.pi / blades), math.hypot(a, b) / a0


def ring_chromaticity_shift(img, ring: tuple[float, float] = (0.85, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """CIE 1931 (x, y) of the light in a ring (radii as fractions of R99) minus that of the whole
    spot, and its jackknife standard error over the batches' X, Y, Z sums.

    A lens with axial colour gives rims of one hue in front of focus and another behind it.
    """
    r, _ = polar(img)
    ref = radius_holding(img)
    sel = (r >= ring[0] * ref) & (r < ring[1] * ref)
    b = _batches(img)  # (B, rows, cols, 3)
    parts = np.concatenate([b[:, sel].sum(axis=1), b.reshape(len(b), -1, 3).sum(axis=1)], axis=1)  # (B, 6)

    def shift(s: np.ndarray) -> np.ndarray:
        return s[0:2] / s[0:3].sum() - s[3:5] / s[3:6].sum()

    return jackknife(parts, shift)


def annulus_radii(img) -> tuple[np.ndarray, np.ndarray]:
    """Inner and outer radius (mm) of a ring-shaped spot and their ratio, with jackknife standard errors.

    The bokeh of a lens with a central obscuration (a reflex lens) far from focus: an annulus
    about the centroid, uniformly lit when the defocus blur dominates the aberrations. The radii
    come from the first two moments of r^2 (module docstring), so they use every ray rather than
    an edge threshold. Returns ``(values, stderr)``, each ``[inner_mm, outer_mm, inner / outer]``.
    """
    r, _ = polar(img)
    r2 = r * r
    b = _batches(img)[..., 1]
    sums = np.stack([b.sum(axis=(1, 2)), (b * r2).sum(axis=(1, 2)), (b * r2 * r2).sum(axis=(1, 2))], axis=1)
    p2 = img.frame.pitch_mm ** 2

    def radii(s: np.ndarray) -> np.ndarray:
        mean = s[1] / s[0]
        var = s[2] / s[0] - mean * mean
        mean, var = mean - p2 / 6.0, var - mean * p2 / 3.0  # Sheppard's correction of the pixel binning
        half = 0.5 * math.sqrt(max(12.0 * var, 0.0))
        a2, b2 = max(mean - half, 0.0), mean + half
        return np.array([math.sqrt(a2), math.sqrt(b2), math.sqrt(a2 / b2)])

    return jackknife(sums, radii)
