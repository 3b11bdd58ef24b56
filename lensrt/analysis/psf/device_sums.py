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

__all__ = ["device_field_sums", "DeviceHistograms", "FIRST_PASS_MODULE", "SECOND_PASS_MODULE", "SECOND_PASS_BLOCK"]

#: the Warp module of each launch (a module is Warp's unit of compilation and caching): one per kernel, so that
#: each compiles only its own kernel, at its own block size, and the two compile side by side. In one module, a
#: GPU compiled both kernels twice -- once per block size of the two launches (NVRTC for sm_90 on the 2-core
#: build machine: 7.2 s at 256 lanes + 6.3 s at 128; 8.3 s of a cold report on an H100, docs/guide/report-speed.md)
FIRST_PASS_MODULE = __name__ + ".first_pass"
SECOND_PASS_MODULE = __name__ + ".second_pass"
#: lanes of a block of the second pass on a GPU (one block per field and encircled energy, or field and batch)
SECOND_PASS_BLOCK = 128

for _name in (__name__, FIRST_PASS_MODULE, SECOND_PASS_MODULE):
    wp.set_module_options({"enable_backward": False}, module=_name)


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


@wp.kernel(module=FIRST_PASS_MODULE)
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
    1 when its farthest point is, 0 when its nearest point is not, else the share of its s x s sub-pixel
    centres (``Rings.fractions``: the same sixteenths)."""
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


@wp.func
def _block_sum(v: wp.float64) -> wp.float64:
    """The sum of ``v`` over the block's lanes, on every lane (block-wide reductions below keep the lanes of a
    block in step: every loop they run is uniform across the block)."""
    return wp.tile_sum(wp.tile(v))[0]


@wp.func
def _energy(H: wp.array2d(dtype=wp.float64), f: int, xs: wp.array2d(dtype=wp.float64),
            ys: wp.array2d(dtype=wp.float64), cx: wp.float64, cy: wp.float64, h: wp.float64,
            off: wp.array2d(dtype=wp.float64), rad: wp.float64, lane: int) -> wp.float64:
    """The light of field f's all-batch histogram inside radius rad about (cx, cy) (``Rings.energy``; sums of
    fixed-point weights times sixteenths: exact in any order), the block's lanes sharing the pixels."""
    nx = xs.shape[1]
    acc = wp.float64(0.0)
    p = lane
    while p < H.shape[1]:
        v = H[f, p]
        if v != wp.float64(0.0):
            r = p // nx
            ay = wp.abs(ys[f, r] - cy)
            if ay - h < rad:
                acc = acc + v * _pixel_fraction(wp.abs(xs[f, p - r * nx] - cx), ay, h, rad, off, f)
        p = p + wp.block_dim()
    return _block_sum(acc)


@wp.func
def _profile_scan(H: wp.array2d(dtype=wp.float64), f: int, xs: wp.array2d(dtype=wp.float64),
                  ys: wp.array2d(dtype=wp.float64), cx: wp.float64, cy: wp.float64, h: wp.float64, far: int,
                  mid: wp.float64, lane: int) -> wp.vec3d:
    """Over the lit pixels' farthest (``far``) or nearest points' distances d: (the light of those with d <= mid,
    the largest d <= mid (-1 if none), the smallest d > mid (1e300 if none))."""
    nx = xs.shape[1]
    acc = wp.float64(0.0)
    below = wp.float64(-1.0)
    above = wp.float64(1.0e300)
    p = lane
    while p < H.shape[1]:
        v = H[f, p]
        if v > wp.float64(0.0):
            r = p // nx
            ax = wp.abs(xs[f, p - r * nx] - cx)
            ay = wp.abs(ys[f, r] - cy)
            d = wp.float64(0.0)
            if far == 1:
                d = wp.sqrt((ax + h) * (ax + h) + (ay + h) * (ay + h))
            else:
                gx = wp.max(ax - h, wp.float64(0.0))
                gy = wp.max(ay - h, wp.float64(0.0))
                d = wp.sqrt(gx * gx + gy * gy)
            if d <= mid:
                acc = acc + v
                below = wp.max(below, d)
            else:
                above = wp.min(above, d)
        p = p + wp.block_dim()
    return wp.vec3d(_block_sum(acc), wp.tile_max(wp.tile(below))[0], wp.tile_min(wp.tile(above))[0])


@wp.func
def _profile_value(H: wp.array2d(dtype=wp.float64), f: int, xs: wp.array2d(dtype=wp.float64),
                   ys: wp.array2d(dtype=wp.float64), cx: wp.float64, cy: wp.float64, h: wp.float64, far: int,
                   v: wp.float64, lane: int) -> wp.float64:
    """The smallest distance d of the lit pixels (farthest or nearest points) whose cumulative light (pixels
    with distances <= d) reaches v, the largest if none does: ``d[searchsorted(cumsum(h[argsort(d)]), v)]``
    (index clamped) of ``jackknife._radius_bisect``, found without sorting -- by bisection on the value, each
    step one pass, until one distinct value is left in the bracket (lo, hi] (C(lo) < v <= C(hi))."""
    top = _profile_scan(H, f, xs, ys, cx, cy, h, far, wp.float64(1.0e300), lane)
    hi = top[1]
    first = _profile_scan(H, f, xs, ys, cx, cy, h, far, wp.float64(-1.0), lane)
    if top[0] < v:
        return hi
    if v <= wp.float64(0.0):
        return first[2]
    lo = wp.float64(-1.0)
    next_above = first[2]
    steps = int(0)
    while next_above < hi and steps < 400:
        mid = lo + wp.float64(0.5) * (hi - lo)
        if mid <= lo or mid >= hi:
            mid = next_above
        s = _profile_scan(H, f, xs, ys, cx, cy, h, far, mid, lane)
        if s[0] >= v:
            hi = s[1]
        else:
            lo = mid
            next_above = s[2]
        steps = steps + 1
    return hi


@wp.func
def _ee_radius(H: wp.array2d(dtype=wp.float64), f: int, xs: wp.array2d(dtype=wp.float64),
               ys: wp.array2d(dtype=wp.float64), cx: wp.float64, cy: wp.float64, h: wp.float64,
               off: wp.array2d(dtype=wp.float64), target: wp.float64, tol: wp.float64, lane: int) -> wp.float64:
    """``jackknife._radius_bisect``: the radius whose light reaches ``target``, bracketed by the radial profiles,
    bisected to ``tol`` (the same brackets, midpoints and comparisons)."""
    one = wp.float64(1.0)
    hi = _profile_value(H, f, xs, ys, cx, cy, h, 1, target * (one - wp.float64(1e-12)), lane) + wp.float64(1e-12)
    lo = wp.max(_profile_value(H, f, xs, ys, cx, cy, h, 0, target, lane) - wp.float64(1e-12), wp.float64(0.0))
    e_lo = _energy(H, f, xs, ys, cx, cy, h, off, lo, lane)
    e_hi = _energy(H, f, xs, ys, cx, cy, h, off, hi, lane)
    if not (e_lo < target and target <= e_hi):
        lo = wp.float64(0.0)
        far = wp.float64(0.0)
        p = lane
        while p < H.shape[1]:  # the farthest point of any pixel
            r = p // xs.shape[1]
            ax = wp.abs(xs[f, p - r * xs.shape[1]] - cx) + h
            ay = wp.abs(ys[f, r] - cy) + h
            far = wp.max(far, wp.sqrt(ax * ax + ay * ay))
            p = p + wp.block_dim()
        hi = wp.tile_max(wp.tile(far))[0]
    while hi - lo > tol:
        mid = wp.float64(0.5) * (lo + hi)
        if _energy(H, f, xs, ys, cx, cy, h, off, mid, lane) < target:
            lo = mid
        else:
            hi = mid
    return wp.float64(0.5) * (lo + hi)


@wp.func
def _ee_block(hist: wp.array(dtype=wp.int64), i0: int, stride: int, nb: int, ny: int, unit: wp.float64,
              H: wp.array2d(dtype=wp.float64), f: int, j: int, xs: wp.array2d(dtype=wp.float64),
              ys: wp.array2d(dtype=wp.float64), half: wp.array(dtype=wp.float64),
              off: wp.array2d(dtype=wp.float64), ee_in: wp.array3d(dtype=wp.float64),
              centre: wp.array2d(dtype=wp.float64), ee_out: wp.array3d(dtype=wp.float64),
              e_b: wp.array3d(dtype=wp.float64), lane: int):
    """Encircled-energy fraction j of field f: radius, light inside it, dE/dr, the gradient of the light in the
    centre (x, y), and each batch's light inside it (``jackknife.ee_radii_jackknife``'s inputs)."""
    target = ee_in[f, j, 0]
    if target < wp.float64(0.0):
        return
    tol = ee_in[f, j, 1]
    d = ee_in[f, j, 2]
    cx = centre[f, 0]
    cy = centre[f, 1]
    h = half[f]
    full = _ee_radius(H, f, xs, ys, cx, cy, h, off, target, tol, lane)
    nx = xs.shape[1]
    lo = wp.max(full - d, wp.float64(0.0))
    e_full = wp.float64(0.0)
    slope = wp.float64(0.0)
    g_x = wp.float64(0.0)
    g_y = wp.float64(0.0)
    p = lane
    while p < H.shape[1]:
        v = H[f, p]
        if v != wp.float64(0.0):
            r = p // nx
            x = xs[f, p - r * nx]
            y = ys[f, r]
            ax = wp.abs(x - cx)
            ay = wp.abs(y - cy)
            e_full = e_full + v * _pixel_fraction(ax, ay, h, full, off, f)
            slope = slope + v * (_pixel_fraction(ax, ay, h, full + d, off, f) - _pixel_fraction(ax, ay, h, lo, off, f))
            g_x = g_x + v * (_pixel_fraction(wp.abs(x - (cx + d)), ay, h, full, off, f)
                             - _pixel_fraction(wp.abs(x - (cx - d)), ay, h, full, off, f))
            g_y = g_y + v * (_pixel_fraction(ax, wp.abs(y - (cy + d)), h, full, off, f)
                             - _pixel_fraction(ax, wp.abs(y - (cy - d)), h, full, off, f))
        p = p + wp.block_dim()
    e_full = _block_sum(e_full)
    slope = _block_sum(slope)
    g_x = _block_sum(g_x)
    g_y = _block_sum(g_y)
    if lane == 0:
        ee_out[f, j, 0] = full
        ee_out[f, j, 1] = e_full
        ee_out[f, j, 2] = slope / (full + d - lo)
        ee_out[f, j, 3] = g_x / (wp.float64(2.0) * d)
        ee_out[f, j, 4] = g_y / (wp.float64(2.0) * d)
    for b in range(nb):
        acc = wp.float64(0.0)
        p = lane
        while p < H.shape[1]:
            r = p // nx
            ay = wp.abs(ys[f, r] - cy)
            if ay - h < full:
                k = hist[i0 + b * stride + (ny - 1 - r) * nx + p - r * nx]
                if k != wp.int64(0):
                    acc = acc + wp.float64(k) * unit * _pixel_fraction(wp.abs(xs[f, p - r * nx] - cx), ay, h, full,
                                                                       off, f)
            p = p + wp.block_dim()
        acc = _block_sum(acc)
        if lane == 0:
            e_b[f, j, b] = acc


@wp.kernel(module=SECOND_PASS_MODULE)
def _second_pass(hist: wp.array(dtype=wp.int64), base: wp.array(dtype=wp.int32), stride: int, nb: int, ny: int,
                 unit: wp.float64, H: wp.array2d(dtype=wp.float64), xs: wp.array2d(dtype=wp.float64),
                 ys: wp.array2d(dtype=wp.float64), half: wp.array(dtype=wp.float64),
                 off: wp.array2d(dtype=wp.float64), ee_in: wp.array3d(dtype=wp.float64),
                 centre: wp.array2d(dtype=wp.float64), lit: wp.array2d(dtype=wp.int32),
                 geo_c: wp.array2d(dtype=wp.float64), loo_c: wp.array3d(dtype=wp.float64),
                 ee_out: wp.array3d(dtype=wp.float64), e_b: wp.array3d(dtype=wp.float64),
                 loo: wp.array2d(dtype=wp.float64), full: wp.array(dtype=wp.float64)):
    """Block (f, t), its lanes sharing the pixels: t < J, encircled-energy fraction t of field f
    (:func:`_ee_block`); else batch b = t - J: the geometric radius without batch b (the farthest bin still lit,
    from the left-out centroid ``loo_c``) and, for b = 0, with all batches (about the centroid ``geo_c``, from
    the per-batch moments as the host finds it)."""
    f, t, lane = wp.tid()
    nj = ee_in.shape[1]
    nx = xs.shape[1]
    if t < nj:
        _ee_block(hist, base[f], stride, nb, ny, unit, H, f, t, xs, ys, half, off, ee_in, centre, ee_out, e_b, lane)
        return
    b = t - nj
    i0 = base[f] + b * stride
    ix = loo_c[f, b, 0]
    iy = loo_c[f, b, 1]
    best = wp.float64(-1.0)
    best_all = wp.float64(-1.0)
    p = lane
    while p < H.shape[1]:
        n = lit[f, p]
        if n > 0:
            r = p // nx
            c = p - r * nx
            mine = int(0)
            if hist[i0 + (ny - 1 - r) * nx + c] > wp.int64(0):
                mine = 1
            if n - mine > 0:
                dx = xs[f, c] - ix
                dy = ys[f, r] - iy
                best = wp.max(best, wp.sqrt(dx * dx + dy * dy))
            dx0 = xs[f, c] - geo_c[f, 0]
            dy0 = ys[f, r] - geo_c[f, 1]
            best_all = wp.max(best_all, wp.sqrt(dx0 * dx0 + dy0 * dy0))
        p = p + wp.block_dim()
    best = wp.tile_max(wp.tile(best))[0]
    best_all = wp.tile_max(wp.tile(best_all))[0]
    if lane == 0:
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
    from .jackknife import jackknife_se
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
    total = np.array([float((s_b[k] + off[k]).sum()) for k in range(n)])
    area = np.array([g.pixel_area_mm2 for g in grids])
    se = (np.sqrt(ss / (nb - 1)) * (nb / (total * area) / math.sqrt(nb))[:, None]).reshape(n, ny, nx)
    hs_all = H.sum(axis=1)
    # the encircled-energy circles' targets and centres (as ee_radii_jackknife takes them), the left-out centroids
    fractions = [float(v) for v in setup.ee_fractions]
    ee_in, centres, hxy, totals, rest = _ee_inputs(H, s_b, off, grids, fractions)
    sx, sy = sx_b.sum(axis=1), sy_b.sum(axis=1)
    cxy = np.array([[sx[k] / hs_all[k], sy[k] / hs_all[k]] if hs_all[k] > 0 else [0.0, 0.0] for k in range(n)])
    with np.errstate(divide="ignore", invalid="ignore"):
        loo_c = np.stack([np.where(rest > 0, (sx[:, None] - sx_b) / rest, cxy[:, :1]),
                          np.where(rest > 0, (sy[:, None] - sy_b) / rest, cxy[:, 1:])], axis=2)
    half = np.array([0.5 * g.pitch_mm for g in grids])
    offs = np.stack([((np.arange(_SUPERSAMPLE) + 0.5) / _SUPERSAMPLE - 0.5) * 2.0 * h for h in half])
    # pass 3: the radii, their derivatives and each batch's light inside them; the geometric radius without
    # each batch
    nj = ee_in.shape[1]
    ee_d = wp.zeros((n, nj, 5), dtype=wp.float64, device=dev)
    e_d = wp.zeros((n, nj, nb), dtype=wp.float64, device=dev)
    loo_d = wp.zeros((n, nb), dtype=wp.float64, device=dev)
    full_d = wp.zeros(n, dtype=wp.float64, device=dev)
    block = SECOND_PASS_BLOCK if str(dev).startswith("cuda") else 1  # Warp's CPU runs blocks of one lane
    launch(_second_pass, dim=(n, nj + nb, block), block_dim=block, device=dev,
           inputs=[dh.array, base, dh.stride, nb, ny, unit, H_d, xs, ys, _up(half, wp.float64, dev),
                   _up(offs, wp.float64, dev), _up(ee_in, wp.float64, dev), _up(centres, wp.float64, dev), lit_d,
                   _up(cxy, wp.float64, dev), _up(loo_c, wp.float64, dev), ee_d, e_d, loo_d, full_d])
    ee_out, e_b, loo, geo_full = download(ee_d), download(e_d), download(loo_d), download(full_d)
    out = []
    for k, g in enumerate(grids):
        geo = (0.0, 0.0)
        if hs_all[k] > 0:
            lk = np.where(rest[k] > 0, np.maximum(loo[k], 0.0), 0.0)
            geo = (float(geo_full[k]), float(jackknife_se(lk)))
        tot_b = s_b[k] + off[k]
        ee = _ee_jackknife(ee_in[k], ee_out[k], e_b[k], centres[k], hs_all[k], hxy[k], s_b[k], sx_b[k], sy_b[k], tot_b,
                           totals[k], fractions)
        fs = {}
        a = 0
        for fx, fy in requests[k]:
            b = a + fx.size
            fs[(fx.tobytes(), fy.tobytes())] = otf[k, :, a:b, 0] + 1j * otf[k, :, a:b, 1]
            a = b
        out.append(FieldSums(H[k], s_b[k], sx_b[k], sy_b[k], None, se[k], None, fs, complete=True,
                             geometric_radius=geo, ee_radii=ee))
    return out


#: sub-pixels per side where a circle cuts a pixel (``Rings``' supersample of the jackknife's radii)
_SUPERSAMPLE = 4


def _ee_inputs(H: np.ndarray, s_b: np.ndarray, off: np.ndarray, grids: Sequence[ImageGrid],
               fractions: Sequence[float]) -> tuple[np.ndarray, ...]:
    """Per field and fraction (target light or -1 where the grid cannot hold it, bisection tolerance, centre
    shift: ``ee_radii_jackknife``'s), the centroids (F, 2) the circles are about and the sums of x and y over the
    all-batch histogram they come from (F, 2), each field's total light and light on the grid less each
    batch's (F, B)."""
    n = len(grids)
    ee_in = np.full((n, max(1, len(fractions)), 3), -1.0)
    centres = np.zeros((n, 2))
    hxy = np.zeros((n, 2))
    totals = np.zeros(n)
    hs_all = H.sum(axis=1)
    for k, g in enumerate(grids):
        totals[k] = float((s_b[k] + off[k]).sum())
        gx, gy = (m.ravel() for m in g.mesh_mm())
        hs = hs_all[k]
        if not hs > 0:
            continue
        hxy[k] = (float(np.einsum("i,i->", H[k], gx)), float(np.einsum("i,i->", H[k], gy)))
        centres[k] = (hxy[k, 0] / hs, hxy[k, 1] / hs)
        for j, frac in enumerate(fractions):
            if not hs < frac * totals[k]:
                ee_in[k, j] = (frac * totals[k], 1e-3 * g.pitch_mm, 0.25 * g.pitch_mm)
    return ee_in, centres, hxy, totals, hs_all[:, None] - s_b


def _ee_jackknife(ee_in: np.ndarray, ee_out: np.ndarray, e_b: np.ndarray, c: np.ndarray, hs: float,
                  hxy: np.ndarray, s_b: np.ndarray, sx_b: np.ndarray, sy_b: np.ndarray, tot_b: np.ndarray,
                  total: float, fractions: Sequence[float]) -> dict[float, tuple[float, float]]:
    """One field's encircled-energy radii and their linearised jackknife errors from the device's radius, light,
    dE/dr, centre gradient and per-batch light (the last lines of ``ee_radii_jackknife``, same operations)."""
    from .jackknife import jackknife_se
    out: dict[float, tuple[float, float]] = {}
    sx, sy = float(hxy[0]), float(hxy[1])
    rest = hs - s_b
    with np.errstate(divide="ignore", invalid="ignore"):
        cx_i = (sx - sx_b) / rest
        cy_i = (sy - sy_b) / rest
    for j, frac in enumerate(fractions):
        if ee_in[j, 0] < 0:
            continue
        full, e_full, dedr, g_x, g_y = (float(v) for v in ee_out[j])
        if not dedr > 0:
            out[frac] = (full, 0.0)
            continue
        e = e_full - e_b[j] + g_x * (cx_i - c[0]) + g_y * (cy_i - c[1])
        loo = np.where(rest > 0, full + (frac * (total - tot_b) - e) / dedr, full)
        out[frac] = (full, float(jackknife_se(loo)))
    return out
