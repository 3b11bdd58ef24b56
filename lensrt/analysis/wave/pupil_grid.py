"""Pupil grids: coordinates, aperture shapes, Zernike fits, and scattered real-ray data -> grid.

Pupil coordinates
-----------------
A pupil grid has ``n`` x ``n`` cells over the normalised pupil square
[-1, 1]^2, cell centres ``p = (k + 1/2 - n/2) * 2/n``. Arrays are (row, col)
like images: column -> ``px``, row 0 at the top -> ``py = +1`` side.

``p`` is a *position* in the exit pupil (Zemax's Px, Py), measured in the
direction-cosine space of the converging beam (the Debye picture): a ray with
image-space direction cosines (L, M) belongs to

    px = -(L - L_chief) / NA,   py = -(M - M_chief) / NA,

where NA = 1 / (2 N_w) is the image-space numerical aperture that sets the
grid's scale (:func:`pupil_coordinates_from_directions`). The minus sign is
there because a ray from the +x side of the pupil travels toward -x. Using
*global* direction cosines (not positions on a tilted exit pupil) makes the
Fourier transform land the PSF on the sensor plane itself (z = const), with
the off-axis foreshortening of the pupil carried by the amplitude's shape.

OPD sign
--------
``opd_mm`` is the optical path of a ray from the object point to the reference
sphere (centred on the reference image point, usually the chief ray's) minus
that of the chief ray; positive = longer path. With this sign a ray's
transverse aberration is ``+ dW/dp / NA`` (mm), so a tilt ``W = a * px``
moves the PSF toward +x.
"""
from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Iris

if TYPE_CHECKING:
    from .ray_mesh import GridLinear

__all__ = ["pupil_coordinates", "aperture_mask", "aperture_fine_mask", "clear_fraction", "circular_aperture", "iris_aperture",
           "aperture_from_iris", "vignetted_aperture", "noll_to_nm", "zernike", "fit_zernike",
           "zernike_surface", "pupil_coordinates_from_directions", "enclosing_na", "defocus_opd_mm",
           "pupil_from_rays", "TriLinear"]


def pupil_coordinates(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised pupil positions (px, py) of the cell centres of an ``n`` x ``n`` grid, row 0 at +py."""
    if n < 2:
        raise LensrtError(f"a pupil grid needs at least 2 x 2 cells, not {n}")
    u = (np.arange(n) + 0.5 - 0.5 * n) * (2.0 / n)
    return np.meshgrid(u, -u)


def aperture_fine_mask(n: int, inside: Callable[[np.ndarray, np.ndarray], np.ndarray],
                       supersample: int = 4) -> np.ndarray:
    """The shape on the ``(n s) x (n s)`` grid of sub-cells (s = ``supersample``): True where a sub-cell's
    centre is clear -- the hard edge a pupil's OTF is taken from (:attr:`PupilFunction.fine_mask`)."""
    s = max(1, int(supersample))
    px, py = pupil_coordinates(n * s)
    return np.asarray(inside(px, py), dtype=bool)


def clear_fraction(fine_mask: np.ndarray, n: int) -> np.ndarray:
    """Clear fraction of each of the ``n`` x ``n`` cells of a fine mask (row r of the fine grid is in cell r // s)."""
    s = fine_mask.shape[0] // n
    return np.asarray(fine_mask, dtype=np.float64).reshape(n, s, n, s).mean(axis=(1, 3))


def aperture_mask(n: int, inside: Callable[[np.ndarray, np.ndarray], np.ndarray], supersample: int = 4) -> np.ndarray:
    """Fraction of each pupil cell inside a shape (anti-aliased by ``supersample**2`` points per cell).

    ``inside(px, py)`` returns a boolean array: True where a normalised pupil
    point is clear.
    """
    return clear_fraction(aperture_fine_mask(n, inside, supersample), n)


def circular_aperture(n: int, obstruction_ratio: float = 0.0, supersample: int = 4) -> np.ndarray:
    """Clear circle of radius 1 (with an optional central obstruction) on an ``n`` x ``n`` grid."""
    return iris_aperture(n, 0, obstruction_ratio=obstruction_ratio, supersample=supersample)


def iris_aperture(n: int, blades: int, rotation_rad: float = 0.0, roundness: float = 0.0,
                  obstruction_ratio: float = 0.0, supersample: int = 4) -> np.ndarray:
    """An iris as in :class:`lensrt.prescription.model.Iris`: regular ``blades``-gon inscribed in the unit circle.

    A vertex lies at ``rotation_rad`` from +x; ``roundness`` in [0, 1] blends
    each straight blade toward the circle; ``blades = 0`` is the circle.
    """
    iris = Iris(blades=int(blades), rotation_rad=float(rotation_rad), roundness=float(roundness),
                obstruction_ratio=float(obstruction_ratio))
    return aperture_from_iris(n, iris, supersample)


def _iris_inside(iris: Iris) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    def inside(px: np.ndarray, py: np.ndarray) -> np.ndarray:
        r = np.hypot(px, py)
        if iris.blades == 0:
            edge = np.ones_like(r)
        else:
            sector = 2.0 * math.pi / iris.blades
            phi = np.mod(np.arctan2(py, px) - iris.rotation_rad, sector)
            straight = math.cos(0.5 * sector) / np.cos(phi - 0.5 * sector)
            edge = straight + iris.roundness * (1.0 - straight)
        return (r <= edge) & (r >= iris.obstruction_ratio)
    return inside


def aperture_from_iris(n: int, iris: Iris, supersample: int = 4) -> np.ndarray:
    """Amplitude mask of a lens's :class:`Iris` on an ``n`` x ``n`` pupil grid."""
    return aperture_mask(n, _iris_inside(iris), supersample)


def vignetted_aperture(n: int, circles: Sequence[tuple[float, float, float]], iris: Iris | None = None,
                       supersample: int = 4) -> np.ndarray:
    """The iris (default: the unit circle) cut by further circles: the classic vignetting model.

    Each circle ``(cx, cy, radius)`` is in normalised pupil units: the image
    of a lens rim seen from the field point (e.g. ``(0, 0.4, 1)`` clips the
    lower part of the pupil, giving the cat's-eye shape).
    """
    base = _iris_inside(iris or Iris())

    def inside(px: np.ndarray, py: np.ndarray) -> np.ndarray:
        ok = base(px, py)
        for cx, cy, rad in circles:
            ok &= (px - cx) ** 2 + (py - cy) ** 2 <= rad ** 2
        return ok
    return aperture_mask(n, inside, supersample)


# -- Zernike polynomials (Noll 1976 ordering and normalisation) --------------------------------
def noll_to_nm(j: int) -> tuple[int, int]:
    """Noll index j >= 1 -> (radial order n, azimuthal m); m > 0 is cos(m theta), m < 0 sin."""
    if j < 1:
        raise ValueError("Noll indices start at 1")
    n, j1 = 0, j - 1
    while j1 > n:
        n += 1
        j1 -= n
    m = (-1) ** j * ((n % 2) + 2 * int((j1 + ((n + 1) % 2)) / 2))
    return n, m


def zernike(j: int, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Noll-normalised Zernike polynomial Z_j (unit RMS over the unit disc)."""
    n, m = noll_to_nm(j)
    ma = abs(m)
    radial = np.zeros_like(np.asarray(rho, dtype=np.float64))
    for k in range((n - ma) // 2 + 1):
        c = (-1) ** k * math.factorial(n - k) / (
            math.factorial(k) * math.factorial((n + ma) // 2 - k) * math.factorial((n - ma) // 2 - k))
        radial = radial + c * rho ** (n - 2 * k)
    if m == 0:
        return math.sqrt(n + 1) * radial
    ang = np.cos(ma * theta) if m > 0 else np.sin(ma * theta)
    return math.sqrt(2 * (n + 1)) * radial * ang


def _design(px: np.ndarray, py: np.ndarray, n_terms: int) -> np.ndarray:
    rho, theta = np.hypot(px, py), np.arctan2(py, px)
    return np.stack([zernike(j, rho, theta) for j in range(1, n_terms + 1)], axis=-1)


def fit_zernike(px: np.ndarray, py: np.ndarray, values: np.ndarray, n_terms: int = 36) -> np.ndarray:
    """Least-squares Noll-Zernike coefficients Z_1..Z_n_terms of values sampled at (px, py)."""
    px, py, v = (np.ravel(np.asarray(a, dtype=np.float64)) for a in (px, py, values))
    if px.size < n_terms:
        raise LensrtError(f"{px.size} pupil samples cannot determine {n_terms} Zernike terms",
                          hint="trace more pupil rays or fit fewer terms")
    coef, *_ = np.linalg.lstsq(_design(px, py, n_terms), v, rcond=None)
    return coef


def zernike_surface(coefficients: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Evaluate sum_j c_j Z_j at pupil positions (px, py)."""
    c = np.asarray(coefficients, dtype=np.float64)
    return _design(np.asarray(px, dtype=np.float64), np.asarray(py, dtype=np.float64), c.size) @ c


# -- from real rays ----------------------------------------------------------------------------
def pupil_coordinates_from_directions(directions: np.ndarray, chief_direction: Sequence[float],
                                      na: float) -> tuple[np.ndarray, np.ndarray]:
    """Normalised pupil positions of rays from their image-space unit directions (see module docstring).

    Parameters
    ----------
    directions : array (n, 3)
        Unit direction of each ray after the last surface.
    chief_direction : (3,)
        Unit direction of the chief ray.
    na : float
        Image-space numerical aperture that scales the grid, e.g. ``1 / (2 N_w)``.
    """
    d = np.asarray(directions, dtype=np.float64)
    c = np.asarray(chief_direction, dtype=np.float64)
    return -(d[:, 0] - c[0]) / na, -(d[:, 1] - c[1]) / na


def enclosing_na(directions: np.ndarray, chief_direction: Sequence[float], valid: np.ndarray | None = None,
                 margin: float = 0.02) -> float:
    """The smallest grid scale NA that keeps every valid ray inside |px|, |py| <= 1, plus ``margin``.

    Use it when the real pupil is larger than the paraxial one (pupil
    aberrations, off-axis pupil distortion); the PSF pitch then follows from
    it (lambda / (2 Q NA)).
    """
    d = np.asarray(directions, dtype=np.float64)
    ok = np.ones(len(d), dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if not ok.any():
        raise LensrtError("no valid rays: cannot size the pupil grid")
    c = np.asarray(chief_direction, dtype=np.float64)
    return float(np.max(np.abs(d[ok, :2] - c[:2])) * (1.0 + margin))


def defocus_opd_mm(px: np.ndarray, py: np.ndarray, na: float, dz_mm: float,
                   chief_direction: Sequence[float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Exact OPD (mm) that moves the observation plane by ``dz_mm`` along +z: dz (N(p) - N_chief).

    N is the z direction cosine of the ray through pupil position p (Debye
    picture); no paraxial rho^2 approximation, so it holds at any aperture.
    """
    L = chief_direction[0] - na * np.asarray(px, dtype=np.float64)
    M = chief_direction[1] - na * np.asarray(py, dtype=np.float64)
    N = np.sqrt(np.clip(1.0 - L * L - M * M, 0.0, None))
    return dz_mm * (N - chief_direction[2])


class TriLinear:
    """Piecewise-linear interpolation on the Delaunay triangulation of scattered points.

    Built on ``matplotlib.tri`` (qhull's triangulation, C++ plane coefficients):
    scipy's ``LinearNDInterpolator`` computes a barycentric transform per
    triangle through LAPACK, which behind a multi-threaded BLAS costs seconds for
    ten thousand triangles. Near-degenerate triangles (area below 1e-6 of the
    median, e.g. from collinear points on the hull of a regular ray grid) are
    masked. Points are located by a bucket grid
    (:class:`~lensrt.analysis.wave.point_location.BucketLocator`, built once per
    triangulation) rather than matplotlib's trapezoid map, which took as long to
    build as the triangulation; the values are matplotlib's ``LinearTriInterpolator``'s
    (the same plane coefficients and expression). ``interp(values, qx, qy, fill)``
    returns ``fill`` outside the hull. :meth:`of` reuses the triangulation of points already
    triangulated (a pupil resampled at a finer grid triangulates the same rays).
    """

    _recent: "dict[bytes, TriLinear]" = {}
    _lock = threading.Lock()
    #: triangulations :meth:`of` keeps (the most recent ones)
    KEEP = 8

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray) -> "TriLinear":
        """``TriLinear(x, y)``, the same object again for the same points (by content)."""
        import hashlib
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        key = hashlib.blake2b(x.tobytes() + b"|" + y.tobytes(), digest_size=20).digest()
        with cls._lock:
            hit = cls._recent.get(key)
        if hit is not None:
            return hit
        made = cls(x, y)
        with cls._lock:
            cls._recent[key] = made
            while len(cls._recent) > cls.KEEP:
                cls._recent.pop(next(iter(cls._recent)))
        return made

    def __init__(self, x: np.ndarray, y: np.ndarray) -> None:
        from matplotlib.tri import Triangulation
        try:
            tr = Triangulation(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        except (RuntimeError, ValueError) as err:
            raise LensrtError(f"cannot triangulate the pupil rays: {err}",
                              hint="trace more pupil rays (they may all lie on a line)") from None
        xt, yt = tr.x[tr.triangles], tr.y[tr.triangles]
        area = np.abs((xt[:, 1] - xt[:, 0]) * (yt[:, 2] - yt[:, 0]) - (xt[:, 2] - xt[:, 0]) * (yt[:, 1] - yt[:, 0]))
        tr.set_mask(area <= 1e-6 * np.median(area))
        self.tri = tr
        self._locator = None

    def find(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """The (unmasked) triangle holding each point of (qx, qy), flattened; -1 outside."""
        if self._locator is None:
            from .point_location import BucketLocator
            self._locator = BucketLocator(self.tri.x, self.tri.y, self.tri.triangles, self.tri.mask)
        return self._locator.find(qx, qy)

    def interp(self, values: np.ndarray, qx: np.ndarray, qy: np.ndarray, fill: float = np.nan) -> np.ndarray:
        qx = np.asarray(qx, dtype=np.float64)
        qy = np.asarray(qy, dtype=np.float64)
        coef = self.tri.calculate_plane_coefficients(np.asarray(values, dtype=np.float64))
        k = self.find(qx, qy)
        x, y = np.ravel(qx), np.ravel(qy)
        out = np.full(x.size, np.nan)
        ok = k >= 0
        t = k[ok]
        out[ok] = coef[t, 0] * x[ok] + coef[t, 1] * y[ok] + coef[t, 2]
        out[~np.isfinite(out)] = fill
        return out.reshape(qx.shape)


def _extrapolate(pts: np.ndarray, values: np.ndarray, qx: np.ndarray, qy: np.ndarray, k: int = 16) -> np.ndarray:
    """Local least-squares quadratic through the k nearest rays, evaluated at (qx, qy).

    Edge cells of a pupil often lie just beyond the outermost valid ray,
    where the wavefront is steepest: a nearest-ray value would be off by
    half a ray spacing times the slope. All cells are solved in one batched
    call (normal equations in coordinates scaled by each cell's neighbourhood).
    """
    from scipy.spatial import cKDTree

    k = min(k, len(values))
    _, idx = cKDTree(pts).query(np.column_stack([qx, qy]), k=k)
    idx = np.asarray(idx).reshape(len(qx), k)
    dx, dy = pts[idx, 0] - np.asarray(qx)[:, None], pts[idx, 1] - np.asarray(qy)[:, None]
    scale = np.maximum(np.sqrt(np.mean(dx * dx + dy * dy, axis=1)), 1e-300)[:, None]
    u, v = dx / scale, dy / scale
    one = np.ones_like(u)
    cols = [one, u, v, u * u, u * v, v * v] if k >= 6 else [one, u, v][:min(3, k)]
    basis = np.stack(cols, axis=2)  # (cells, k, terms)
    ata = np.einsum("nki,nkj->nij", basis, basis)
    atb = np.einsum("nki,nk->ni", basis, values[idx])
    ridge = 1e-12 * np.trace(ata, axis1=1, axis2=2)[:, None, None] * np.eye(basis.shape[2])
    coef = np.linalg.solve(ata + ridge, atb[..., None])[..., 0]
    return coef[:, 0]


def _valid_ray_interpolant(px: np.ndarray, py: np.ndarray, ok: np.ndarray,
                           ray_grid: tuple[int, np.ndarray] | GridLinear | None, gx: np.ndarray,
                           gy: np.ndarray) -> Callable[..., np.ndarray]:
    """``lin(values, fill=nan, every=False)``: values on the valid rays (all rays with ``every``) interpolated
    linearly at the grid points (gx, gy) -- on the valid rays' Delaunay triangulation (every ray's, with
    ``every``), or along the ray grid (:class:`~lensrt.analysis.wave.ray_mesh.GridLinear`, one point location
    for all)."""
    if ray_grid is None:
        def lin(values: np.ndarray, fill: float = np.nan, every: bool = False) -> np.ndarray:
            tri = TriLinear(px, py) if every else TriLinear.of(px[ok], py[ok])
            return tri.interp(values, gx, gy, fill=fill)
        return lin
    from .ray_mesh import GridLinear
    if isinstance(ray_grid, GridLinear):
        mesh = ray_grid
        if mesh.index.size != px.size:
            raise LensrtError(f"a ray mesh of {mesh.index.size} rays for {px.size} rays")
    else:
        index = np.ravel(np.asarray(ray_grid[1], dtype=np.int64))
        if index.size != px.size:
            raise LensrtError(f"{index.size} ray grid indices for {px.size} rays")
        mesh = GridLinear.of(int(ray_grid[0]), index, px, py)

    def lin(values: np.ndarray, fill: float = np.nan, every: bool = False) -> np.ndarray:
        if every:
            return mesh.interp(values, gx, gy, fill=fill)
        full = np.zeros(px.size)
        full[ok] = values
        return mesh.interp(full, gx, gy, fill=fill, use=ok)
    return lin


def pupil_from_rays(px: np.ndarray, py: np.ndarray, opd_mm: np.ndarray, valid: np.ndarray, n: int, *,
                    method: str = "linear", amplitude: np.ndarray | None = None,
                    aperture: np.ndarray | None = None, n_zernike: int = 36,
                    ray_grid: tuple[int, np.ndarray] | GridLinear | None = None
                    ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Grid scattered real-ray pupil data: the glue from the tracer's *store* output to the FFT.

    Parameters
    ----------
    px, py : arrays (m,)
        Normalised pupil positions of the traced rays (all of them, valid or not),
        e.g. from :func:`pupil_coordinates_from_directions`.
    opd_mm : array (m,)
        OPD of each ray (mm, sign in the module docstring); ignored where not valid.
    valid : bool array (m,)
        Ray reached the image (status OK); invalid rays mark vignetted pupil parts.
    n : int
        Pupil grid size.
    method : {"linear", "zernike"}
        ``"linear"`` (default): piecewise-linear interpolation on the Delaunay
        triangulation of the valid rays (:class:`TriLinear`). Exact at
        every ray, follows any vignetted outline, needs no order to be chosen;
        its error is O(h^2 |W''|) for a ray spacing h, and a dense ray set makes
        it converge to the true wavefront. Lit cells just outside the valid
        rays' hull get a local quadratic fit to the nearest 16 rays. ``"zernike"``: least-squares fit of
        ``n_zernike`` Noll terms -- smooth, robust to sparse or noisy rays, and
        the coefficients come back in the info dict; but a truncated series
        misses wavefronts with steep edge structure (fast lenses near full
        aperture), so it is the second choice.
    amplitude : array (m,), optional
        Per-ray amplitude (transmission, apodisation); interpolated like the OPD.
    aperture : array (n, n), optional
        Known amplitude mask (e.g. :func:`aperture_from_iris`). Without it the
        mask comes from the rays: the validity of the rays, interpolated
        linearly and cut at 1/2 (edge placed midway between valid and invalid rays).
    ray_grid : (m, index) or GridLinear, optional
        The rays were traced on an m x m grid, ray k at flat index ``index[k]``: the linear interpolation then
        runs on the grid's cells cut in two (:class:`~lensrt.analysis.wave.ray_mesh.GridLinear`) rather than on
        a Delaunay triangulation -- the same interpolant but for ties and the hull's slivers, without qhull.
        A ``GridLinear`` given here must be the one of these rays (``GridLinear(m, index, px, py)``).

    Returns
    -------
    amplitude (n, n), opd_mm (n, n), info dict
        ``info`` has the method, rays used, RMS fit residual (mm) at the rays and,
        for ``"zernike"``, the coefficients (mm).
    """
    from scipy.interpolate import NearestNDInterpolator

    px, py, w = (np.ravel(np.asarray(a, dtype=np.float64)) for a in (px, py, opd_mm))
    ok = np.ravel(np.asarray(valid, dtype=bool))
    if not (px.size == py.size == w.size == ok.size):
        raise LensrtError("pupil ray arrays px, py, opd_mm and valid must have the same length")
    ok &= np.isfinite(w) & np.isfinite(px) & np.isfinite(py)
    if ok.sum() < 3:
        raise LensrtError(f"only {int(ok.sum())} valid rays reached the image: cannot build a pupil function",
                          hint="check the field point and the aperture; trace more pupil rays")
    outside = int(np.sum(ok & ((np.abs(px) > 1) | (np.abs(py) > 1))))
    if outside:
        raise LensrtError(f"{outside} valid rays lie outside the pupil grid (|px| or |py| > 1)",
                          hint="scale the pupil coordinates with a larger NA, e.g. enclosing_na(...)")
    gx, gy = pupil_coordinates(n)
    pts = np.column_stack([px[ok], py[ok]])
    lin = _valid_ray_interpolant(px, py, ok, ray_grid, gx, gy)
    info: dict = {"method": method, "rays": int(px.size), "valid_rays": int(ok.sum())}
    if aperture is None:
        frac = lin(ok.astype(np.float64), 0.0, every=True)
        mask = (frac >= 0.5).astype(np.float64)
    else:
        mask = np.asarray(aperture, dtype=np.float64)
        if mask.shape != (n, n):
            raise LensrtError(f"aperture mask has shape {mask.shape}, expected ({n}, {n})")
    if method == "linear":
        grid_w = lin(w[ok])
        hole = ~np.isfinite(grid_w) & (mask > 0)  # lit edge cells outside the valid rays' hull
        if hole.any():
            grid_w[hole] = _extrapolate(pts, w[ok], gx[hole], gy[hole])
        grid_w = np.where(np.isfinite(grid_w), grid_w, 0.0)
        info["residual_rms_mm"] = 0.0
    elif method == "zernike":
        coef = fit_zernike(px[ok], py[ok], w[ok], n_zernike)
        grid_w = zernike_surface(coef, gx, gy)
        info["zernike_mm"] = coef.tolist()
        info["residual_rms_mm"] = float(np.sqrt(np.mean((zernike_surface(coef, px[ok], py[ok]) - w[ok]) ** 2)))
    else:
        raise LensrtError(f"unknown pupil gridding method {method!r}", hint="use 'linear' or 'zernike'")
    if amplitude is not None:
        a = np.ravel(np.asarray(amplitude, dtype=np.float64))[ok]
        grid_a = lin(a)
        hole = ~np.isfinite(grid_a)
        grid_a[hole & (mask <= 0)] = 0.0   # dark cells: their amplitude is multiplied by 0 below
        hole &= mask > 0
        if hole.any():
            grid_a[hole] = NearestNDInterpolator(pts, a)(gx[hole], gy[hole])
        mask = mask * np.clip(grid_a, 0.0, None)
    grid_w = np.where(mask > 0, grid_w, 0.0)
    return mask, grid_w, info
