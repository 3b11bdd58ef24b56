"""The wavefront of a field point from real rays: OPD to the reference sphere, and the pupil function.

Definitions (what the numbers mean)
-----------------------------------
* **Reference point Q**: where the real chief ray of the primary wavelength
  (through the centre of the real stop) meets the observation plane z = z_P.
* **Exit-pupil point E**: where that chief ray's image-space line crosses the
  paraxial exit-pupil plane z = z_XP (primary wavelength).
* **Reference sphere**: centred on Q with radius R = |Q - E|, through E.
  (A telecentric lens, z_XP at infinity, has R = infinity: the reference
  surface becomes the plane through Q perpendicular to the chief ray; the
  formula below tends to it.)
* **Optical path** of a ray: from the object point's wavefront through the
  first vertex (the sphere about a finite object point, or the plane
  perpendicular to a collimated beam -- where :mod:`lensrt.trace.aiming` starts
  every ray) through the lens to the reference sphere, sum of n x length.
* **OPD** of a ray = its optical path minus the chief ray's (the chief ray of
  the same wavelength), positive = longer path, in mm. Sign as in
  :mod:`lensrt.analysis.wave.pupil_grid`: a focus displaced by +dx from Q appears as
  the tilt W = dx NA p_x.

The store kernel traces each ray to the plane z_P, giving its landing point P,
unit direction d and optical path S_P. Going back from P along d by s to the
sphere, |P - s d - Q| = R, with v = P - Q:

    s - R = v.d + ((v.d)^2 - |v|^2) / (sqrt(R^2 + (v.d)^2 - |v|^2) + R),

written so that it does not cancel for large R, and the optical path to the
sphere is S_P - n' s (n' the image-space index). The chief ray has v ~ 0, s = R.

The pupil function
------------------
Rays start on an m x m grid over the real pupil's box (:mod:`lensrt.analysis.pupil_rays`)
and are placed at normalised pupil positions p = -(d_xy - d_chief,xy) / NA
(:func:`lensrt.analysis.wave.pupil_grid.pupil_coordinates_from_directions`), NA the
smallest scale that holds every valid ray (2 % margin). Rays that fail
(vignetted by any clear aperture, stopped by an iris blade, missed, TIR) are
traced again without clipping to place them in p; the aperture is the region
where the linear interpolant of "this ray passed" is >= 1/2, anti-aliased
over 4 x 4 sub-cells in the cells along the edge -- so vignetting and the iris polygon come from the rays
themselves, with zero amplitude outside. The amplitude carries the ray
density: uniform flux over the entrance-pupil box, times the kernel's ray
weight, spread over the p-area each ray occupies, |a|^2 = w / |d(p)/d(a, b)|
(finite differences on the ray grid; normalised to its median).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...units import NM_PER_MM
from .pupil_grid import enclosing_na, pupil_coordinates_from_directions, pupil_from_rays
from ..pupil_rays import PupilRays, pupil_grid_rays

if TYPE_CHECKING:
    from .ray_mesh import GridLinear

__all__ = ["ReferenceSphere", "RayWavefront", "reference_sphere", "opd_to_sphere_mm", "trace_wavefronts",
           "trace_wavefronts_many", "pupil_function_from_wavefront"]


@dataclass(frozen=True)
class ReferenceSphere:
    """Centre Q (x, y, z; mm), exit-pupil point E (mm), radius R (mm; inf for a plane), chief direction."""

    centre_mm: tuple[float, float, float]
    exit_pupil_point_mm: tuple[float, float, float]
    radius_mm: float
    chief_direction: tuple[float, float, float]

    def to_dict(self) -> dict:
        return {"centre_mm": list(self.centre_mm), "exit_pupil_point_mm": list(self.exit_pupil_point_mm),
                "radius_mm": self.radius_mm if math.isfinite(self.radius_mm) else None,
                "chief_direction": list(self.chief_direction)}


def reference_sphere(lens: Lens, chief_position_mm: np.ndarray, chief_direction: np.ndarray) -> ReferenceSphere:
    """The reference sphere of a field point from its real chief ray (module docstring)."""
    from ...paraxial import first_order
    q = np.asarray(chief_position_mm, dtype=np.float64)
    d = np.asarray(chief_direction, dtype=np.float64)
    z_xp = first_order(lens).exit_pupil_z_mm
    if not math.isfinite(z_xp) or abs(d[2]) < 1e-12:
        return ReferenceSphere(tuple(q), (math.nan,) * 3, math.inf, tuple(d))
    e = q + d * (z_xp - q[2]) / d[2]
    r = float(np.linalg.norm(q - e))
    if z_xp > q[2]:  # exit pupil behind the observation plane: a diverging reference
        r = -r
    return ReferenceSphere(tuple(q), tuple(float(v) for v in e), r, tuple(d))


def opd_to_sphere_mm(position_mm: np.ndarray, direction: np.ndarray, opl_mm: np.ndarray, n_image: float,
                     sphere: ReferenceSphere) -> np.ndarray:
    """Optical path to the reference sphere, less the constant n' R: S_P - n' (s - R) per ray (mm).

    Differences between rays (of one wavelength) are their OPDs (module docstring).
    """
    v = np.asarray(position_mm, dtype=np.float64) - np.asarray(sphere.centre_mm)
    d = np.asarray(direction, dtype=np.float64)
    vd = np.sum(v * d, axis=1)
    vv = np.sum(v * v, axis=1)
    r = sphere.radius_mm
    if math.isinf(r):
        s_minus_r = vd
    else:
        ra = abs(r)
        s_minus_r = vd + (vd * vd - vv) / (np.sqrt(np.maximum(ra * ra + vd * vd - vv, 0.0)) + ra)
        if r < 0:
            s_minus_r = vd - (vd * vd - vv) / (np.sqrt(np.maximum(ra * ra + vd * vd - vv, 0.0)) + ra)
    return np.asarray(opl_mm, dtype=np.float64) - n_image * s_minus_r


@dataclass
class RayWavefront:
    """One wavelength's traced wavefront at a field point.

    ``px, py`` (k,) normalised pupil positions of every placed ray, ``valid`` (k,) ray passed,
    ``opd_mm`` (k,) OPD (valid rays), ``amplitude`` (k,) relative amplitude (valid rays),
    ``spot_half_mm`` the largest |x|, |y| of a valid ray's landing point from Q (geometric spot),
    ``na`` the grid scale, ``grid_m`` the m of the m x m ray grid the rays were traced on and ``grid_index``
    (k,) each ray's flat index in it (0 and None for rays not from a grid: they are then triangulated by
    Delaunay); ``sphere`` the reference sphere; ``ray_step_waves`` the largest OPD change
    between neighbouring rays and ``interp_error_waves`` an estimate of the linear interpolation
    error (max |second difference| / 8).
    """

    wavelength_nm: float
    px: np.ndarray
    py: np.ndarray
    valid: np.ndarray
    opd_mm: np.ndarray
    amplitude: np.ndarray
    na: float
    na_real: float
    sphere: ReferenceSphere
    rays: int
    ray_step_waves: float
    interp_error_waves: float
    opd_pv_waves: float
    opd_rms_waves: float
    spot_half_mm: float
    grid_m: int = 0
    grid_index: np.ndarray | None = None

    @property
    def ray_grid(self) -> tuple[int, np.ndarray] | None:
        """``(m, grid_index)`` for :func:`~lensrt.analysis.wave.pupil_grid.pupil_from_rays`, None off a grid."""
        return None if self.grid_index is None or self.grid_m < 2 else (int(self.grid_m), self.grid_index)

    @property
    def mesh(self) -> GridLinear | None:
        """The rays' :class:`~lensrt.analysis.wave.ray_mesh.GridLinear` (built once per wavefront; a pupil
        function at any size uses it), None off a grid. Two threads asking at once may both build it (the
        same mesh): no lock, so analysis threads never wait on each other here."""
        from .ray_mesh import GridLinear
        got = self.__dict__.get("_mesh")
        if got is None or got[0] is not self.px:
            grid = self.ray_grid
            got = (self.px, None if grid is None else GridLinear(grid[0], grid[1], self.px, self.py))
            self.__dict__["_mesh"] = got
        return got[1]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_mesh", None)   # rebuilt on demand
        return state


def _grid_stats(opd: np.ndarray, valid: np.ndarray, m: int, wavelength_mm: float) -> tuple[float, float]:
    w = np.where(valid, opd, np.nan).reshape(m, m) / wavelength_mm
    steps, second = [0.0], [0.0]
    for ax in (0, 1):
        d1 = np.abs(np.diff(w, axis=ax))
        d2 = np.abs(np.diff(w, n=2, axis=ax))
        if np.isfinite(d1).any():
            steps.append(float(np.nanmax(d1)))
        if np.isfinite(d2).any():
            second.append(float(np.nanmax(d2)))
    return max(steps), max(second) / 8.0


def _amplitude(px: np.ndarray, py: np.ndarray, ok: np.ndarray, weight: np.ndarray, m: int) -> np.ndarray:
    """|a| = sqrt(w / |d(p)/d(a, b)|), central differences on the ray grid, nearest fill, median 1."""
    from scipy.interpolate import NearestNDInterpolator
    X = np.where(ok, px, np.nan).reshape(m, m)
    Y = np.where(ok, py, np.nan).reshape(m, m)
    xa, xb = np.gradient(X)
    ya, yb = np.gradient(Y)
    jac = np.abs(xa * yb - xb * ya).ravel()
    dens = weight / np.where(jac > 0, jac, np.nan)
    good = ok & np.isfinite(dens)
    if good.sum() < 3:
        return np.where(ok, 1.0, 0.0)
    idx = np.arange(m * m)
    ai, bi = np.divmod(idx, m)
    fill = ok & ~good
    if fill.any():
        dens[fill] = NearestNDInterpolator(np.column_stack([ai[good], bi[good]]), dens[good])(ai[fill], bi[fill])
    med = float(np.median(dens[ok]))
    amp = np.sqrt(np.clip(dens / med, 0.0, 25.0))
    return np.where(ok, amp, 0.0)


def trace_wavefronts(lens: Lens, fp, box, wavelengths_nm: Sequence[float], plane_z_mm: float, m: int,
                     primary_nm: float | None = None, device: str | None = None, chief=None) -> list[RayWavefront]:
    """Trace an m x m ray grid over ``box`` at each wavelength; OPDs to the common reference sphere.
    ``chief``: the :func:`~lensrt.analysis.pupil_rays.chief_ray_at` result at [primary] + wavelengths when
    already traced."""
    from ..pupil_rays import chief_ray_at
    prim = float(primary_nm if primary_nm is not None else lens.wavelengths.primary_nm)
    if chief is None:
        chief = chief_ray_at(lens, fp, [prim] + [float(v) for v in wavelengths_nm], plane_z_mm, device)
    got = trace_wavefronts_many(lens, [(fp, box, m, chief)], wavelengths_nm, plane_z_mm, device)[0]
    if isinstance(got, LensrtError):
        raise got
    return got


def trace_wavefronts_many(lens: Lens, jobs: Sequence[tuple], wavelengths_nm: Sequence[float], plane_z_mm: float,
                          device: str | None = None) -> list:
    """:func:`trace_wavefronts` of several field points, the same wavefronts: every job's ray grid at every
    wavelength in one clipped and one unclipped trace (two launches in all).

    ``jobs``: (field point, pupil box, m rays a side, chief) each, ``chief`` the
    :func:`~lensrt.analysis.pupil_rays.chief_ray_at` result at [primary] + wavelengths. An entry of the answer
    is the job's list of :class:`RayWavefront` (one per wavelength), or the :class:`LensrtError` that
    :func:`trace_wavefronts` raises for it."""
    from ...trace import RayBatch, trace
    wls = [float(v) for v in wavelengths_nm]
    grids: list = []
    for fp, box, m, _ in jobs:
        try:
            grids.append(pupil_grid_rays(fp, box, m))
        except LensrtError as err:
            grids.append(err)
    traced = [g for g in grids if not isinstance(g, LensrtError)]
    if not traced:
        return grids
    # each job's grid repeated per wavelength (as trace_pupil_rays_many tiles one grid), the jobs one after
    # the other; every ray is traced on its own, so its result does not depend on the rest of the batch
    wl = np.asarray(wls, dtype=np.float64)
    batch = RayBatch(np.concatenate([np.tile(g.origin_mm, (len(wls), 1)) for g in traced]),
                     np.concatenate([np.tile(g.direction, (len(wls), 1)) for g in traced]),
                     np.concatenate([np.repeat(wl, len(g.weight)) for g in traced]))
    both = [trace(lens, batch, "float64", device, clip=clip, plane_z_mm=plane_z_mm) for clip in (True, False)]
    out, start = [], 0
    for (fp, box, m, chief), g in zip(jobs, grids):
        if isinstance(g, LensrtError):
            out.append(g)
            continue
        n = len(g.weight)
        parts = [[r.part(start + k * n, start + (k + 1) * n) for k in range(len(wls))] for r in both]
        start += n * len(wls)
        try:
            out.append(_wavefronts_of(lens, g, wls, chief, parts[0], parts[1]))
        except LensrtError as err:
            out.append(err)
    return out


def _wavefronts_of(lens: Lens, rays: PupilRays, wls: list[float], chief_all, all_clipped: list,
                   all_free: list) -> list[RayWavefront]:
    """One field's wavefronts from its traced grid (clipped and unclipped, one RayResult per wavelength)."""
    m = rays.m
    sphere = reference_sphere(lens, chief_all.position_mm[0], chief_all.direction[0])
    dc = chief_all.direction[0]
    traced = []
    for k, wl in enumerate(wls):
        n_img = float(lens.indices(wl)[-1])
        clipped, free = all_clipped[k], all_free[k]
        ok = clipped.ok
        placed = free.ok  # rays that can be put in the pupil (their unclipped path exists)
        s = opd_to_sphere_mm(clipped.position_mm, clipped.direction, clipped.opl_mm, n_img, sphere)
        c = opd_to_sphere_mm(chief_all.position_mm[k + 1:k + 2], chief_all.direction[k + 1:k + 2],
                             chief_all.opl_mm[k + 1:k + 2], n_img, sphere)[0]
        opd = np.where(ok, s - c, 0.0)
        dirs = np.where(ok[:, None], clipped.direction, free.direction)
        half = float(np.abs(clipped.position_mm[ok, :2] - np.asarray(sphere.centre_mm[:2])).max()) if ok.any() else 0.0
        traced.append((wl, ok, placed, opd, dirs, half))
    # one grid scale for every wavelength: holds all valid rays
    all_dirs = np.concatenate([t[4][t[1]] for t in traced])
    if len(all_dirs) < 16:
        raise LensrtError("too few rays reach the image to build a wavefront", hint="check the field point")
    na_real = enclosing_na(all_dirs, dc, margin=0.0)
    na = na_real * 1.02
    out = []
    for wl, ok, placed, opd, dirs, half in traced:
        px, py = pupil_coordinates_from_directions(dirs, dc, na)
        lam = wl / NM_PER_MM
        step, interp = _grid_stats(opd, ok, m, lam)
        amp = _amplitude(px, py, ok, rays.weight, m)
        keep = placed | ok
        o = opd[ok] / lam
        out.append(RayWavefront(wl, px[keep], py[keep], ok[keep], opd[keep], amp[keep], na, na_real, sphere,
                                int(m * m), step, interp, float(o.max() - o.min()) if o.size else 0.0,
                                float(np.sqrt(np.mean((o - o.mean()) ** 2))) if o.size else 0.0, half,
                                int(m), np.nonzero(keep)[0]))
    return out


#: sub-cells a side of the fine pupil grid an OTF is taken on (at most; see lensrt.analysis.psf.diffraction)
OTF_FINE_CELLS = 256


def _ray_mask(inside_value, n: int, supersample: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(clear fraction of each pupil cell, the hard-edged fine mask for the OTF) where ``inside_value(px, py)
    >= 1/2``. The fractions sub-sample (s x s points) only the cells at the edge (where the value at the centres
    of the cell and its neighbours is not all 0 or 1); the fine mask has f x f sub-cells a cell
    (f = OTF_FINE_CELLS // n, at least 1), the edge cells' sub-cells sampled at their centres -- the same
    points as the fractions' when f = s, which are then not sampled again."""
    from .pupil_grid import pupil_coordinates
    gx, gy = pupil_coordinates(n)
    v = inside_value(gx, gy)
    mask = (v >= 0.5).astype(np.float64)
    mixed = (v > 1e-9) & (v < 1 - 1e-9)
    pad = np.pad(mask, 1, mode="edge")
    differs = np.zeros_like(mixed)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            differs |= pad[1 + dr:n + 1 + dr, 1 + dc:n + 1 + dc] != mask
    edge = np.nonzero(mixed | differs)
    f = max(1, OTF_FINE_CELLS // n)
    fine = np.repeat(np.repeat(mask >= 0.5, f, axis=0), f, axis=1)
    if edge[0].size and f > 1:
        fx, fy = pupil_coordinates(n * f)
        k = np.arange(f)
        rows = edge[0][:, None, None] * f + k[None, :, None]
        cols = edge[1][:, None, None] * f + k[None, None, :]
        fine[rows, cols] = inside_value(fx[rows, cols], fy[rows, cols]) >= 0.5
        if f == supersample:  # the s x s sub-samples are the fine sub-cells' centres: already found
            mask[edge] = np.mean(fine[rows, cols].reshape(-1, f * f), axis=1)
            return mask, fine
    if edge[0].size and supersample > 1:
        s = int(supersample)
        off = ((np.arange(s) + 0.5) / s - 0.5) * (2.0 / n)
        ox, oy = (a.ravel() for a in np.meshgrid(off, off))
        qx = gx[edge][:, None] + ox[None, :]
        qy = gy[edge][:, None] + oy[None, :]
        mask[edge] = np.mean(inside_value(qx, qy) >= 0.5, axis=1)
    return mask, fine


def pupil_function_from_wavefront(wf: RayWavefront, n: int):
    """The :class:`~lensrt.analysis.wave.propagation.PupilFunction` of a traced wavefront on an n x n pupil grid."""
    from .propagation import PupilFunction
    from .pupil_grid import TriLinear
    mesh = wf.mesh  # rays from a regular grid are triangulated along it (ray_mesh), others by Delaunay
    lin = TriLinear.of(wf.px, wf.py) if mesh is None else mesh
    valid = wf.valid.astype(np.float64)
    mask, fine = _ray_mask(lambda qx, qy: lin.interp(valid, qx, qy, fill=0.0), n, supersample=4)
    amp, opd, info = pupil_from_rays(wf.px, wf.py, wf.opd_mm, wf.valid, n, aperture=mask, amplitude=wf.amplitude,
                                     ray_grid=mesh)
    # the clear pupil's area in direction-cosine space -> the NA of the circle of equal area
    info["equivalent_na"] = float(wf.na * math.sqrt(mask.sum() * (2.0 / n) ** 2 / math.pi))
    a_cell = np.where(mask > 0, amp / np.where(mask > 0, mask, 1.0), 0.0)
    intensity = mask * a_cell * a_cell
    pupil = PupilFunction(amp, opd, wf.wavelength_nm, 0.5 / wf.na, tuple(wf.sphere.chief_direction),
                          intensity=np.maximum(intensity, amp * amp), fine_mask=fine)
    return pupil, info
