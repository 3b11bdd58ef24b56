"""Jackknife standard errors of a geometric PSF's statistics, vectorised over the batches.

:func:`lensrt.stats.jackknife` recomputes a statistic once per left-out batch
(B + 1 calls of a Python function). For the statistics of a geometric PSF the
left-out values have closed forms in per-batch sums, so all B come from a few
array operations -- the same numbers to rounding, at a fraction of the cost
(a PSF map has hundreds of PSFs with 32 batches each):

* moments (centroid, RMS radii): from the per-batch moment sums;
* the OTF along a direction (MTF): linear in the histogram, so every batch's
  Fourier sums come from one matrix product and the left-out OTFs by
  subtraction (:func:`mtf_jackknife`);
* the geometric radius (the farthest lit bin from the centroid): the left-out
  lit set differs from the full one only in bins lit by one batch, and only
  bins near the full maximum can be the maximum (:func:`geometric_radius_jackknife`);
* encircled-energy radii: :func:`lensrt.analysis.psf.result._ee_radius_jackknife`'s
  linearisation, with the pixel geometry shared by all fractions and the
  bisection bracketed by the radial profile (:func:`ee_radii_jackknife`).

The jackknife variance is ``(B - 1) / B * sum_i (theta_i - mean)^2`` (Efron & Stein 1981).
Matrix-vector products go through ``numpy.einsum`` (its own loops, one thread) rather than
BLAS: for arrays this small a multi-threaded BLAS spends more time starting threads than
computing, and many PSFs are analysed side by side.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...errors import LensrtError
from ..grid import ImageGrid
from .otf import mtf_directions

if TYPE_CHECKING:
    from .bulk import FieldSums

__all__ = ["jackknife_se", "moment_jackknife", "mtf_jackknife", "geometric_radius_jackknife",
           "ee_radii_jackknife"]


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b of two vectors without BLAS (module docstring)."""
    return float(np.einsum("i,i->", a, b))


def jackknife_se(loo: np.ndarray) -> np.ndarray:
    """Jackknife standard error from the B left-out values (axis 0)."""
    b = loo.shape[0]
    m = loo.mean(axis=0)
    return np.sqrt((b - 1) / b * np.sum((loo - m) ** 2, axis=0))


def _moment_stats(t: np.ndarray, ref: np.ndarray, tang: float) -> dict[str, np.ndarray]:
    """Centroid and RMS radii of moment sums t (..., 6) (psf.MOMENT_KEYS), vectorised."""
    w = t[..., 0]
    cx, cy = t[..., 1] / w, t[..., 2] / w
    vxx, vxy, vyy = t[..., 3] / w - cx * cx, t[..., 4] / w - cx * cy, t[..., 5] / w - cy * cy
    out = {"centroid_x_mm": cx + ref[0], "centroid_y_mm": cy + ref[1],
           "rms_radius_mm": np.sqrt(np.maximum(vxx + vyy, 0.0))}
    for name, ang in (("rms_tangential_mm", tang), ("rms_sagittal_mm", tang + 0.5 * math.pi)):
        c, d = math.cos(ang), math.sin(ang)
        out[name] = np.sqrt(np.maximum(vxx * c * c + 2 * vxy * c * d + vyy * d * d, 0.0))
    return out


def moment_jackknife(sums: np.ndarray, reference_mm: Sequence[float], tangential_rad: float
                     ) -> dict[str, tuple[float, float]]:
    """(value, stderr) of centroid x/y, RMS radius and tangential/sagittal RMS from per-batch moment sums."""
    s = np.asarray(sums, dtype=np.float64)
    total = s.sum(axis=0)
    if not total[0] > 0:
        raise LensrtError("no rays reached the image plane")
    ref = np.asarray(reference_mm, dtype=np.float64)
    full = _moment_stats(total, ref, tangential_rad)
    with np.errstate(divide="ignore", invalid="ignore"):
        loo = _moment_stats(total[None, :] - s, ref, tangential_rad)
    return {k: (float(full[k]), float(jackknife_se(loo[k]))) for k in full}


def _otf_sums(hb: np.ndarray, grid: ImageGrid, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    """Per-batch Fourier sums (B, F) of histograms hb (B, rows, cols) at frequencies (fx, fy) (cycles/mm),
    phase origin at the grid centre (as :func:`lensrt.analysis.psf.otf.otf_along`)."""
    cx, cy = grid.centre_mm
    ex = np.exp(-2j * np.pi * np.outer(fx, grid.x_mm - cx))  # (F, cols)
    ey = np.exp(-2j * np.pi * np.outer(fy, grid.y_mm - cy))  # (F, rows)
    # separable: sum over columns with ex, then rows with ey (real and imaginary parts, no BLAS)
    a = np.einsum("brc,fc->bfr", hb, ex.real) + 1j * np.einsum("brc,fc->bfr", hb, ex.imag)  # (B, F, rows)
    return np.einsum("bfr,fr->bf", a, ey)


def mtf_jackknife(hb: np.ndarray, grid: ImageGrid, freqs_cpmm: Sequence[float], angles_rad: Sequence[float],
                  binned: bool = True, sums: FieldSums | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """MTF along each direction of ``angles_rad`` at ``freqs_cpmm`` from per-batch histograms, with jackknife
    standard errors: one (value (F,), stderr (F,)) per angle -- :func:`lensrt.analysis.psf.otf.mtf_estimate`'s
    numbers, all angles and left-out batches from one matrix product. ``sums``: the field's
    :class:`~lensrt.analysis.psf.bulk.FieldSums` (its Fourier sums at these frequencies, if it has them)."""
    h = np.asarray(hb, dtype=np.float64)
    f = np.atleast_1d(np.asarray(freqs_cpmm, dtype=np.float64))
    nyq = 0.5 / grid.pitch_mm
    fx, fy = mtf_directions(f, angles_rad)
    if np.max(np.maximum(np.abs(fx), np.abs(fy)), initial=0.0) > nyq * (1 + 1e-9):
        raise LensrtError(f"frequency {f.max():g} cycles/mm is beyond this PSF grid's Nyquist {nyq:g}",
                          hint="sample the PSF on a finer grid or ask for lower frequencies")
    nb = sums.otf.get((fx.tobytes(), fy.tobytes())) if sums is not None else None
    if nb is None and sums is not None and sums.complete:
        raise LensrtError("internal: the device sums hold no Fourier sums at these frequencies",
                          hint="ask the PSF map for its MTF frequencies in its setup")
    nb = _otf_sums(h, grid, fx, fy) if nb is None else nb  # (B, A*F)
    tb = h.sum(axis=(1, 2)) if sums is None else sums.s_b
    tot = tb.sum()
    if not tot > 0:
        raise LensrtError("the PSF holds no light: no MTF")
    box = np.sinc(grid.pitch_mm * fx) * np.sinc(grid.pitch_mm * fy) if binned else np.ones_like(fx)
    n_all = nb.sum(axis=0)
    full = np.abs(n_all / tot / box)
    with np.errstate(divide="ignore", invalid="ignore"):
        loo = np.abs((n_all[None, :] - nb) / (tot - tb)[:, None] / box[None, :])
    se = jackknife_se(loo)
    k = len(f)
    return [(full[i * k:(i + 1) * k], se[i * k:(i + 1) * k]) for i in range(len(angles_rad))]


def geometric_radius_jackknife(hb: np.ndarray, grid: ImageGrid, sums: FieldSums | None = None) -> tuple[float, float]:
    """The farthest lit bin centre from the centroid (mm) and its jackknife error (module docstring);
    ``sums``: the field's :class:`~lensrt.analysis.psf.bulk.FieldSums` when already computed (with the
    radius itself when they were made on the device)."""
    if sums is not None and sums.geometric_radius is not None:
        return sums.geometric_radius
    b = hb.shape[0]
    flat = hb.reshape(b, -1)
    gx, gy = (v.ravel() for v in grid.mesh_mm())
    H = flat.sum(axis=0) if sums is None else sums.H
    S = H.sum()
    if not S > 0:
        return 0.0, 0.0
    if sums is None:
        sb = flat.sum(axis=1)
        sx_b, sy_b = np.einsum("bp,p->b", flat, gx), np.einsum("bp,p->b", flat, gy)
        lit_n = np.count_nonzero(flat > 0, axis=0)
    else:
        sb, sx_b, sy_b, lit_n = sums.s_b, sums.sx_b, sums.sy_b, sums.lit_n
    sx, sy = float(sx_b.sum()), float(sy_b.sum())
    cx, cy = sx / S, sy / S
    lit = lit_n > 0
    d0 = np.hypot(gx - cx, gy - cy)
    full = float(d0[lit].max())
    rest = S - sb
    with np.errstate(divide="ignore", invalid="ignore"):
        cxi = np.where(rest > 0, (sx - sx_b) / rest, cx)
        cyi = np.where(rest > 0, (sy - sy_b) / rest, cy)
    delta = float(np.max(np.hypot(cxi - cx, cyi - cy)))
    always = lit_n >= 2  # lit whichever batch is left out
    floor = float(d0[always].max()) - 2.0 * delta if always.any() else -np.inf
    cand = np.nonzero(lit & (d0 >= floor))[0]
    dist = np.hypot(gx[cand][None, :] - cxi[:, None], gy[cand][None, :] - cyi[:, None])  # (B, C)
    lit_i = (lit_n[cand][None, :] - (flat[:, cand] > 0)) > 0
    loo = np.where(lit_i, dist, -np.inf).max(axis=1)
    loo = np.where(rest > 0, np.maximum(loo, 0.0), 0.0)
    return full, float(jackknife_se(loo))


class _Annulus:
    """Energy sum(H * fraction inside r) for radii in [lo, hi] only: pixels wholly inside lo are counted
    once, those beyond hi never, the rest sub-sampled where the circle cuts them (as ``Rings``)."""

    def __init__(self, rings, H: np.ndarray, lo: float, hi: float) -> None:
        self.r = rings
        self.e_inner = float(H[rings.dmax <= lo].sum())
        self.idx = np.nonzero((rings.dmax > lo) & (rings.dmin < hi) & (H != 0))[0]
        self.h = H[self.idx]
        self.dmin, self.dmax = rings.dmin[self.idx], rings.dmax[self.idx]
        self.ax, self.ay = rings.ax[self.idx], rings.ay[self.idx]

    def energy(self, r: float) -> float:
        f = (self.dmax <= r).astype(np.float64)
        cut = np.nonzero((self.dmin < r) & (self.dmax > r))[0]
        if cut.size:
            sx = self.ax[cut, None] + self.r.ox[None, :]
            sy = self.ay[cut, None] + self.r.oy[None, :]
            f[cut] = np.mean(sx * sx + sy * sy <= r * r, axis=1)
        return self.e_inner + _dot(self.h, f)


def _radial_profiles(rings, H: np.ndarray) -> tuple[np.ndarray, ...]:
    """The lit pixels' farthest and nearest distances from the centre, sorted, each with the cumulative
    light in that order (the brackets of :func:`_radius_bisect`, shared by every fraction)."""
    lit = np.nonzero(H > 0)[0]
    h = H[lit]
    dmax, dmin = rings.dmax[lit], rings.dmin[lit]
    o_max, o_min = np.argsort(dmax, kind="stable"), np.argsort(dmin, kind="stable")
    return dmax[o_max], np.cumsum(h[o_max]), dmin[o_min], np.cumsum(h[o_min])


def _radius_bisect(rings, H: np.ndarray, target: float, tol: float, profiles: tuple | None = None) -> float:
    """Radius whose pixel-fraction energy sum(H * fractions(r)) reaches ``target`` (bisection, bracketed
    by the pixels' nearest and farthest points: a pixel is wholly inside r when its farthest point is,
    and adds nothing while its nearest point is outside); ``profiles``: :func:`_radial_profiles`."""
    dmax, c_max, dmin, c_min = _radial_profiles(rings, H) if profiles is None else profiles
    k = int(np.searchsorted(c_max, target * (1 - 1e-12)))
    hi = float(dmax[min(k, len(dmax) - 1)]) + 1e-12
    k = int(np.searchsorted(c_min, target))
    lo = max(float(dmin[min(k, len(dmin) - 1)]) - 1e-12, 0.0)
    ann = _Annulus(rings, H, lo, hi)
    if not (ann.energy(lo) < target <= ann.energy(hi)):  # numerical edge: the whole range
        lo, hi = 0.0, float(rings.dmax.max())
        ann = _Annulus(rings, H, lo, hi)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ann.energy(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def ee_centres_mm(c: tuple[float, float], grid: ImageGrid) -> list[tuple[float, float]]:
    """The centres of the encircled-energy rings: the centroid ``c``, then shifted by -+ a quarter pixel in x
    and in y (the centroid gradient of the energy, :func:`ee_radii_jackknife`)."""
    d = 0.25 * grid.pitch_mm
    return [c] + [(c[0] + dx, c[1] + dy) for dx, dy in ((d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d))]


def ee_radii_jackknife(hb: np.ndarray, off: np.ndarray, grid: ImageGrid, fractions: Sequence[float],
                       sums: FieldSums | None = None) -> dict[float, tuple[float, float]]:
    """Encircled-energy radii about the centroid holding ``fractions`` of all landed light (on and off the
    grid) and their linearised jackknife errors, as :func:`lensrt.analysis.psf.result._ee_radius_jackknife`
    computes them one fraction at a time; fractions the grid cannot hold are left out. ``sums``: the field's
    :class:`~lensrt.analysis.psf.bulk.FieldSums` (per-batch sums and ring geometry) when already computed --
    or the radii and errors themselves, when they were made on the device
    (:mod:`lensrt.analysis.psf.device_sums`, the same steps)."""
    from .energy import Rings
    if sums is not None and sums.ee_radii is not None:
        return {frac: sums.ee_radii[float(frac)] for frac in fractions if float(frac) in sums.ee_radii}
    nb = hb.shape[0]
    flat_b = hb.reshape(nb, -1)
    gx, gy = (v.ravel() for v in grid.mesh_mm())
    if sums is None:
        H, s_b = flat_b.sum(axis=0), flat_b.sum(axis=1)
        sx_b, sy_b = np.einsum("bp,p->b", flat_b, gx), np.einsum("bp,p->b", flat_b, gy)
    else:
        H, s_b, sx_b, sy_b = sums.H, sums.s_b, sums.sx_b, sums.sy_b
    tot_b = s_b + off
    total = float(tot_b.sum())
    hs = H.sum()
    sx, sy = float(_dot(H, gx)), float(_dot(H, gy))
    c = (sx / hs, sy / hs)
    d = 0.25 * grid.pitch_mm
    centres = ee_centres_mm(c, grid)
    if sums is None:
        rings, *shifted = (Rings(grid, cc, 4) for cc in centres)
        H_s = H
    else:
        # the shifted rings serve one dot product with H each: on the lit pixels alone (the rest add 0)
        lit = np.nonzero(H)[0]
        rings, H_s = sums.rings, H[lit]
        shifted = [Rings(grid, cc, 4, lit) for cc in centres[1:]]
    profiles = _radial_profiles(rings, H)
    rest = hs - s_b
    with np.errstate(divide="ignore", invalid="ignore"):
        cx_i = (sx - sx_b) / rest
        cy_i = (sy - sy_b) / rest
    out: dict[float, tuple[float, float]] = {}
    for frac in fractions:
        if hs < frac * total:
            continue
        full = _radius_bisect(rings, H, frac * total, 1e-3 * grid.pitch_mm, profiles)
        w = rings.fractions(full)
        lo = max(full - d, 0.0)
        dedr = float(_dot(H, rings.fractions(full + d) - rings.fractions(lo))) / (full + d - lo)
        if not dedr > 0:
            out[frac] = (full, 0.0)
            continue
        grad = [float(_dot(H_s, shifted[0].fractions(full) - shifted[1].fractions(full))) / (2 * d),
                float(_dot(H_s, shifted[2].fractions(full) - shifted[3].fractions(full))) / (2 * d)]
        e = float(_dot(H, w)) - np.einsum("bp,p->b", flat_b, w) + grad[0] * (cx_i - c[0]) + grad[1] * (cy_i - c[1])
        loo = np.where(rest > 0, full + (frac * (total - tot_b) - e) / dedr, full)
        out[frac] = (full, float(jackknife_se(loo)))
    return out
