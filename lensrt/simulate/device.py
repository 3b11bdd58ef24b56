"""The blur of :mod:`lensrt.simulate` on a device: Warp kernels and Warp tile FFTs (``wp.tile_fft``).

The same operator as the host path (:mod:`.convolve`, :mod:`.compose`), step for
step, with every full-size array on the device: per layer, a warp kernel (the
real chief-ray mapping through the layer's radial tables, bilinear colour,
nearest mask, relative illumination) writes the layer's channels; the PSF
spectra of the nodes the layer needs are transformed once (one batch); per cell
that the layer needs (:func:`lensrt.simulate.convolve.tile_plan`), the cell's
channels are packed two real signals to one complex one -- (r a, g a), (b a, a)
and per band (Y_b^2 a, 1), whose blur is the full-layer response -- weighted by
each corner column's tent and transformed along their rows (``wp.tile_fft``, one
row per block, zero-padded to powers of two); one kernel transposes them into
the four corners' slabs, scaled by each corner row's tent (the tents are
separable); row FFTs again; a kernel multiplies each corner's spectrum by its
node's PSF spectrum and sums the four (the frequency-domain blend); one inverse
transform per cell, added into the layer's box. A compositing kernel applies
"over"; a last kernel divides by the coverage and forms the coefficients and
linear sRGB. Only the picture, the layer index and the tables go up, only the
results come down.

Since a real kernel's convolution is linear, the blur of x1 + i x2 is
h * x1 + i h * x2: one complex FFT carries two real channels.

Single precision (the host path's FFTs are single precision too); results agree
with the host path to about 1e-5 of the signal (tests/simulate/test_device.py).
Cell FFT sizes are powers of two up to :data:`MAX_FFT`; a larger cell is one
clear error (use a finer PSF grid).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..errors import LensrtError
from .compose import radial_tables
from .convolve import cell_edges, meet_box, plan_from_cells

__all__ = ["simulate_on_device", "fft_rows", "MAX_FFT"]

#: the largest tile FFT (per axis); four elements per thread at most 1024 threads a block
MAX_FFT = 4096
_ELEMENTS_PER_THREAD = 4

wp.set_module_options({"enable_backward": False})


@wp.kernel
def _warp_layer(image: wp.array3d(dtype=wp.float32), index: wp.array2d(dtype=wp.uint8), inside: int, has_index: int,
                scale_tab: wp.array(dtype=wp.float64), ri_tab: wp.array(dtype=wp.float64), step: float,
                pitch: float, gain: float, yw: wp.array2d(dtype=wp.float32), shared: wp.array3d(dtype=wp.float32),
                own: wp.array3d(dtype=wp.float32), outside: wp.array(dtype=wp.int32)):
    """One layer's channels: colour x alpha, alpha (shared) and Y_b^2 alpha per band (own); the layer is where
    ``index`` (its input mask) equals ``inside``."""
    r, c = wp.tid()
    rows = image.shape[0]
    cols = image.shape[1]
    u = (wp.float64(c) - wp.float64(0.5) * wp.float64(cols - 1)) * wp.float64(pitch)
    v = (wp.float64(0.5) * wp.float64(rows - 1) - wp.float64(r)) * wp.float64(pitch)
    rad = wp.sqrt(u * u + v * v)
    x = rad / wp.float64(step)
    k = wp.min(int(x), scale_tab.shape[0] - 2)
    t = x - wp.float64(k)
    s = scale_tab[k] + t * (scale_tab[k + 1] - scale_tab[k])
    ri = ri_tab[k] + t * (ri_tab[k + 1] - ri_tab[k])
    ci = u * s / wp.float64(pitch) + wp.float64(0.5) * wp.float64(cols - 1)
    rr = wp.float64(0.5) * wp.float64(rows - 1) - v * s / wp.float64(pitch)
    half = wp.float64(0.5)
    if ci < -half or ci > wp.float64(cols) - half or rr < -half or rr > wp.float64(rows) - half:
        wp.atomic_add(outside, 0, 1)
    alpha = float(1.0)
    if has_index != 0:
        rn = wp.clamp(int(wp.floor(rr + half)), 0, rows - 1)
        cn = wp.clamp(int(wp.floor(ci + half)), 0, cols - 1)
        if int(index[rn, cn]) != inside:
            alpha = float(0.0)
    # bilinear, edge pixels repeated beyond the frame (scipy's map_coordinates, order 1, mode "nearest")
    y = wp.clamp(rr, wp.float64(0.0), wp.float64(rows - 1))
    xx = wp.clamp(ci, wp.float64(0.0), wp.float64(cols - 1))
    r0 = wp.min(int(y), rows - 1)
    c0 = wp.min(int(xx), cols - 1)
    r1 = wp.min(r0 + 1, rows - 1)
    c1 = wp.min(c0 + 1, cols - 1)
    ty = float(y - wp.float64(r0))
    tx = float(xx - wp.float64(c0))
    g = float(ri) * gain * alpha
    for ch in range(3):
        top = image[r0, c0, ch] * (1.0 - tx) + image[r0, c1, ch] * tx
        bot = image[r1, c0, ch] * (1.0 - tx) + image[r1, c1, ch] * tx
        shared[ch, r, c] = (top * (1.0 - ty) + bot * ty) * g
    shared[3, r, c] = alpha
    for b in range(own.shape[0]):
        yb = yw[b, 0] * shared[0, r, c] + yw[b, 1] * shared[1, r, c] + yw[b, 2] * shared[2, r, c]
        own[b, r, c] = yb * yb * alpha


@wp.kernel
def _cell_flags(shared: wp.array3d(dtype=wp.float32), row_cell: wp.array(dtype=wp.int32),
                col_edges: wp.array(dtype=wp.int32), flags: wp.array2d(dtype=wp.int32)):
    """flags[cell] = 1 where the layer's alpha (``shared[3]``) is non-zero somewhere in the cell: one thread
    per picture row and cell column (``row_cell``: each row's cell row)."""
    r, cj = wp.tid()
    for c in range(col_edges[cj], col_edges[cj + 1]):
        if shared[3, r, c] > 0.0:
            flags[row_cell[r], cj] = 1
            break


@wp.kernel
def _pack_psfs(psf: wp.array3d(dtype=wp.float32), p: int, buf: wp.array2d(dtype=wp.vec2f)):
    """Slab k (p rows of the buffer): the k-th PSF (real), zero-padded."""
    k, y, x = wp.tid()
    n = psf.shape[1]
    val = wp.vec2f(0.0, 0.0)
    if y < n and x < n:
        val = wp.vec2f(psf[k, y, x], 0.0)
    buf[k * p + y, x] = val


@wp.kernel
def _pack_cell(shared: wp.array3d(dtype=wp.float32), own: wp.array3d(dtype=wp.float32),
               wc: wp.array2d(dtype=wp.float32), j0: int, r0: int, c0: int, w: int, h: int,
               buf: wp.array2d(dtype=wp.vec2f)):
    """Per corner column jj (nodes j0, j0 + 1) and slab s, the cell's h rows weighted by that node's column
    tent: (r a, g a), (b a, a), per band (Y_b^2 a, 1) -- the last one's blur is the full-layer response."""
    jj, s, y, x = wp.tid()
    n_b = own.shape[0]
    val = wp.vec2f(0.0, 0.0)
    if x < w:
        wt = wc[j0 + jj, c0 + x]
        if s == 0:
            val = wp.vec2f(shared[0, r0 + y, c0 + x], shared[1, r0 + y, c0 + x]) * wt
        elif s == 1:
            val = wp.vec2f(shared[2, r0 + y, c0 + x], shared[3, r0 + y, c0 + x]) * wt
        else:
            val = wp.vec2f(own[s - 2, r0 + y, c0 + x], 1.0) * wt
    buf[((jj * (2 + n_b)) + s) * h + y, x] = val


@wp.kernel
def _spread_corners(src: wp.array2d(dtype=wp.vec2f), wr: wp.array2d(dtype=wp.float32), i0: int, r0: int, h: int,
                    slabs: int, p: int, q: int, dst: wp.array2d(dtype=wp.vec2f)):
    """Transpose the row-transformed slabs (h, q) of corner column jj into the four corners' slabs (q, p), each
    scaled by its node row's tent and zero-padded to p: corner c = 2 ii + jj."""
    c, s, x, y = wp.tid()
    ii = c // 2
    jj = c - 2 * ii
    val = wp.vec2f(0.0, 0.0)
    if y < h:
        val = src[(jj * slabs + s) * h + y, x] * wr[i0 + ii, r0 + y]
    dst[(c * slabs + s) * q + x, y] = val


@wp.kernel
def _transpose(src: wp.array2d(dtype=wp.vec2f), p: int, q: int, dst: wp.array2d(dtype=wp.vec2f)):
    """Per slab: (p, q) -> (q, p)."""
    s, y, x = wp.tid()
    dst[s * q + x, y] = src[s * p + y, x]


@wp.kernel
def _multiply_corners(spec: wp.array2d(dtype=wp.vec2f), nodes: wp.array2d(dtype=wp.vec2f),
                      slot: wp.array(dtype=wp.int32), n_b: int, rows: int, out: wp.array2d(dtype=wp.vec2f)):
    """Per band b: slabs 0 and 1 and b's own slab of each corner times that corner node's PSF spectrum for b,
    summed over the four corners -> out slabs 3b .. 3b + 2 (the frequency-domain blend of the cell)."""
    s, y, x = wp.tid()
    b = s // 3
    j = s - 3 * b
    src = j
    if j == 2:
        src = 2 + b
    slabs = 2 + n_b
    re = float(0.0)
    im = float(0.0)
    for c in range(4):
        a = spec[(c * slabs + src) * rows + y, x]
        k = nodes[(slot[c] * n_b + b) * rows + y, x]
        re += a[0] * k[0] - a[1] * k[1]
        im += a[0] * k[1] + a[1] * k[0]
    out[s * rows + y, x] = wp.vec2f(re, im)


@wp.kernel
def _accumulate(res: wp.array2d(dtype=wp.vec2f), p: int, scale: float, sr0: int, sc0: int, dr0: int, dc0: int,
                blurred: wp.array4d(dtype=wp.float32), ones: wp.array3d(dtype=wp.float32)):
    """Add the tile's blur (full convolution, from (sr0, sc0)) into the box from (dr0, dc0)."""
    b, y, x = wp.tid()
    a0 = res[(3 * b) * p + sr0 + y, sc0 + x] * scale
    a1 = res[(3 * b + 1) * p + sr0 + y, sc0 + x] * scale
    a2 = res[(3 * b + 2) * p + sr0 + y, sc0 + x] * scale
    blurred[b, 0, dr0 + y, dc0 + x] += a0[0]
    blurred[b, 1, dr0 + y, dc0 + x] += a0[1]
    blurred[b, 2, dr0 + y, dc0 + x] += a1[0]
    blurred[b, 3, dr0 + y, dc0 + x] += a1[1]
    blurred[b, 4, dr0 + y, dc0 + x] += a2[0]
    ones[b, dr0 + y, dc0 + x] += a2[1]


@wp.kernel
def _composite(blurred: wp.array4d(dtype=wp.float32), ones: wp.array3d(dtype=wp.float32), r0: int, c0: int,
               yw: wp.array2d(dtype=wp.float32), rays: wp.array(dtype=wp.float32), col: wp.array4d(dtype=wp.float32),
               acc: wp.array3d(dtype=wp.float32), var: wp.array3d(dtype=wp.float32)):
    """"over" of one layer's normalised blur (:class:`lensrt.simulate.compose.Compositor`)."""
    b, y, x = wp.tid()
    inv_u = 1.0 / wp.max(ones[b, y, x], 1.0e-12)
    red = blurred[b, 0, y, x] * inv_u
    grn = blurred[b, 1, y, x] * inv_u
    blu = blurred[b, 2, y, x] * inv_u
    a = wp.clamp(blurred[b, 3, y, x] * inv_u, 0.0, 1.0)
    q = blurred[b, 4, y, x] * inv_u
    yb = yw[b, 0] * red + yw[b, 1] * grn + yw[b, 2] * blu
    v = wp.max(q - yb * yb, 0.0) / wp.max(rays[b], 1.0)
    keep = 1.0 - a
    r = r0 + y
    c = c0 + x
    col[b, 0, r, c] = col[b, 0, r, c] * keep + red
    col[b, 1, r, c] = col[b, 1, r, c] * keep + grn
    col[b, 2, r, c] = col[b, 2, r, c] * keep + blu
    var[b, r, c] = var[b, r, c] * keep * keep + v
    acc[b, r, c] = acc[b, r, c] * keep + a


@wp.kernel
def _finish(col: wp.array4d(dtype=wp.float32), acc: wp.array3d(dtype=wp.float32), var: wp.array3d(dtype=wp.float32),
            to_rgb: wp.array3d(dtype=wp.float32), coef: wp.array4d(dtype=wp.float32),
            rgb: wp.array3d(dtype=wp.float32), var_y: wp.array2d(dtype=wp.float32)):
    """C / Acc per band -> coefficients (K, H, W, 3), linear sRGB and the variance of Y."""
    y, x = wp.tid()
    out = wp.vec3f(0.0, 0.0, 0.0)
    v = float(0.0)
    for b in range(col.shape[0]):
        a = acc[b, y, x]
        inv = float(0.0)
        if a > 1.0e-6:
            inv = 1.0 / a
        for c in range(3):
            val = col[b, c, y, x] * inv
            coef[b, y, x, c] = val
            for o in range(3):
                out[o] = out[o] + to_rgb[o, b, c] * val
        v += var[b, y, x] * inv * inv
    for o in range(3):
        rgb[y, x, o] = out[o]
    var_y[y, x] = v


_FFT_KERNELS: dict = {}
#: whether cuFFTDx (libmathdx) builds the tile FFTs on CUDA; set to False, with a note, if it fails to
FFT_STATE = {"mathdx": True, "note": ""}


def fft_rows(n: int, inverse: bool, mathdx: bool = True):
    """A kernel that transforms every row (length ``n``, a power of two) of a 2-D vec2f array in place
    (``mathdx``: let Warp use cuFFTDx on CUDA; else its cooperative radix-2 tile FFT)."""
    key = (int(n), bool(inverse), bool(mathdx))
    if key not in _FFT_KERNELS:
        def body(a: wp.array2d(dtype=wp.vec2f)):
            i, _lane = wp.tid()
            t = wp.tile_load(a, shape=(1, n), offset=(i, 0))
            if wp.static(inverse):
                wp.tile_ifft(t)
            else:
                wp.tile_fft(t)
            wp.tile_store(a, t, offset=(i, 0))
        body.__name__ = f"fft_rows_{n}_{'inv' if inverse else 'fwd'}_{'dx' if mathdx else 'r2'}"
        _FFT_KERNELS[key] = wp.kernel(body, module="unique",
                                      module_options={"enable_backward": False, "enable_mathdx_fft": bool(mathdx)})
    return _FFT_KERNELS[key]


def _rows_fft(a, n_rows: int, n: int, inverse: bool, device) -> None:
    """Every row of ``a`` (``n_rows`` rows of length ``n``) transformed in place. Should cuFFTDx fail to build
    the kernel on CUDA, Warp's own tile FFT is used from then on and the reason kept in ``FFT_STATE``."""
    if FFT_STATE["mathdx"]:
        try:
            wp.launch_tiled(fft_rows(n, inverse, True), dim=[n_rows], inputs=[a], block_dim=_block(n), device=device)
            return
        except Exception as err:  # noqa: BLE001 - a cuFFTDx build failure: fall back, say so
            if not wp.get_device(device).is_cuda:
                raise
            FFT_STATE["mathdx"] = False
            FFT_STATE["note"] = f"cuFFTDx tile FFT unavailable ({type(err).__name__}: {err}); Warp's radix-2 tile FFT"
    wp.launch_tiled(fft_rows(n, inverse, False), dim=[n_rows], inputs=[a], block_dim=_block(n), device=device)


def _pow2(n: int) -> int:
    return 1 << max(int(n - 1).bit_length(), 3)


def _fft2(buf, tmp, slabs: int, p: int, q: int, inverse: bool, device) -> None:
    """2-D FFT of ``slabs`` (p, q) slabs of ``buf``: rows, transpose into ``tmp`` (q, p), rows. The result is
    in ``tmp`` (transposed) for a forward transform; an inverse one starts from ``tmp`` (transposed) and ends in
    ``buf``."""
    if not inverse:
        _rows_fft(buf, slabs * p, q, False, device)
        wp.launch(_transpose, dim=(slabs, p, q), inputs=[buf, p, q, tmp], device=device)
        _rows_fft(tmp, slabs * q, p, False, device)
    else:
        _rows_fft(tmp, slabs * q, p, True, device)
        wp.launch(_transpose, dim=(slabs, q, p), inputs=[tmp, q, p, buf], device=device)
        _rows_fft(buf, slabs * p, q, True, device)


def _block(n: int) -> int:
    return max(1, n // _ELEMENTS_PER_THREAD)


def _node_spectra(psf: np.ndarray, nodes: list[tuple[int, int]], p: int, q: int, device):
    """The PSF spectra (transposed: slab ``slot * K + b`` holds q rows of p) of ``nodes`` [(i, j), ...], every
    band, zero-padded to p x q: one batch of launches per layer."""
    n_b, n = psf.shape[0], psf.shape[-1]
    ii, jj = np.array([i for i, _ in nodes]), np.array([j for _, j in nodes])
    host = np.ascontiguousarray(psf[:, ii, jj].transpose(1, 0, 2, 3).reshape(-1, n, n), dtype=np.float32)
    slabs = host.shape[0]
    buf = wp.empty((slabs * p, q), dtype=wp.vec2f, device=device)
    spec = wp.empty((slabs * q, p), dtype=wp.vec2f, device=device)
    wp.launch(_pack_psfs, dim=(slabs, p, q), inputs=[wp.array(host, dtype=wp.float32, device=device), p, buf],
              device=device)
    _fft2(buf, spec, slabs, p, q, False, device)
    return spec


def _blur_layer(shared, own, psf: np.ndarray, plan, wr, wc, device):
    """(blurred (K, 5, bh, bw), ones (K, bh, bw)) of one layer over ``plan.box`` (device arrays), cell by cell:
    the four corners' tent-weighted, transformed channels times their nodes' PSF spectra, summed, and one
    inverse transform per cell (the host path's scheme, :func:`lensrt.simulate.convolve.convolve_layer`)."""
    n_b, n = psf.shape[0], psf.shape[-1]
    er, ec = plan.row_edges, plan.col_edges
    r0b, r1b, c0b, c1b = plan.box
    blurred = wp.zeros((n_b, 5, r1b - r0b, c1b - c0b), dtype=wp.float32, device=device)
    ones = wp.zeros((n_b, r1b - r0b, c1b - c0b), dtype=wp.float32, device=device)
    h_max, w_max = int(np.diff(er).max()), int(np.diff(ec).max())
    p, q = _pow2(h_max + n - 1), _pow2(w_max + n - 1)
    if max(p, q) > MAX_FFT:
        raise LensrtError(f"a PSF cell needs a {p} x {q} FFT, more than {MAX_FFT} a side on the device",
                          hint="use a finer --grid (more PSF nodes) for this picture size")
    cells = []
    for ci, cj in zip(*np.nonzero(plan.cells_needed)):
        r0, r1, c0, c1 = int(er[ci]), int(er[ci + 1]), int(ec[cj]), int(ec[cj + 1])
        where = meet_box(r0, r1, c0, c1, n, plan.box)
        if where is not None:
            cells.append((int(ci), int(cj), (r0, r1, c0, c1), where))
    if not cells:
        return blurred, ones
    nodes = sorted({(ci + a, cj + b) for ci, cj, _, _ in cells for a in (0, 1) for b in (0, 1)})
    slot_of = {node: k for k, node in enumerate(nodes)}
    slots = wp.array(np.array([slot_of[(ci + a, cj + b)] for ci, cj, _, _ in cells for a in (0, 1) for b in (0, 1)],
                              dtype=np.int32), dtype=wp.int32, device=device)
    node_spec = _node_spectra(psf, nodes, p, q, device)
    slabs = 2 + n_b
    first = wp.empty((2 * slabs * h_max, q), dtype=wp.vec2f, device=device)
    spread = wp.empty((4 * slabs * q, p), dtype=wp.vec2f, device=device)
    prod = wp.empty((3 * n_b * q, p), dtype=wp.vec2f, device=device)
    back = wp.empty((3 * n_b * p, q), dtype=wp.vec2f, device=device)
    for k, (ci, cj, (r0, r1, c0, c1), ((sr, sc), (dr, dc))) in enumerate(cells):
        h, w = r1 - r0, c1 - c0
        wp.launch(_pack_cell, dim=(2, slabs, h, q), inputs=[shared, own, wc, cj, r0, c0, w, h, first], device=device)
        _rows_fft(first, 2 * slabs * h, q, False, device)
        wp.launch(_spread_corners, dim=(4, slabs, q, p), inputs=[first, wr, ci, r0, h, slabs, p, q, spread],
                  device=device)
        _rows_fft(spread, 4 * slabs * q, p, False, device)
        wp.launch(_multiply_corners, dim=(3 * n_b, q, p), inputs=[spread, node_spec, slots[4 * k:4 * k + 4], n_b, q,
                                                                  prod], device=device)
        _fft2(back, prod, 3 * n_b, p, q, True, device)
        wp.launch(_accumulate, dim=(n_b, dr.stop - dr.start, dc.stop - dc.start),
                  inputs=[back, p, 1.0 / (p * q), sr.start, sc.start, dr.start, dc.start, blurred, ones],
                  device=device)
    return blurred, ones


def simulate_on_device(layers, cam, optics: list, gains: list[float], grid, y_weights: np.ndarray, rays: np.ndarray,
                       to_rgb: np.ndarray, device: str):
    """Warp, blur and composite every layer on ``device``: (coefficients (K, H, W, 3), linear sRGB (H, W, 3),
    variance of Y (H, W), fraction of pixels from beyond the input frame) -- as the host path in
    :func:`lensrt.simulate.pipeline.simulate`. ``layers`` yields per layer, far first, its input (colour
    (H, W, 3), mask (H, W) bool or None: everywhere)."""
    from .psf_grid import hat_weights
    wp.init()
    dev = wp.get_device(device)
    rows, cols = cam.shape
    n_b = len(y_weights)
    yw = wp.array(np.asarray(y_weights, np.float32), dtype=wp.float32, device=dev)
    wr_h, wc_h = hat_weights(grid.node_rows, rows), hat_weights(grid.node_cols, cols)
    col = wp.zeros((n_b, 3, rows, cols), dtype=wp.float32, device=dev)
    acc = wp.zeros((n_b, rows, cols), dtype=wp.float32, device=dev)
    var = wp.zeros((n_b, rows, cols), dtype=wp.float32, device=dev)
    shared = wp.empty((4, rows, cols), dtype=wp.float32, device=dev)
    own = wp.empty((n_b, rows, cols), dtype=wp.float32, device=dev)
    outside = wp.zeros(len(optics), dtype=wp.int32, device=dev)  # per layer; read once at the end
    wr = wp.array(wr_h.astype(np.float32), dtype=wp.float32, device=dev)
    wc = wp.array(wc_h.astype(np.float32), dtype=wp.float32, device=dev)
    er, ec = cell_edges(grid.node_rows, rows), cell_edges(grid.node_cols, cols)
    row_cell = wp.array(np.repeat(np.arange(len(er) - 1), np.diff(er)).astype(np.int32), dtype=wp.int32, device=dev)
    ec_dev = wp.array(ec.astype(np.int32), dtype=wp.int32, device=dev)
    flags = wp.zeros((len(er) - 1, len(ec) - 1), dtype=wp.int32, device=dev)
    for li, (opt, (image, mask)) in enumerate(zip(optics, layers)):
        step, scale_tab, ri_tab = radial_tables(cam, opt)
        img = wp.array(np.ascontiguousarray(image, dtype=np.float32), dtype=wp.float32, device=dev)
        index = wp.array(mask.astype(np.uint8) if mask is not None else np.zeros((1, 1), np.uint8), dtype=wp.uint8,
                         device=dev)
        wp.launch(_warp_layer, dim=(rows, cols), device=dev,
                  inputs=[img, index, 1, int(mask is not None), wp.array(scale_tab, dtype=wp.float64, device=dev),
                          wp.array(ri_tab, dtype=wp.float64, device=dev), step, cam.pitch_mm, float(gains[li]), yw,
                          shared, own, outside[li:li + 1]])
        psf = grid.psf[li]
        # which cells the layer shows in, found on the device (only the small flag array comes down)
        flags.zero_()
        if mask is None:
            flags.fill_(1)
        else:
            wp.launch(_cell_flags, dim=(rows, len(ec) - 1), inputs=[shared, row_cell, ec_dev, flags], device=dev)
        plan = plan_from_cells(flags.numpy().astype(bool), er, ec, psf.shape[-1] // 2, (rows, cols))
        if not plan.cells.any():
            continue
        blurred, ones = _blur_layer(shared, own, psf, plan, wr, wc, dev)
        r0b, r1b, c0b, c1b = plan.box
        wp.launch(_composite, dim=(n_b, r1b - r0b, c1b - c0b), device=dev,
                  inputs=[blurred, ones, r0b, c0b, yw, wp.array(np.asarray(rays[li], np.float32), dtype=wp.float32,
                                                                   device=dev), col, acc, var])
    coef = wp.empty((n_b, rows, cols, 3), dtype=wp.float32, device=dev)
    rgb = wp.empty((rows, cols, 3), dtype=wp.float32, device=dev)
    var_y = wp.empty((rows, cols), dtype=wp.float32, device=dev)
    wp.launch(_finish, dim=(rows, cols), device=dev,
              inputs=[col, acc, var, wp.array(np.asarray(to_rgb, np.float32), dtype=wp.float32, device=dev), coef,
                      rgb, var_y])
    worst = int(outside.numpy().max()) if len(optics) else 0
    return coef.numpy(), rgb.numpy(), var_y.numpy(), worst / float(rows * cols)
