"""PSF results: the container, and the host side of geometric (ray-histogram) PSFs.

A geometric PSF is Monte Carlo: rays through the pupil land on the image
plane and are counted in a histogram. The tracer's *stream* kernel
accumulates, for each of B independent batches (differently seeded),

* a histogram ``hist[b, row, col]`` of ray weight on an :class:`ImageGrid`
  (and the weight that fell off the grid, ``off_grid[b]``), and
* the moment sums ``sums[b, :]`` = (w, w x, w y, w x^2, w x y, w y^2) over all
  landed rays, with (x, y) = ray position minus ``reference_mm`` (the chief
  ray's image point) so that float32 sums do not lose the spot's size to the
  field's size.

:func:`geometric_psf` turns those into a :class:`PsfResult`: the PSF
normalised to unit volume (p. 111) over the landed light, and centroid, RMS
radius, geometric radius and encircled-energy radii as
:class:`lensrt.stats.Estimate` with jackknife standard errors over batches.
:func:`histogram_rays` and :func:`ray_moment_sums` are the float64 NumPy
versions of that accumulation, the reference for the kernel's tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ...errors import LensrtError
from ...stats import Estimate, batch_means, jackknife
from .energy import centroid_mm, radius_for_energy
from ..grid import ImageGrid
from .otf import tangential_angle_rad

if TYPE_CHECKING:
    from .bulk import FieldSums

__all__ = ["PsfResult", "MOMENT_KEYS", "PSF_KINDS", "histogram_rays", "ray_moment_sums",
           "geometric_psf", "diffraction_result"]

#: order of the per-batch moment sums
MOMENT_KEYS = ("w", "wx", "wy", "wxx", "wxy", "wyy")
PSF_KINDS = ("geometric", "diffraction-fft", "diffraction-mft", "diffraction-huygens")


@dataclass(frozen=True)
class PsfResult:
    """One PSF at one field point, with everything needed to trust and reproduce it.

    Attributes
    ----------
    psf : array (rows, cols)
        Irradiance per unit power, 1/mm^2, unit volume over the plane (p. 111):
        ``psf.sum() * grid.pixel_area_mm2`` is the fraction of the light on the grid.
    grid : ImageGrid
        Pixel pitch (um) and sensor-plane position (mm) of every sample.
    kind : str
        One of :data:`PSF_KINDS`. Geometric PSFs are bin averages (MTFs divide
        out the bin aperture), diffraction PSFs point samples.
    wavelengths_nm, weights : tuple of float
        The spectrum the PSF integrates (weights sum to 1).
    field_xy : (float, float)
        Field point in the lens's field units (rad for angles, mm for heights).
    field_kind : str
        ``Fields.kind`` of the lens ("angle", "object_height", ...).
    reference_mm : (float, float)
        Sensor-plane point the PSF is referred to (the chief ray's image point).
    samples : int
        Rays traced (geometric) or pupil samples (diffraction).
    seconds : float
        Wall-clock seconds it took.
    seed : int or None
        Random seed (geometric), None for deterministic PSFs.
    batches : int
        Independent batches behind the standard errors (0 if deterministic).
    estimates : dict[str, Estimate]
        Named results with standard errors: ``centroid_x_mm``, ``centroid_y_mm``,
        ``rms_radius_mm``, ``rms_tangential_mm``, ``rms_sagittal_mm``,
        ``geometric_radius_mm``, ``ee50_radius_mm``, ``ee80_radius_mm``,
        ``fraction_off_grid``.
    psf_stderr : array (rows, cols) or None
        Per-pixel standard error of ``psf`` (batch means), None if deterministic.
    metadata : dict
        Free-form provenance (lens name, focus, sampler, sampling report, ...).
    """

    psf: np.ndarray
    grid: ImageGrid
    kind: str
    wavelengths_nm: tuple[float, ...]
    weights: tuple[float, ...]
    field_xy: tuple[float, float] = (0.0, 0.0)
    field_kind: str = "angle"
    reference_mm: tuple[float, float] = (0.0, 0.0)
    samples: int = 0
    seconds: float = 0.0
    seed: int | None = None
    batches: int = 0
    estimates: dict[str, Estimate] = field(default_factory=dict)
    psf_stderr: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in PSF_KINDS:
            raise LensrtError(f"unknown PSF kind {self.kind!r}", hint=f"use one of {', '.join(PSF_KINDS)}")
        if np.shape(self.psf) != self.grid.shape:
            raise LensrtError(f"PSF shape {np.shape(self.psf)} does not match its grid {self.grid.shape}")
        if len(self.wavelengths_nm) != len(self.weights):
            raise LensrtError("one weight per wavelength")

    @property
    def binned(self) -> bool:
        """True for histograms (values are bin means), False for point samples."""
        return self.kind == "geometric"

    @property
    def energy_on_grid(self) -> float:
        return float(np.sum(self.psf) * self.grid.pixel_area_mm2)

    def to_dict(self, include_arrays: bool = False) -> dict:
        """JSON-ready summary (arrays only if asked: they belong in EXR files)."""
        out = {"kind": self.kind, "grid": self.grid.to_dict(), "wavelengths_nm": list(self.wavelengths_nm),
               "weights": list(self.weights), "field_xy": list(self.field_xy), "field_kind": self.field_kind,
               "reference_mm": list(self.reference_mm), "samples": self.samples, "seconds": self.seconds,
               "seed": self.seed, "batches": self.batches, "energy_on_grid": self.energy_on_grid,
               "estimates": {k: v.to_dict() for k, v in self.estimates.items()}, "metadata": self.metadata}
        if include_arrays:
            out["psf"] = np.asarray(self.psf).tolist()
        return out


# -- reference accumulation (what the stream kernel does) ---------------------------------------
def _batch_index(batch: np.ndarray | None, n: int, n_batches: int) -> np.ndarray:
    if batch is None:
        return (np.arange(n) * n_batches) // max(n, 1)
    b = np.asarray(batch, dtype=np.int64)
    if b.shape != (n,) or (n and (b.min() < 0 or b.max() >= n_batches)):
        raise LensrtError("batch indices must be one per ray, in [0, n_batches)")
    return b


def histogram_rays(x_mm: np.ndarray, y_mm: np.ndarray, weight: np.ndarray | None, grid: ImageGrid,
                   n_batches: int, batch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-batch histograms (B, rows, cols) of ray weight on ``grid`` and the off-grid weight (B,).

    ``batch`` gives each ray's batch; by default the rays are split into
    ``n_batches`` consecutive equal blocks.
    """
    x, y = np.ravel(np.asarray(x_mm, dtype=np.float64)), np.ravel(np.asarray(y_mm, dtype=np.float64))
    w = np.ones_like(x) if weight is None else np.ravel(np.asarray(weight, dtype=np.float64))
    b = _batch_index(batch, x.size, n_batches)
    row, col = grid.pixel_of(x, y)
    r, c = np.floor(row + 0.5).astype(np.int64), np.floor(col + 0.5).astype(np.int64)
    rows, cols = grid.shape
    on = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
    flat = (b[on] * rows + r[on]) * cols + c[on]
    hist = np.bincount(flat, weights=w[on], minlength=n_batches * rows * cols).reshape(n_batches, rows, cols)
    off = np.bincount(b[~on], weights=w[~on], minlength=n_batches)
    return hist, off


def ray_moment_sums(x_mm: np.ndarray, y_mm: np.ndarray, weight: np.ndarray | None,
                    reference_mm: tuple[float, float], n_batches: int, batch: np.ndarray | None = None) -> np.ndarray:
    """Per-batch sums (B, 6) in the order of :data:`MOMENT_KEYS`, positions relative to ``reference_mm``."""
    x = np.ravel(np.asarray(x_mm, dtype=np.float64)) - reference_mm[0]
    y = np.ravel(np.asarray(y_mm, dtype=np.float64)) - reference_mm[1]
    w = np.ones_like(x) if weight is None else np.ravel(np.asarray(weight, dtype=np.float64))
    b = _batch_index(batch, x.size, n_batches)
    cols = [w, w * x, w * y, w * x * x, w * x * y, w * y * y]
    return np.stack([np.bincount(b, weights=v, minlength=n_batches) for v in cols], axis=1)


# -- statistics -------------------------------------------------------------------------------
def _moments(s: np.ndarray) -> tuple[float, float, float, float, float]:
    w = s[0]
    if not w > 0:
        raise LensrtError("no rays reached the image plane")
    cx, cy = s[1] / w, s[2] / w
    return cx, cy, s[3] / w - cx * cx, s[4] / w - cx * cy, s[5] / w - cy * cy


def _directional_rms(s: np.ndarray, angle: float) -> float:
    _, _, vxx, vxy, vyy = _moments(s)
    c, d = math.cos(angle), math.sin(angle)
    return math.sqrt(max(vxx * c * c + 2 * vxy * c * d + vyy * d * d, 0.0))


def _geometric_radius(h: np.ndarray, grid: ImageGrid) -> float:
    if not h.sum() > 0:
        return 0.0
    cx, cy = centroid_mm(h, grid)
    gx, gy = grid.mesh_mm()
    return float(np.hypot(gx - cx, gy - cy)[h > 0].max())


def _ee_radius_jackknife(h: np.ndarray, off: np.ndarray, grid: ImageGrid, frac: float) -> tuple[float, float]:
    """Radius holding ``frac`` of the landed light (on and off the grid) about the centroid, jackknifed.

    The full-data radius r comes from bisection. Each leave-one-batch-out
    radius is its first-order (linearised) value: with E(r, c) the light
    within radius r of centre c, r_(-i) = r + [frac T_(-i) - E_(-i)(r, c)
    - grad_c E . (c_(-i) - c)] / (dE/dr), where E_(-i) is the full sum less
    batch i's light inside the same circle (one pixel-fraction vector for all
    batches) and c_(-i) the leave-one-out centroid -- so the centroid's own
    scatter is part of the error, as in a full recomputation. The jackknife is
    itself a first-order method (its replicates differ by O(1/B)), so this
    costs it nothing in accuracy and makes it independent of the batch count.
    """
    from .energy import Rings
    area = grid.pixel_area_mm2
    nb = h.shape[0]
    flat_b = h.reshape(nb, -1)
    tot_b = flat_b.sum(axis=1) + off
    total = float(tot_b.sum())
    H = flat_b.sum(axis=0)
    psf = H.reshape(grid.shape) / (total * area)
    gx, gy = (v.ravel() for v in grid.mesh_mm())
    c = (float(H @ gx / H.sum()), float(H @ gy / H.sum()))
    rings = Rings(grid, c, 4)
    full = radius_for_energy(psf, grid, frac, relative=False, supersample=4, tol_mm=1e-3 * grid.pitch_mm)
    w = rings.fractions(full)
    d = 0.25 * grid.pitch_mm
    lo = max(full - d, 0.0)
    dedr = float(H @ (rings.fractions(full + d) - rings.fractions(lo))) / (full + d - lo)
    grad = []
    for dx, dy in ((d, 0.0), (0.0, d)):
        plus = Rings(grid, (c[0] + dx, c[1] + dy), 4).fractions(full)
        minus = Rings(grid, (c[0] - dx, c[1] - dy), 4).fractions(full)
        grad.append(float(H @ (plus - minus)) / (2 * d))
    if not dedr > 0:
        return full, 0.0
    e_full = float(H @ w)
    e_b = flat_b @ w
    sx_b, sy_b, s_b = flat_b @ gx, flat_b @ gy, flat_b.sum(axis=1)
    hs = H.sum()
    loo = np.empty(nb)
    for i in range(nb):
        rest = hs - s_b[i]
        if rest <= 0:
            loo[i] = full
            continue
        cx = (H @ gx - sx_b[i]) / rest
        cy = (H @ gy - sy_b[i]) / rest
        e = e_full - e_b[i] + grad[0] * (cx - c[0]) + grad[1] * (cy - c[1])
        loo[i] = full + (frac * (total - tot_b[i]) - e) / dedr
    se = math.sqrt((nb - 1) / nb * float(np.sum((loo - loo.mean()) ** 2)))
    return full, se


def geometric_psf(hist: np.ndarray, grid: ImageGrid, *, moment_sums: np.ndarray | None = None,
                  off_grid: np.ndarray | None = None, reference_mm: tuple[float, float] = (0.0, 0.0),
                  wavelengths_nm: Sequence[float] = (), weights: Sequence[float] | None = None,
                  field_xy: tuple[float, float] = (0.0, 0.0), field_kind: str = "angle",
                  samples: int = 0, seconds: float = 0.0, seed: int | None = None,
                  ee_fractions: Sequence[float] = (0.5, 0.8), metadata: dict | None = None,
                  sums: FieldSums | None = None) -> PsfResult:
    """A geometric :class:`PsfResult` from per-batch histograms and (optionally) moment sums.

    Parameters
    ----------
    hist : array (B, rows, cols)
        Per-batch histograms of landed ray weight on ``grid`` (B >= 2).
    moment_sums : array (B, 6), optional
        Exact per-batch moment sums (:data:`MOMENT_KEYS`, relative to
        ``reference_mm``). Without them the moments come from the histogram
        (bin centres, Sheppard's pitch^2/12 correction; light off the grid is
        missed).
    off_grid : array (B,), optional
        Per-batch weight that landed outside the grid.
    samples, seconds, seed
        Rays traced (all batches), wall-clock seconds, seed -- carried into
        every estimate.
    sums : FieldSums, optional
        The histograms' per-batch sums, made for many fields at once by
        :func:`lensrt.analysis.psf.bulk.field_sums` (the same numbers to 1e-12
        relative; without them they are computed here, the reference path).

    Notes
    -----
    Normalisation: the PSF is divided by the total landed weight (on and off
    the grid), so it has unit volume when the grid holds all the light.
    Standard errors: the jackknife over batches for every non-linear
    quantity (:func:`lensrt.stats.jackknife`), batch means for the per-pixel
    error and the off-grid fraction. Encircled-energy radii (``ee50_radius_mm``
    for ``ee_fractions`` = 0.5, ...) are about the centroid and count fractions
    of all landed light; one that the grid cannot hold is left out and named
    in ``metadata["not_estimated"]``. The geometric radius (the farthest lit
    bin from the centroid, good to half a bin diagonal) is an extreme value:
    its jackknife error is indicative only.
    """
    h = np.asarray(hist, dtype=np.float64)
    if h.ndim != 3 or h.shape[1:] != grid.shape or h.shape[0] < 2:
        raise LensrtError(f"histograms must be (batches >= 2, {grid.shape[0]}, {grid.shape[1]}), not {h.shape}")
    nb = h.shape[0]
    off = np.zeros(nb) if off_grid is None else np.asarray(off_grid, dtype=np.float64)
    landed_b = (h.sum(axis=(1, 2)) if sums is None else sums.s_b) + off
    total = float(landed_b.sum())
    if not total > 0:
        raise LensrtError("no rays reached the image plane: no PSF",
                          hint="check the field point, focus and aperture (all rays vignetted?)")
    area = grid.pixel_area_mm2
    if sums is None:
        psf = h.sum(axis=0) / (total * area)
        _, pix_se = batch_means(h * (nb / (total * area)))
    else:
        psf, pix_se = sums.H.reshape(grid.shape) / (total * area), sums.psf_stderr
    jk = f"jackknife over {nb} batches"

    def est(value: Any, se: Any, unit: str, method: str = jk) -> Estimate:
        return Estimate(value, se, int(samples), float(seconds), method, unit)

    ests: dict[str, Estimate] = {}
    ref = np.asarray(reference_mm, dtype=np.float64)
    tang = tangential_angle_rad(tuple(ref))
    if moment_sums is not None:
        from .jackknife import moment_jackknife
        s = np.asarray(moment_sums, dtype=np.float64)
        if s.shape != (nb, len(MOMENT_KEYS)):
            raise LensrtError(f"moment sums must be ({nb}, {len(MOMENT_KEYS)}), not {s.shape}")
        if not s[:, 0].sum() > 0:
            raise LensrtError("no rays reached the image plane")
        for name, (v, se) in moment_jackknife(s, ref, tang).items():
            ests[name] = est(v, se, "mm")
    else:
        from .energy import second_moments_mm2

        def hm(t: np.ndarray, angle: float | None = None) -> float:
            vxx, vxy, vyy = second_moments_mm2(t, grid, sheppard=True)
            if angle is None:
                return math.sqrt(max(vxx + vyy, 0.0))
            c, d = math.cos(angle), math.sin(angle)
            return math.sqrt(max(vxx * c * c + 2 * vxy * c * d + vyy * d * d, 0.0))
        stat = {"centroid_x_mm": lambda t: centroid_mm(t, grid)[0],
                "centroid_y_mm": lambda t: centroid_mm(t, grid)[1],
                "rms_radius_mm": hm, "rms_tangential_mm": lambda t: hm(t, tang),
                "rms_sagittal_mm": lambda t: hm(t, tang + 0.5 * math.pi)}
        for name, fn in stat.items():
            ests[name] = est(*jackknife(h, fn), "mm", jk + " (from the histogram)")
    from .jackknife import ee_radii_jackknife, geometric_radius_jackknife
    ests["geometric_radius_mm"] = est(*geometric_radius_jackknife(h, grid, sums), "mm",
                                      jk + " (extreme value: indicative)")
    skipped = []
    ee = ee_radii_jackknife(h, off, grid, ee_fractions, sums)
    for frac in ee_fractions:
        key = f"ee{int(round(100 * frac))}_radius_mm"
        if frac not in ee:
            skipped.append(key)
            continue
        ests[key] = est(*ee[frac], "mm")
    fo, fo_se = batch_means(off / np.where(landed_b > 0, landed_b, 1.0))
    ests["fraction_off_grid"] = est(float(fo), float(fo_se), "", f"batch means over {nb} batches")
    meta = dict(metadata or {})
    if skipped:
        meta["not_estimated"] = {k: "less of the light than that fell on the grid" for k in skipped}
    w = np.ones(len(wavelengths_nm)) if weights is None else np.asarray(weights, dtype=np.float64)
    return PsfResult(psf, grid, "geometric", tuple(float(v) for v in wavelengths_nm),
                     tuple(float(v) for v in (w / w.sum() if w.size else w)), tuple(field_xy), field_kind,
                     tuple(float(v) for v in ref), int(samples), float(seconds), seed, nb, ests, pix_se, meta)


def diffraction_result(psf: np.ndarray, grid: ImageGrid, kind: str, *, wavelengths_nm: Sequence[float],
                       weights: Sequence[float] | None = None, reference_mm: tuple[float, float] = (0.0, 0.0),
                       field_xy: tuple[float, float] = (0.0, 0.0), field_kind: str = "angle",
                       samples: int = 0, seconds: float = 0.0, ee_fractions: Sequence[float] = (0.5, 0.8),
                       metadata: dict | None = None) -> PsfResult:
    """Wrap a deterministic diffraction PSF (from :mod:`~lensrt.analysis.wave.propagation`) as a :class:`PsfResult`.

    Its estimates carry a zero standard error (no sampling noise; the
    discretisation error is described by the sampling report, which belongs
    in ``metadata["sampling"]``). Encircled-energy radii count fractions of
    the whole light (unit volume). The RMS radius of a hard-edged pupil's PSF
    depends on the window: its 1/r^3 wings make the second moment grow like
    log(window) -- compare RMS radii of diffraction PSFs on equal windows
    only, and prefer the encircled-energy radii.
    """
    from .energy import second_moments_mm2

    a = np.asarray(psf, dtype=np.float64)
    cx, cy = centroid_mm(a, grid)
    vxx, vxy, vyy = second_moments_mm2(a, grid, sheppard=False)
    tang = tangential_angle_rad(reference_mm)
    vals = {"centroid_x_mm": cx, "centroid_y_mm": cy, "rms_radius_mm": math.sqrt(max(vxx + vyy, 0.0))}
    for name, ang in (("rms_tangential_mm", tang), ("rms_sagittal_mm", tang + 0.5 * math.pi)):
        c, d = math.cos(ang), math.sin(ang)
        vals[name] = math.sqrt(max(vxx * c * c + 2 * vxy * c * d + vyy * d * d, 0.0))
    for frac in ee_fractions:
        if a.sum() * grid.pixel_area_mm2 >= frac:  # of the whole light (unit volume)
            vals[f"ee{int(round(100 * frac))}_radius_mm"] = radius_for_energy(a, grid, frac, relative=False,
                                                                              points=True)
    ests = {k: Estimate(v, 0.0, int(samples), float(seconds), "deterministic", "mm") for k, v in vals.items()}
    w = np.ones(len(wavelengths_nm)) if weights is None else np.asarray(weights, dtype=np.float64)
    return PsfResult(a, grid, kind, tuple(float(v) for v in wavelengths_nm), tuple(float(v) for v in w / w.sum()),
                     tuple(field_xy), field_kind, tuple(float(v) for v in reference_mm), int(samples),
                     float(seconds), None, 0, ests, None, dict(metadata or {}))
