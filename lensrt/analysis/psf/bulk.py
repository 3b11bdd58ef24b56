"""The passes over a PSF map's per-batch histograms, made for many fields at once.

The analysis of one geometric PSF (:func:`lensrt.analysis.psf.result.geometric_psf`, the jackknife
helpers of :mod:`lensrt.analysis.psf.jackknife`, :func:`~lensrt.analysis.psf.geometric.add_mtf_estimates`)
reads the field's per-batch histograms (B, rows, cols) many times over: the all-batch histogram, the
per-batch totals and first moments, how many batches lit each bin, the per-pixel standard errors, the
per-batch Fourier sums of the MTF, and the pixel geometry of the encircled-energy circles.
:func:`field_sums` makes those passes for a stack of fields (F, B, rows, cols) as whole-array
operations -- reductions over the stack, one BLAS product per field for the Fourier sums (the
separable column-then-row sum of :func:`~lensrt.analysis.psf.jackknife.mtf_jackknife`) -- and gives
each field a :class:`FieldSums` that those functions take instead of recomputing (``sums=``).

A field's sums depend on its own histograms only, never on the other fields of the stack, so a PSF
map stays the same bits whatever its grouping (one field at a time goes through here too, as a stack
of one). The per-field code without ``sums`` is kept as the float64 reference: the two agree to
1e-12 relative (tests/analysis/psf/test_psf_bulk.py; sums in another order, BLAS for einsum).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ...errors import LensrtError
from ..grid import ImageGrid
from .energy import Rings
from .otf import mtf_directions, tangential_angle_rad, usable_freqs

__all__ = ["FieldSums", "field_sums", "mtf_requests", "FIELDS_PER_PASS", "analysis_on_device", "shape_only"]

#: fields per whole-array pass: bounds the temporaries (4 fields of 32 x 128^2 float64 are 16 MiB) and
#: gives a map's analysis threads runs of fields to share out
FIELDS_PER_PASS = 4


@dataclass(frozen=True)
class FieldSums:
    """Per-batch sums of one field's histograms hb (B, rows, cols) on its grid (module docstring).

    Attributes
    ----------
    H : array (rows * cols,)
        All-batch histogram, flattened.
    s_b, sx_b, sy_b : array (B,)
        Per-batch weight on the grid and its sums of x and y (mm, pixel centres).
    lit_n : array (rows * cols,) of int
        Batches that put weight in each bin.
    psf_stderr : array (rows, cols)
        Batch-means standard error of the unit-volume PSF (1/mm^2), as ``geometric_psf`` computes it.
    rings : Rings
        Pixel geometry about the centroid (supersample 4), the circles of the encircled-energy radii.
    otf : dict
        ``(fx.tobytes(), fy.tobytes())`` -> per-batch Fourier sums (B, K) complex of
        :func:`mtf_requests`' frequency sets.
    complete : bool
        Made on the histograms' device (:mod:`lensrt.analysis.psf.device_sums`): the fields below hold
        what would otherwise need the per-batch histograms, which the host does not have (``lit_n`` and
        ``rings`` are None).
    geometric_radius : (float, float) or None
        The geometric radius and its jackknife error (device sums).
    ee_radii : dict or None
        Encircled-energy fraction -> (radius mm, jackknife error) (device sums; fractions the grid cannot
        hold left out).
    """

    H: np.ndarray
    s_b: np.ndarray
    sx_b: np.ndarray
    sy_b: np.ndarray
    lit_n: np.ndarray | None
    psf_stderr: np.ndarray
    rings: Rings | None
    otf: dict
    complete: bool = False
    geometric_radius: tuple[float, float] | None = None
    ee_radii: dict | None = None


def analysis_on_device(device: str) -> bool:
    """Whether a map's passes over its per-batch histograms run on the histograms' device
    (:mod:`lensrt.analysis.psf.device_sums`) rather than here: on GPUs, where the histograms are and the
    host would first have to download them; on the CPU NumPy's passes (threads over fields) are faster than
    Warp's one-thread-per-launch CPU kernels. ``LENSRT_PSF_ANALYSIS`` = ``host`` / ``device`` chooses."""
    mode = os.environ.get("LENSRT_PSF_ANALYSIS", "auto").strip().lower() or "auto"
    if mode not in ("auto", "host", "device"):
        raise LensrtError(f"LENSRT_PSF_ANALYSIS={mode!r} is not one of auto, host, device",
                          hint="unset it, or set it to host or device")
    return mode == "device" or (mode == "auto" and str(device).startswith("cuda"))


def shape_only(batches: int, rows: int, cols: int) -> np.ndarray:
    """A read-only stand-in of zeros (batches, rows, cols) that takes no memory: the per-batch histograms' shape
    for the analysis functions when complete (device) :class:`FieldSums` hold every pass over them."""
    return np.broadcast_to(np.zeros((1, 1, 1)), (int(batches), int(rows), int(cols)))


def mtf_requests(grid: ImageGrid, reference_mm: tuple[float, float], freqs_ref, freqs_curve
                 ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (fx, fy) sets (cycles/mm) whose per-batch Fourier sums ``add_mtf_estimates`` asks a geometric
    PSF on ``grid`` for: the usable reference, then curve, frequencies, sagittal then tangential."""
    t = tangential_angle_rad(tuple(reference_mm))
    out = []
    for freqs in (freqs_ref, freqs_curve):
        f = usable_freqs(np.asarray(freqs, dtype=np.float64), 0.5 / grid.pitch_mm)
        if f.size:
            out.append(mtf_directions(f, (t + 0.5 * math.pi, t)))
    return out


def _fourier_sums(h: np.ndarray, grid: ImageGrid, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    """Per-batch Fourier sums (B, K) of h (B, rows, cols), phase origin at the grid centre: over the
    columns by one BLAS product (real and imaginary parts side by side), then over the rows."""
    cx, cy = grid.centre_mm
    ex = np.exp(-2j * np.pi * np.outer(fx, grid.x_mm - cx))  # (K, cols)
    ey = np.exp(-2j * np.pi * np.outer(fy, grid.y_mm - cy))  # (K, rows)
    k = fx.size
    # one small product per batch (a stacked matmul): one large one would start BLAS threads, which costs
    # more than it saves on arrays this size
    a = h @ np.ascontiguousarray(np.concatenate([ex.real, ex.imag]).T)  # (B, rows, 2K)
    return np.einsum("brf,fr->bf", a[:, :, :k] + 1j * a[:, :, k:], ey)


def _chunk_sums(h: np.ndarray, off: np.ndarray, grids: Sequence[ImageGrid], refs, setup: Any) -> list[FieldSums]:
    """:func:`field_sums` of one stack h (F, B, rows, cols) (all its arrays' passes at once)."""
    n, nb = h.shape[:2]
    flat = h.reshape(n, nb, -1)
    H = h.sum(axis=1).reshape(n, -1)
    s_b = flat.sum(axis=2)
    # per-batch first moments, field by field as the reference sums them (the jackknife of the centroid's
    # shift differences these sums: summed in another order they would move its errors by 1e-10)
    mesh = [[m.ravel() for m in g.mesh_mm()] for g in grids]
    sx_b = np.stack([np.einsum("bp,p->b", flat[k], m[0]) for k, m in enumerate(mesh)])
    sy_b = np.stack([np.einsum("bp,p->b", flat[k], m[1]) for k, m in enumerate(mesh)])
    lit_n = np.count_nonzero(flat > 0, axis=1)
    total = (s_b + off).sum(axis=1)
    area = np.array([g.pixel_area_mm2 for g in grids])
    # per-pixel standard deviation over the batches (numpy.std's two passes, its mean being H / B), scaled
    # to the unit-volume PSF's batch-means error afterwards (the reference scales first: 1e-16 apart)
    dev = flat - (H / nb)[:, None, :]
    np.multiply(dev, dev, out=dev)
    sd = np.sqrt(dev.sum(axis=1) / (nb - 1)).reshape(n, *h.shape[2:])
    se = sd * (nb / (total * area) / math.sqrt(nb))[:, None, None]
    # the encircled-energy rings of every field about its centroid (computed as ee_radii_jackknife does)
    centres = []
    for k, g in enumerate(grids):
        gx, gy = mesh[k]
        hs = H[k].sum()
        c = (float(np.einsum("i,i->", H[k], gx)) / hs, float(np.einsum("i,i->", H[k], gy)) / hs) if hs > 0 \
            else g.centre_mm
        centres.append(c)
    rings = Rings.many(grids, np.array(centres), 4)
    out = []
    for k, g in enumerate(grids):
        otf = {}
        for fx, fy in mtf_requests(g, refs[k], setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm):
            otf[(fx.tobytes(), fy.tobytes())] = _fourier_sums(h[k], g, fx, fy)
        out.append(FieldSums(H[k], s_b[k], sx_b[k], sy_b[k], lit_n[k], se[k], rings[k], otf))
    return out


def field_sums(hists: np.ndarray, off_grid: np.ndarray, grids: Sequence[ImageGrid],
               references_mm: Sequence[tuple[float, float]], setup: Any) -> list[FieldSums]:
    """The :class:`FieldSums` of every field of a stack, :data:`FIELDS_PER_PASS` fields per pass.

    Parameters
    ----------
    hists : array (F, B, rows, cols)
        Per-batch histograms of landed ray weight, one grid shape for all fields.
    off_grid : array (F, B)
        Per-batch weight that landed off each grid.
    grids : sequence of ImageGrid
        Each field's grid (pitch, position).
    references_mm : sequence of (float, float)
        Each field's reference point (mm; sets the sagittal and tangential directions).
    setup : PsfSetup
        Its ``mtf_freqs_cpmm`` and ``mtf_curve_cpmm`` (cycles/mm) name the Fourier sums made.
    """
    h = np.asarray(hists, dtype=np.float64)
    off = np.asarray(off_grid, dtype=np.float64)
    out: list[FieldSums] = []
    for k in range(0, h.shape[0], FIELDS_PER_PASS):
        sl = slice(k, k + FIELDS_PER_PASS)
        out.extend(_chunk_sums(h[sl], off[sl], grids[sl], references_mm[sl], setup))
    return out
