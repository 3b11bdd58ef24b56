"""Depth layers, the distortion warp, and back-to-front compositing of blurred layers.

Layers. The depth map is cut into layers at depths evenly spaced in 1/depth (the
blur diameter is linear in it); every pixel goes to the nearest layer (hard
assignment), so the depth error is at most half a layer spacing in dioptres
(reported). Without a depth map there is one layer at the focus distance.

Warp. For each layer and output pixel, the input is sampled (bilinear) at the
pinhole position of the direction whose real chief ray lands there
(:meth:`lensrt.simulate.optics.LayerOptics.ideal_of_real`); the layer's mask is
sampled nearest. Output pixels whose pinhole position lies outside the input
frame take the nearest edge pixel (counted in the sidecar). The sharp layer is
then multiplied by the layer's relative illumination and on-axis gain.

Compositing (occlusion). Layers are blurred by their own PSFs as premultiplied
colour B = h * (alpha I) and coverage A = h * alpha and composited back to front
with the "over" operator, C <- B + (1 - A) C, Acc <- A + (1 - A) Acc (Porter &
Duff 1984; the layered depth-of-field scheme of Kraus & Strengert, "Depth-of-Field
Rendering by Pyramidal Image Processing", Eurographics 2007, and Lee, Eisemann &
Seidel, "Real-time lens blur effects and focus control", SIGGRAPH 2010). The
B and A are first divided by the same blur of a full layer of ones, so that
a layer covering everything has A = 1 exactly (and the frame's edge does not
darken). The result is C / Acc: the division renormalises where a layer's hidden part (behind
a nearer layer, or beyond the frame edge) would otherwise darken its blur -- the
single-image input cannot show what is hidden. So a sharp foreground stays sharp
(its A is 1 over it: nothing from behind leaks onto it), and a blurred foreground
spreads over the background by its own blur radius only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from .convolve import TilePlan, convolve_layer, tile_plan
from .optics import Camera, LayerOptics, picture_positions_mm

__all__ = ["layer_depths_mm", "assign_layers", "Geometry", "geometry", "radial_tables", "LayerFill", "warp_layer",
           "layer_channels", "Compositor", "blur_and_composite", "TABLE_SAMPLES"]

#: floats of a layer's blurred channels composited at a time (a few MB: the passes stay in cache)
_CHUNK_FLOATS = 1 << 19
#: samples of the per-layer radial tables (real radius -> pinhole radius, relative illumination)
TABLE_SAMPLES = 4097


def layer_depths_mm(depth_m: np.ndarray, n_layers: int) -> np.ndarray:
    """At most ``n_layers`` layer depths (mm), evenly spaced in 1/depth over the map's range, far first."""
    if n_layers < 1:
        raise LensrtError(f"{n_layers} depth layers: use at least 1")
    inv = 1.0 / np.asarray(depth_m, dtype=np.float64).ravel()
    lo, hi = float(inv.min()), float(inv.max())
    if hi - lo <= 1e-12 * hi or n_layers == 1:
        return np.array([1000.0 / (0.5 * (lo + hi))])
    levels = _few_levels(inv, n_layers)
    if levels is not None:
        return np.sort(1000.0 / levels)[::-1]
    return 1000.0 / np.linspace(lo, hi, n_layers)


def _few_levels(values: np.ndarray, most: int) -> np.ndarray | None:
    """The distinct values of ``values`` (sorted) if there are at most ``most`` of them, else None. A strided
    sample gives the candidates (more than ``most`` there: more in the whole too); one search over the map
    checks that every value is one of them; failing that, one pass per level (no sort of the whole map)."""
    sample = np.unique(values[::max(1, values.size // 65536)])
    if len(sample) > most:
        return None
    idx = np.minimum(np.searchsorted(sample, values), len(sample) - 1)
    if np.array_equal(sample[idx], values):
        return sample
    levels, cur = [], -np.inf
    for _ in range(most + 1):
        nxt = float(np.min(values, where=values > cur, initial=np.inf))
        if not np.isfinite(nxt):
            return np.array(levels)
        levels.append(nxt)
        cur = nxt
    return None


def assign_layers(depth_m: np.ndarray, layers_mm: np.ndarray) -> tuple[np.ndarray, float]:
    """Layer index of every pixel (nearest in 1/depth; ties to the farther layer) and the largest dioptre
    error (1/m)."""
    inv = 1.0 / np.asarray(depth_m, dtype=np.float64)
    lev = 1000.0 / np.asarray(layers_mm, dtype=np.float64)  # increasing: layers far first
    idx = np.searchsorted(0.5 * (lev[1:] + lev[:-1]), inv, side="left").astype(np.int32)
    return idx, float(np.max(np.abs(inv - lev[idx])))


@dataclass(frozen=True)
class Geometry:
    """Per output pixel, shared by the layers: picture position (u, v) and radius r (mm, float64); ``row0``
    the frame row of its first row (a band of rows)."""

    u_mm: np.ndarray
    v_mm: np.ndarray
    r_mm: np.ndarray
    row0: int = 0


def geometry(cam: Camera, row_range: tuple[int, int] | None = None) -> Geometry:
    """The :class:`Geometry` of the camera's pixel frame, or of its rows [r0, r1) (``row_range``)."""
    r0, r1 = row_range if row_range is not None else (0, cam.shape[0])
    rows, cols = r1 - r0, cam.shape[1]
    u, v = picture_positions_mm(cam, np.arange(r0, r1)[:, None], np.arange(cols)[None, :])
    u, v = np.broadcast_to(u, (rows, cols)), np.broadcast_to(v, (rows, cols))
    return Geometry(u, v, np.hypot(u, v), int(r0))


def radial_tables(cam: Camera, opt: LayerOptics) -> tuple[float, np.ndarray, np.ndarray]:
    """(step in mm, scale s(r) = pinhole radius / real radius, relative illumination), on
    :data:`TABLE_SAMPLES` radii from 0 to the frame's corner: the layer's PCHIP tables, sampled once and then
    interpolated linearly per pixel (the same on the host and on a device)."""
    r_max = 0.5 * cam.pitch_mm * float(np.hypot(cam.shape[0], cam.shape[1])) * 1.0001
    r = np.linspace(0.0, r_max, TABLE_SAMPLES)
    ri = opt.ideal_of_real(r)
    scale = np.ones_like(r)
    scale[1:] = ri[1:] / r[1:]
    # on the axis the scale is the slope d r_i / d r (the limit of r_i / r)
    scale[0] = (ri[1] - ri[0]) / r[1] if len(r) > 1 else 1.0
    return float(r[1] - r[0]), scale, opt.ri_at(r)


class LayerFill:
    """The input of each depth layer: the picture's pixels of that layer, continued behind the nearer layers
    as far as their blur reaches.

    Where a nearer layer hides layer ``li`` (``layer_index > li``) and within ``reach_px`` of where it shows,
    the layer is taken to go on, with the colour of its nearest visible block (``block`` x ``block`` pixels,
    the mean of its visible pixels there): the lens looks that far behind a nearer layer's blurred edge
    (``reach_px``: the nearer layers' largest PSF half-width). This is the disocclusion fill of layered depth
    of field (Kraus & Strengert 2007, by nearest block instead of their pyramid); without it, the blurred edge
    of a foreground would be filled with the foreground itself where the background shows through it. The
    ring just outside the mask gets the fill colour too, so that the warp's bilinear samples at the mask's
    edge see the layer's own colour. The work is confined to the layer's bounding box grown by the reach, and
    one scratch copy of the picture is patched and restored layer by layer.
    """

    def __init__(self, image: np.ndarray, layer_index: np.ndarray, block: int = 8):
        self.image, self.index, self.block = image, layer_index, int(block)
        self._work: np.ndarray | None = None
        self._patched: tuple[np.ndarray, np.ndarray] | None = None

    def __call__(self, li: int, reach_px: int) -> tuple[np.ndarray, np.ndarray]:
        """(colour (H, W, 3) -- valid until the next call, mask (H, W) bool) of layer ``li``."""
        visible = self.index == li
        rows_any, cols_any = visible.any(axis=1), visible.any(axis=0)
        if not rows_any.any() or visible.all():
            return self.image, visible
        h, w = visible.shape
        bl, grow = self.block, max(int(reach_px), 0) + 2 * self.block + 1
        nz_r, nz_c = np.flatnonzero(rows_any), np.flatnonzero(cols_any)
        r0, c0 = max(nz_r[0] - grow, 0) // bl * bl, max(nz_c[0] - grow, 0) // bl * bl
        r1, c1 = min(nz_r[-1] + 1 + grow, h), min(nz_c[-1] + 1 + grow, w)
        mask_c, fill_rr, fill_cc, col = self._crop(li, reach_px, visible[r0:r1, c0:c1], (r0, r1, c0, c1))
        mask = visible.copy()
        mask[r0:r1, c0:c1] = mask_c
        if self._work is None:
            self._work = self.image.copy()
        elif self._patched is not None:  # undo the previous layer's patch
            pr, pc = self._patched
            self._work[pr, pc] = self.image[pr, pc]
        self._work[fill_rr + r0, fill_cc + c0] = col
        self._patched = (fill_rr + r0, fill_cc + c0)
        return self._work, mask

    def _crop(self, li: int, reach_px: int, vis: np.ndarray, box: tuple[int, int, int, int]):
        """Within the box: (mask, rows and cols of the pixels to fill, their colours)."""
        from scipy.ndimage import distance_transform_edt
        r0, r1, c0, c1 = box
        bl = self.block
        img, idx = self.image[r0:r1, c0:c1], self.index[r0:r1, c0:c1]
        h, w = vis.shape
        hb, wb = -(-h // bl), -(-w // bl)
        pad = ((0, hb * bl - h), (0, wb * bl - w))
        cnt = np.pad(vis, pad).reshape(hb, bl, wb, bl).sum(axis=(1, 3))
        sums = [np.pad(np.where(vis, img[..., k], np.float32(0.0)), pad).reshape(hb, bl, wb, bl).sum(axis=(1, 3))
                for k in range(3)]
        col = np.stack(sums, axis=-1) / np.maximum(cnt, 1)[..., None]
        dist, (ir, ic) = distance_transform_edt(cnt == 0, return_indices=True)
        mask = vis.copy()
        if reach_px > 0:
            near = dist * bl <= reach_px + bl  # blocks within reach (a block's size of slack)
            mask |= (idx > li) & near[np.arange(h)[:, None] // bl, np.arange(w)[None, :] // bl]
        rr, cc = np.nonzero(_dilate3(mask) & ~vis)
        return mask, rr, cc, col[ir[rr // bl, cc // bl], ic[rr // bl, cc // bl]].astype(self.image.dtype)


def _dilate3(mask: np.ndarray) -> np.ndarray:
    """``mask`` grown by one pixel (3 x 3 neighbourhood), by shifted ORs."""
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    grown = out.copy()
    out[:, 1:] |= grown[:, :-1]
    out[:, :-1] |= grown[:, 1:]
    return out


def _input_coords(cam: Camera, u: np.ndarray, v: np.ndarray, r: np.ndarray, step: float,
                  scale_tab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(row, col) in the input picture that output positions (u, v) of radius r (mm) sample."""
    rows, cols = cam.shape
    s = np.interp(r, np.arange(len(scale_tab)) * step, scale_tab)
    return 0.5 * (rows - 1) - v * s / cam.pitch_mm, u * s / cam.pitch_mm + 0.5 * (cols - 1)


def _shift_px(cam: Camera, step: float, scale_tab: np.ndarray) -> int:
    """An upper bound (pixels) of the distance between an output pixel and the input position it samples
    (r |s(r) - 1| over the table, rounded up, + 2 for the interpolation between table samples and the
    bilinear and nearest neighbours)."""
    r = np.arange(len(scale_tab)) * step
    return int(np.ceil(np.max(r * np.abs(scale_tab - 1.0)) / cam.pitch_mm)) + 2


def _outside_fraction(cam: Camera, geo: Geometry, step: float, scale_tab: np.ndarray, a: int, b: int,
                      reach: int) -> float:
    """Fraction of the pixels of rows a..b of ``geo`` that sample beyond the input frame. Only pixels within
    ``reach`` (:func:`_shift_px`) of the frame's edge can: the edge rows are looked at whole, the others at
    their ``reach`` columns either side (the same count as over every pixel)."""
    rows, cols = cam.shape
    if b <= a:
        return 0.0
    fr = geo.row0 + np.arange(a, b)
    edge = (fr < reach) | (fr >= rows - reach)
    cidx = np.arange(cols) if 2 * reach >= cols else np.r_[0:reach, cols - reach:cols]
    count = 0
    for ridx, cset in ((a + np.flatnonzero(edge), np.arange(cols)), (a + np.flatnonzero(~edge), cidx)):
        if len(ridx):
            rr, cc = _input_coords(cam, geo.u_mm[ridx][:, cset], geo.v_mm[ridx][:, cset], geo.r_mm[ridx][:, cset],
                                   step, scale_tab)
            count += int(np.count_nonzero((cc < -0.5) | (cc > cols - 0.5) | (rr < -0.5) | (rr > rows - 0.5)))
    return count / float((b - a) * cols)


def warp_layer(cam: Camera, geo: Geometry, opt: LayerOptics, image: np.ndarray, mask: np.ndarray | None,
               gain: float, count_rows: tuple[int, int] | None = None):
    """(layer (4, h, W): the sharp linear image x RI x gain -- zero where the layer is absent, so it is also
    colour x alpha -- and alpha (0 or 1); the fraction of pixels from beyond the input frame; the window (r0,
    r1, c0, c1) outside which the layer is zero) of a layer over the rows of ``geo`` (h of them): ``mask``
    (H, W) where the layer is in the input (None: everywhere); the fraction is counted over the rows
    ``count_rows`` of ``geo`` (default: all). Only the window -- the mask's bounding box grown by the largest
    shift of the warp -- is sampled."""
    from scipy.ndimage import map_coordinates
    rows, cols = cam.shape
    shape = geo.r_mm.shape
    step, scale_tab, ri_tab = radial_tables(cam, opt)
    reach = _shift_px(cam, step, scale_tab)
    a, b = count_rows if count_rows is not None else (0, shape[0])
    outside = _outside_fraction(cam, geo, step, scale_tab, a, b, reach)
    layer = np.zeros((4,) + shape, dtype=np.float32)
    sharp, alpha = layer[:3], layer[3]
    win = (0, shape[0], 0, shape[1])
    if mask is not None:
        rows_any, cols_any = mask.any(axis=1), mask.any(axis=0)
        if not rows_any.any():
            return layer, outside, (0, 0, 0, 0)
        nz_r, nz_c = np.flatnonzero(rows_any), np.flatnonzero(cols_any)
        win = (max(int(nz_r[0]) - reach - geo.row0, 0), min(int(nz_r[-1]) + 1 + reach - geo.row0, shape[0]),
               max(int(nz_c[0]) - reach, 0), min(int(nz_c[-1]) + 1 + reach, shape[1]))
        if win[0] >= win[1]:
            return layer, outside, (0, 0, 0, 0)
    sub = (slice(win[0], win[1]), slice(win[2], win[3]))
    ri_row, ci = _input_coords(cam, geo.u_mm[sub], geo.v_mm[sub], geo.r_mm[sub], step, scale_tab)
    if mask is None:
        alpha[sub] = 1.0
    else:  # the layer's mask, sampled nearest
        rn = np.clip(np.floor(ri_row + 0.5), 0, rows - 1).astype(np.intp)
        cn = np.clip(np.floor(ci + 0.5), 0, cols - 1).astype(np.intp)
        alpha[sub] = mask[rn, cn]
    sel = np.nonzero(alpha[sub])
    coords = np.stack([ri_row[sel], ci[sel]])
    gain_px = np.interp(geo.r_mm[sub][sel], np.arange(len(ri_tab)) * step, ri_tab) * gain
    for k in range(3):
        sharp[k][sub][sel] = map_coordinates(image[..., k], coords, order=1, mode="nearest") * gain_px
    return layer, outside, win


def layer_channels(layer: np.ndarray, y_weights: np.ndarray,
                   win: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """own (K, H, W): each band's Y^2 alpha of a ``layer`` (4, H, W) of :func:`warp_layer` (colour x alpha,
    alpha), float32, formed over the window (r0, r1, c0, c1) ``win`` only (zero beyond it, as the layer is)."""
    r0, r1, c0, c1 = win if win is not None else (0, layer.shape[1], 0, layer.shape[2])
    yw = np.asarray(y_weights, dtype=np.float32)
    own = np.zeros((len(yw),) + layer.shape[1:], dtype=np.float32)
    o = np.einsum("kc,chw->khw", yw, layer[:3, r0:r1, c0:c1])
    np.square(o, out=o)
    o *= layer[3, r0:r1, c0:c1]
    own[:, r0:r1, c0:c1] = o
    return own


class Compositor:
    """Back-to-front "over" compositing of blurred layers, all bands at once (module docstring).

    Accumulates colour C (K, 3, H, W), coverage Acc (K, H, W) and the variance of Y from the PSFs' rays
    (K, H, W); :meth:`add` takes the next nearer layer, :meth:`result` the coefficients and the variance.
    ``row0``: the row, in the frame of the blurred layers, of the compositor's first row (a band of rows:
    what the layers' boxes hold beyond its H rows is left out).
    """

    def __init__(self, n_bands: int, shape: tuple[int, int], y_weights: np.ndarray, row0: int = 0):
        self.row0 = int(row0)
        self.c = np.zeros((n_bands, 3) + tuple(shape), dtype=np.float32)
        self.acc = np.zeros((n_bands,) + tuple(shape), dtype=np.float32)
        self.var = np.zeros((n_bands,) + tuple(shape), dtype=np.float32)
        self.yw = np.asarray(y_weights, dtype=np.float32)

    def add(self, blurred: np.ndarray, ones: np.ndarray, box: tuple[int, int, int, int], rays: np.ndarray) -> None:
        """Composite a layer's blurred channels (K, 5, bh, bw) over the box (see
        :func:`lensrt.simulate.convolve.convolve_layer`); ``rays`` (K,) rays landed per PSF. ``blurred`` and
        ``ones`` are used as scratch."""
        r0, r1, c0, c1 = box
        lo, hi = max(r0, self.row0), min(r1, self.row0 + self.c.shape[2])
        if lo >= hi:
            return
        per_ray = np.maximum(np.asarray(rays, dtype=np.float32), 1.0)[:, None, None]
        # a few rows at a time, in place: the dozen passes below then run over data that stays in cache
        step = max(1, _CHUNK_FLOATS // (blurred.shape[0] * 5 * max(c1 - c0, 1)))
        for a0 in range(lo, hi, step):
            a1 = min(a0 + step, hi)
            self._add_rows(blurred[:, :, a0 - r0:a1 - r0], ones[:, a0 - r0:a1 - r0],
                           (a0 - self.row0, a1 - self.row0, c0, c1), per_ray)

    def _add_rows(self, blurred: np.ndarray, ones: np.ndarray, box: tuple[int, int, int, int],
                  per_ray: np.ndarray) -> None:
        r0, r1, c0, c1 = box
        # divide by the operator's response to a full, uniform layer: a layer that covers everything then has
        # coverage exactly 1 (the blend of node PSFs need not add up to 1 everywhere; the frame edge loses light)
        inv_u = np.maximum(ones, np.float32(1e-12), out=ones)
        np.reciprocal(inv_u, out=inv_u)
        blurred *= inv_u[:, None]
        b, a, q = blurred[:, :3], blurred[:, 3], blurred[:, 4]
        np.clip(a, 0.0, 1.0, out=a)
        yb = np.einsum("kchw,kc->khw", b, self.yw)
        np.square(yb, out=yb)
        v = np.subtract(q, yb, out=q)
        np.maximum(v, 0.0, out=v)
        v /= per_ray
        keep = np.subtract(np.float32(1.0), a, out=yb)
        c, acc, var = self.c[:, :, r0:r1, c0:c1], self.acc[:, r0:r1, c0:c1], self.var[:, r0:r1, c0:c1]
        c *= keep[:, None]
        c += b
        var *= keep
        var *= keep
        var += v
        acc *= keep
        acc += a

    def write(self, coef: np.ndarray, rgb: np.ndarray, var_y: np.ndarray, to_rgb: np.ndarray, row: int) -> None:
        """Write the result from frame row ``row`` on, a few rows at a time: the coefficients C / Acc into
        ``coef`` (K, H, W, 3), linear sRGB (``to_rgb`` (3, 3 K) on the coefficients) into ``rgb`` (H, W, 3),
        the variance of Y summed over the bands into ``var_y`` (H, W)."""
        n_b, _, h, w = self.c.shape
        m = np.asarray(to_rgb, dtype=np.float32).reshape(3, 3 * n_b)
        step = max(1, _CHUNK_FLOATS // (n_b * 5 * max(w, 1)))
        for a0 in range(0, h, step):
            a1 = min(a0 + step, h)
            acc = self.acc[:, a0:a1]
            good = acc > 1e-6
            inv = np.where(good, 1.0 / np.where(good, acc, 1.0), 0.0).astype(np.float32)
            c = self.c[:, :, a0:a1] * inv[:, None]
            coef[:, row + a0:row + a1] = c.transpose(0, 2, 3, 1)
            rgb[row + a0:row + a1] = (m @ c.reshape(3 * n_b, -1)).reshape(3, a1 - a0, w).transpose(1, 2, 0)
            var_y[row + a0:row + a1] = (self.var[:, a0:a1] * inv * inv).sum(axis=0)


def blur_and_composite(comp: Compositor, layer: np.ndarray, psf: np.ndarray, rays: np.ndarray,
                       wr: np.ndarray, wc: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                       win: tuple[int, int, int, int] | None = None) -> TilePlan:
    """Blur one layer (4, H, W) of :func:`warp_layer` (all bands, host FFTs) and composite it over what
    ``comp`` holds; returns its plan (``win``: the window outside which the layer is zero)."""
    plan = tile_plan(layer[3], rows, cols, psf.shape[-1] // 2)
    if not plan.cells.any():
        return plan
    own = layer_channels(layer, comp.yw, win)
    blurred, ones = convolve_layer(layer, own, psf, wr, wc, rows, cols, plan)
    comp.add(blurred, ones, plan.box, rays)
    return plan
