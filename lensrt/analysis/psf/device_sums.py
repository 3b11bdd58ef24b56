"""The passes of a PSF map's analysis over per-batch histograms, as Warp kernels on the histograms' device.

:func:`lensrt.analysis.psf.bulk.field_sums` makes the passes over each field's per-batch histograms
(B, rows, cols) on the host; for that the stream must download them -- B x rows x cols int64 per field,
340 MB for a 9 x 9 map of 128^2 px and 32 batches -- and NumPy must walk them several times. Here the
histograms stay where the stream kernel left them (``stream(..., batch_histograms="device")``) and
two launches per group of fields (1 and 2 below share one) make the same passes, all fields at once,
in float64:

1. per pixel (fields x pixels threads): the all-batch histogram ``H`` (int64 sums: exact), the batches
   that lit it, and the sum of squared deviations from the batch mean (summed over the batches in
   batch order, as NumPy sums that axis);
2. per (field, batch, frequency) thread: the per-batch weight and first moments (one extra thread per
   batch) and the per-batch Fourier sums of the MTF at each field's :func:`~.bulk.mtf_requests`
   frequencies (the host's own ``exp`` tables go up, so the phases are the host's bits);
3. after the host has found each field's encircled-energy radii on ``H`` (the same bisection as
   :func:`~lensrt.analysis.psf.jackknife.ee_radii_jackknife`): per (field, batch) the light of each
   batch inside those circles (pixel fractions recomputed from the rings' geometry: the same
   sixteenths, so the sums of fixed-point weights are exact), and the geometric radius left out
   batch by batch (the farthest bin still lit without that batch, from its left-out centroid).

Only small arrays come down: H and the per-pixel deviations (the PSF image and its error, rows x cols
per field), per-batch sums (B per field), Fourier sums (B x K), radii. The results are
:class:`~lensrt.analysis.psf.bulk.FieldSums` with ``complete=True``: every statistic the field's
analysis needs from its per-batch histograms is in them, so no host pass over them remains.

Equality with the host path (tests/analysis/psf/test_psf_device_sums.py, on Warp's CPU device):
``H``, the per-batch weights, the lit counts and the encircled light of each batch are sums of
fixed-point weights (multiples of 2^-24 below 2^53 units) and are exact in any order, so they -- and
the encircled-energy radii and their errors -- are the same bits. The first moments, Fourier sums and
distances are sums of products in another order than NumPy's (and a GPU compiler may fuse a multiply
and an add), so the MTF, per-pixel errors and geometric radius agree to rounding: 1e-12 relative,
the jackknife errors that difference nearly equal sums to 1e-9 relative.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import warp as wp

from ...core.telemetry import download, launch, upload
from ...errors import LensrtError
from ..grid import ImageGrid

__all__ = ["device_field_sums", "DeviceHistograms"]

wp.set_module_options({"enable_backward": False})


@wp.func
def _pixel_pass(hist: wp.array(dtype=wp.int64), base: wp.array(dtype=wp.int32), stride: int, nb: int, ny: int,
                nx: int, unit: wp.float64, H: wp.array2d(dtype=wp.float64), lit: wp.array2d(dtype=wp.int32),
                ss: wp.array2d(dtype=wp.float64), f: int, p: int):
    """All-batch histogram, lit batches and summed squared deviation of pixel p (host rows: top row first)."""
    r = p // nx
    c = p - r * nx
    i0 = base[f] + (ny - 1 - r) * nx + c
    tot = wp.int64(0)
    n = int(0)
    for b in range(nb):
        v = hist[i0 + b * stride]
        tot = tot + v
        if v > wp.int64(0):
            n = n + 1
    h = wp.float64(tot) * unit
    mean = h / wp.float64(nb)
    acc = wp.float64(0.0)
    for b in range(nb):
        d = wp.float64(hist[i0 + b * stride]) * unit - mean
        acc = acc + d * d
    H[f, p] = h
    lit[f, p] = n
    ss[f, p] = acc


@wp.func
def _batch_pass(hist: wp.array(dtype=wp.int64), base: wp.array(dtype=wp.int32), stride: int, ny: int, nx: int,
                unit: wp.float64, xs: wp.array2d(dtype=wp.float64), ys: wp.array2d(dtype=wp.float64),
                ex_re: wp.array3d(dtype=wp.float64), ex_im: wp.array3d(dtype=wp.float64),
                ey_re: wp.array3d(dtype=wp.float64), ey_im: wp.array3d(dtype=wp.float64),
                nk: wp.array(dtype=wp.int32), sums: wp.array3d(dtype=wp.float64),
                otf: wp.array4d(dtype=wp.float64), f: int, b: int, k: int):
    """Thread (f, b, k): the Fourier sum of batch b at frequency k of field f; k = K: the batch's weight and
    first moments (x, y of the pixel centres, mm)."""
    nkmax = ex_re.shape[1]
    i0 = base[f] + b * stride
    if k == nkmax:
        s = wp.int64(0)
        sx = wp.float64(0.0)
        sy = wp.float64(0.0)
        for r in range(ny):
            row = i0 + (ny - 1 - r) * nx
            yv = ys[f, r]
            for c in range(nx):
                v = hist[row + c]
                if v != wp.int64(0):
                    w = wp.float64(v) * unit
                    s = s + v
                    sx = sx + w * xs[f, c]
                    sy = sy + w * yv
        sums[f, b, 0] = wp.float64(s) * unit
        sums[f, b, 1] = sx
        sums[f, b, 2] = sy
        return
    if k >= nk[f]:
        return
    acc_re = wp.float64(0.0)
    acc_im = wp.float64(0.0)
    for r in range(ny):
        row = i0 + (ny - 1 - r) * nx
        a_re = wp.float64(0.0)
        a_im = wp.float64(0.0)
        for c in range(nx):
            v = hist[row + c]
            if v != wp.int64(0):
                w = wp.float64(v) * unit
                a_re = a_re + w * ex_re[f, k, c]
                a_im = a_im + w * ex_im[f, k, c]
        e_re = ey_re[f, k, r]
        e_im = ey_im[f, k, r]
        acc_re = acc_re + (a_re * e_re - a_im * e_im)
        acc_im = acc_im + (a_re * e_im + a_im * e_re)
    otf[f, b, k, 0] = acc_re
    otf[f, b, k, 1] = acc_im


@wp.kernel
def _first_pass(hist: wp.array(dtype=wp.int64), base: wp.array(dtype=wp.int32), stride: int, nb: int, ny: int,
                nx: int, unit: wp.float64, H: wp.array2d(dtype=wp.float64), lit: wp.array2d(dtype=wp.int32),
                ss: wp.array2d(dtype=wp.float64), xs: wp.array2d(dtype=wp.float64), ys: wp.array2d(dtype=wp.float64),
                ex_re: wp.array3d(dtype=wp.float64), ex_im: wp.array3d(dtype=wp.float64),
                ey_re: wp.array3d(dtype=wp.float64), ey_im: wp.array3d(dtype=wp.float64),
                nk: wp.array(dtype=wp.int32), sums: wp.array3d(dtype=wp.float64),
                otf: wp.array4d(dtype=wp.float64)):
    """Passes 1 and 2 of the module docstring in one launch: the first F x pixels threads are per pixel, the
    rest per (field, batch, frequency or moments)."""
    t = wp.tid()
    n_f = H.shape[0]
    n_p = H.shape[1]
    if t < n_f * n_p:
        _pixel_pass(hist, base, stride, nb, ny, nx, unit, H, lit, ss, t // n_p, t - (t // n_p) * n_p)
        return
    t = t - n_f * n_p
    per_f = nb * (ex_re.shape[1] + 1)
    f = t // per_f
    t = t - f * per_f
    b = t // (ex_re.shape[1] + 1)
    _batch_pass(hist, base, stride, ny, nx, unit, xs, ys, ex_re, ex_im, ey_re, ey_im, nk, sums, otf, f, b,
                t - b * (ex_re.shape[1] + 1))


@wp.func
def _pixel_fraction(ax: wp.float64, ay: wp.float64, h: wp.float64, rad: wp.float64, off: wp.array2d(dtype=wp.float64),
                    f: int) -> wp.float64:
    """Fraction of a pixel (centre |dx|, |dy| from the circle's centre, half-width h) inside radius rad:
    1 when its farthest point is, else the share of its s x s sub-pixel centres (``Rings.fractions``)."""
    dmax = wp.sqrt((ax + h) * (ax + h) + (ay + h) * (ay + h))
    if dmax <= rad:
        return wp.float64(1.0)
    gx = wp.max(ax - h, wp.float64(0.0))
    gy = wp.max(ay - h, wp.float64(0.0))
    if wp.sqrt(gx * gx + gy * gy) >= rad:
        return wp.float64(0.0)
    s = off.shape[1]
    n = int(0)
    for j in range(s):
        sy = ay + off[f, j]
        for i in range(s):
            sx = ax + off[f, i]
            if sx * sx + sy * sy <= rad * rad:
                n = n + 1
    return wp.float64(n) / wp.float64(s * s)


@wp.kernel
def _radius_pass(hist: wp.array(dtype=wp.int64), base: wp.array(dtype=wp.int32), stride: int, ny: int, nx: int,
                 unit: wp.float64, xs: wp.array2d(dtype=wp.float64), ys: wp.array2d(dtype=wp.float64),
                 half: wp.array(dtype=wp.float64), off: wp.array2d(dtype=wp.float64),
                 radius: wp.array2d(dtype=wp.float64), centre: wp.array2d(dtype=wp.float64),
                 lit: wp.array2d(dtype=wp.int32), geo_c: wp.array2d(dtype=wp.float64),
                 loo_c: wp.array3d(dtype=wp.float64),
                 e_b: wp.array3d(dtype=wp.float64), loo: wp.array2d(dtype=wp.float64),
                 full: wp.array(dtype=wp.float64)):
    """Thread (f, b, j): the light of batch b inside field f's j-th encircled-energy circle (radius < 0: none);
    j = J: the geometric radius without batch b (from its left-out centroid ``loo_c``) and, for b = 0, with
    all batches (about the centroid ``geo_c``, from the per-batch moments as the host finds it)."""
    f, b, j = wp.tid()
    nj = radius.shape[1]
    i0 = base[f] + b * stride
    cx = centre[f, 0]
    cy = centre[f, 1]
    if j < nj:
        rad = radius[f, j]
        if rad < wp.float64(0.0):
            return
        h = half[f]
        acc = wp.float64(0.0)
        for r in range(ny):
            row = i0 + (ny - 1 - r) * nx
            ay = wp.abs(ys[f, r] - cy)
            for c in range(nx):
                v = hist[row + c]
                if v != wp.int64(0):
                    w = _pixel_fraction(wp.abs(xs[f, c] - cx), ay, h, rad, off, f)
                    acc = acc + wp.float64(v) * unit * w
        e_b[f, j, b] = acc
        return
    ix = loo_c[f, b, 0]
    iy = loo_c[f, b, 1]
    best = wp.float64(-1.0)
    best_all = wp.float64(-1.0)
    for r in range(ny):
        row = i0 + (ny - 1 - r) * nx
        for c in range(nx):
            n = lit[f, r * nx + c]
            if n > 0:
                mine = int(0)
                if hist[row + c] > wp.int64(0):
                    mine = 1
                if n - mine > 0:
                    dx = xs[f, c] - ix
                    dy = ys[f, r] - iy
                    best = wp.max(best, wp.sqrt(dx * dx + dy * dy))
                if b == 0:
                    dx0 = xs[f, c] - geo_c[f, 0]
                    dy0 = ys[f, r] - geo_c[f, 1]
                    best_all = wp.max(best_all, wp.sqrt(dx0 * dx0 + dy0 * dy0))
    loo[f, b] = best
    if b == 0:
        full[f] = best_all


class DeviceHistograms:
    """Where a stream left per-batch histograms on its device: the flat int64 array (layers, batches, channels,
    ny, nx; rows bottom-up), its shape and fixed-point unit, and the layer of each field to analyse."""

    def __init__(self, array: Any, layers: Sequence[int], batches: int, channels: int, ny: int, nx: int,
                 unit: float, device: str) -> None:
        self.array, self.layers = array, [int(v) for v in layers]
        self.batches, self.channels, self.ny, self.nx = int(batches), int(channels), int(ny), int(nx)
        self.unit, self.device = float(unit), device

    @property
    def stride(self) -> int:
        """Elements from one batch's plane to the next (channel 0 is analysed)."""
        return self.channels * self.ny * self.nx

    def bases(self, sources: Sequence[int]) -> np.ndarray:
        """Offset of batch 0 of each source's layer (int32)."""
        return np.array([self.layers[s] * self.batches * self.stride for s in sources], dtype=np.int32)


def _fourier_tables(grids: Sequence[ImageGrid], requests: list[list[tuple[np.ndarray, np.ndarray]]]
                    ) -> tuple[np.ndarray, ...]:
    """The host's phase tables of every field's frequency sets, padded to the largest count: ex (F, K, cols),
    ey (F, K, rows) complex (the expressions of ``bulk._fourier_sums``), and the counts (F,)."""
    n, rows, cols = len(grids), grids[0].shape[0], grids[0].shape[1]
    counts = np.array([sum(fx.size for fx, _ in req) for req in requests], dtype=np.int32)
    kmax = max(1, int(counts.max(initial=0)))
    ex = np.zeros((n, kmax, cols), dtype=np.complex128)
    ey = np.zeros((n, kmax, rows), dtype=np.complex128)
    for i, (g, req) in enumerate(zip(grids, requests)):
        if not req:
            continue
        fx = np.concatenate([a for a, _ in req])
        fy = np.concatenate([b for _, b in req])
        cx, cy = g.centre_mm
        ex[i, :fx.size] = np.exp(-2j * np.pi * np.outer(fx, g.x_mm - cx))
        ey[i, :fy.size] = np.exp(-2j * np.pi * np.outer(fy, g.y_mm - cy))
    return ex, ey, counts


def _up(a: np.ndarray, dtype: Any, device: str) -> Any:
    return upload(np.ascontiguousarray(a), dtype, device)


def device_field_sums(dh: DeviceHistograms, sources: Sequence[int], off_grid: np.ndarray,
                      grids: Sequence[ImageGrid], references_mm: Sequence[tuple[float, float]], setup: Any) -> list:
    """The :class:`~lensrt.analysis.psf.bulk.FieldSums` (``complete=True``) of the fields whose histograms are
    layers ``sources`` of ``dh`` -- what :func:`~lensrt.analysis.psf.bulk.field_sums` makes from downloaded
    histograms, made on their device (module docstring).

    Parameters
    ----------
    dh : DeviceHistograms
        The stream's per-batch histograms, still on its device.
    sources : sequence of int
        The stream source of each field (its layer in ``dh``).
    off_grid : array (F, B)
        Per-batch weight that landed off each field's grid.
    grids, references_mm, setup
        As for :func:`~lensrt.analysis.psf.bulk.field_sums`; every grid has shape (dh.ny, dh.nx).
    """
    from .bulk import FieldSums, mtf_requests
    from .energy import Rings
    from .jackknife import ee_radii_full, jackknife_se
    n, nb, ny, nx, dev = len(grids), dh.batches, dh.ny, dh.nx, dh.device
    if n == 0:
        return []
    if any(g.shape != (ny, nx) for g in grids) or nb < 2:
        raise LensrtError("device PSF sums need every grid of the histograms' shape and at least 2 batches")
    off = np.asarray(off_grid, dtype=np.float64)
    unit = wp.float64(dh.unit)
    base = _up(dh.bases(sources), wp.int32, dev)
    xs = _up(np.stack([g.x_mm for g in grids]), wp.float64, dev)
    ys = _up(np.stack([g.y_mm for g in grids]), wp.float64, dev)
    # pass 1: per pixel, then per (batch, frequency)
    P = ny * nx
    H_d = wp.empty((n, P), dtype=wp.float64, device=dev)
    lit_d = wp.empty((n, P), dtype=wp.int32, device=dev)
    ss_d = wp.empty((n, P), dtype=wp.float64, device=dev)
    requests = [mtf_requests(g, r, setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm) for g, r in zip(grids, references_mm)]
    ex, ey, counts = _fourier_tables(grids, requests)
    kmax = ex.shape[1]
    sums_d = wp.zeros((n, nb, 3), dtype=wp.float64, device=dev)
    otf_d = wp.zeros((n, nb, kmax, 2), dtype=wp.float64, device=dev)
    launch(_first_pass, dim=n * P + n * nb * (kmax + 1), device=dev,
           inputs=[dh.array, base, dh.stride, nb, ny, nx, unit, H_d, lit_d, ss_d, xs, ys, _up(ex.real, wp.float64, dev),
                   _up(ex.imag, wp.float64, dev), _up(ey.real, wp.float64, dev), _up(ey.imag, wp.float64, dev),
                   _up(counts, wp.int32, dev), sums_d, otf_d])
    H, ss, bsums, otf = download(H_d), download(ss_d), download(sums_d), download(otf_d)
    s_b, sx_b, sy_b = bsums[:, :, 0], bsums[:, :, 1], bsums[:, :, 2]
    # the host's small steps, as bulk._chunk_sums and the jackknife functions take them
    total = (s_b + off).sum(axis=1)
    area = np.array([g.pixel_area_mm2 for g in grids])
    se = (np.sqrt(ss / (nb - 1)) * (nb / (total * area) / math.sqrt(nb))[:, None]).reshape(n, ny, nx)
    centres, hs_all = [], H.sum(axis=1)
    for k, g in enumerate(grids):
        gx, gy = (m.ravel() for m in g.mesh_mm())
        hs = hs_all[k]
        centres.append((float(np.einsum("i,i->", H[k], gx)) / hs, float(np.einsum("i,i->", H[k], gy)) / hs)
                       if hs > 0 else g.centre_mm)
    rings = Rings.many(grids, np.array(centres), 4)
    fractions = [float(v) for v in setup.ee_fractions]
    radii = np.full((n, max(1, len(fractions))), -1.0)
    ee_full, profiles = [], []
    for k, g in enumerate(grids):
        full, prof = ee_radii_full(H[k], float(total[k]), g, rings[k], fractions) if hs_all[k] > 0 else ({}, None)
        ee_full.append(full)
        profiles.append(prof)
        for j, frac in enumerate(fractions):
            radii[k, j] = full.get(frac, -1.0)
    # pass 2: each batch's light inside the circles, the geometric radius without each batch
    sx, sy = sx_b.sum(axis=1), sy_b.sum(axis=1)
    rest = hs_all[:, None] - s_b
    cxy = np.array([[sx[k] / hs_all[k], sy[k] / hs_all[k]] if hs_all[k] > 0 else [0.0, 0.0] for k in range(n)])
    with np.errstate(divide="ignore", invalid="ignore"):
        loo_c = np.stack([np.where(rest > 0, (sx[:, None] - sx_b) / rest, cxy[:, :1]),
                          np.where(rest > 0, (sy[:, None] - sy_b) / rest, cxy[:, 1:])], axis=2)
    half = np.array([r.h for r in rings])
    offs = np.stack([np.unique(r.ox) for r in rings])
    e_d = wp.zeros((n, radii.shape[1], nb), dtype=wp.float64, device=dev)
    loo_d = wp.zeros((n, nb), dtype=wp.float64, device=dev)
    full_d = wp.zeros(n, dtype=wp.float64, device=dev)
    launch(_radius_pass, dim=(n, nb, radii.shape[1] + 1), device=dev,
           inputs=[dh.array, base, dh.stride, ny, nx, unit, xs, ys, _up(half, wp.float64, dev),
                   _up(offs, wp.float64, dev), _up(radii, wp.float64, dev), _up(np.array(centres), wp.float64, dev),
                   lit_d, _up(cxy, wp.float64, dev), _up(loo_c, wp.float64, dev), e_d, loo_d, full_d])
    e_b, loo, geo_full = download(e_d), download(loo_d), download(full_d)
    out = []
    for k, g in enumerate(grids):
        geo = (0.0, 0.0)
        if hs_all[k] > 0:
            lk = np.where(rest[k] > 0, np.maximum(loo[k], 0.0), 0.0)
            geo = (float(geo_full[k]), float(jackknife_se(lk)))
        ee = {frac: (ee_full[k][frac], e_b[k, j]) for j, frac in enumerate(fractions) if frac in ee_full[k]}
        fs = {}
        a = 0
        for fx, fy in requests[k]:
            b = a + fx.size
            fs[(fx.tobytes(), fy.tobytes())] = otf[k, :, a:b, 0] + 1j * otf[k, :, a:b, 1]
            a = b
        out.append(FieldSums(H[k], s_b[k], sx_b[k], sy_b[k], None, se[k], rings[k], fs, complete=True,
                             geometric_radius=geo, ee_batch=ee, ee_profiles=profiles[k]))
    return out
