"""Deterministic ray sets for PSF set-up: a regular grid over a field point's real pupil, and chief rays.

The Monte Carlo PSF itself comes from the stream kernel; these helpers trace
small regular ray sets with the float64 *store* kernel for what must be known
before it runs (where the light lands, the best-focus plane) and for the
wavefront (optical path differences) behind diffraction PSFs.

Rays start as the stream kernel's do: uniformly over the rectangle
(:class:`lensrt.trace.stream.PupilBox`) that holds the field point's real,
vignetted entrance pupil, with the kernel's weights (1 for a collimated beam;
the solid-angle factor, times cos(theta) for a Lambertian object point).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens

__all__ = ["PupilRays", "pupil_grid_rays", "trace_pupil_rays", "trace_pupil_rays_many",
           "chief_ray_at", "chief_rays_at_many", "field_xy_of"]


@dataclass
class PupilRays:
    """An m x m grid of rays over a pupil box (row-major over (a, b)).

    ``origin_mm``/``direction`` (m*m, 3), ``weight`` (m*m,) as the stream kernel weights rays,
    ``m`` rays per side, ``box`` the PupilBox, ``cell_mm2`` the box area per ray.
    """

    origin_mm: np.ndarray
    direction: np.ndarray
    weight: np.ndarray
    m: int
    box: object
    cell_mm2: float


def pupil_grid_rays(fp, box, m: int) -> PupilRays:
    """Rays of field point ``fp`` through the centres of an m x m grid of cells over ``box``."""
    from ..trace.aiming import ray_through_point
    if box.area_mm2 <= 0:
        raise LensrtError("no ray of this field point passes the lens (the pupil is empty)",
                          hint="choose a field point inside the lens's coverage")
    a = box.a0 + (np.arange(m) + 0.5) * (box.a1 - box.a0) / m
    b = box.b0 + (np.arange(m) + 0.5) * (box.b1 - box.b0) / m
    A, B = np.meshgrid(a, b, indexing="ij")
    pts = box.points(A.ravel(), B.ravel())
    o, d = ray_through_point(fp, pts)
    if fp.infinite:
        w = np.ones(len(d))
    else:
        # the kernel's weight: cos(theta_plane) (dist / rho)^2, times cos(theta_object) (Lambertian)
        obj = np.asarray(fp.point_mm, dtype=np.float64)
        axis = np.asarray(box.axis, dtype=np.float64)
        dist = float(np.dot(np.asarray(box.centre) - obj, axis))
        rho = np.linalg.norm(pts - obj, axis=1)
        w = (d @ axis) * (dist / rho) ** 2 * d[:, 2]
    return PupilRays(o, d, w, int(m), box, box.area_mm2 / (m * m))


def trace_pupil_rays(lens: Lens, rays: PupilRays, wavelength_nm: float, plane_z_mm: float,
                     device: str | None = None, clip: bool = True):
    """Trace a :class:`PupilRays` set at one wavelength to the plane z = ``plane_z_mm`` (float64 store kernel)."""
    from ..trace import RayBatch, trace
    batch = RayBatch(rays.origin_mm, rays.direction, np.full(len(rays.weight), float(wavelength_nm)))
    return trace(lens, batch, "float64", device, clip=clip, plane_z_mm=plane_z_mm)


def trace_pupil_rays_many(lens: Lens, rays: PupilRays, wavelengths_nm: Sequence[float], plane_z_mm: float,
                          device: str | None = None, clip: bool = True) -> list:
    """:func:`trace_pupil_rays` at each of several wavelengths, the same results, in one trace (one launch)."""
    from ..trace import RayBatch, trace
    wls = [float(w) for w in wavelengths_nm]
    m = len(rays.weight)
    batch = RayBatch(np.tile(rays.origin_mm, (len(wls), 1)), np.tile(rays.direction, (len(wls), 1)),
                     np.repeat(np.asarray(wls, dtype=np.float64), m))
    res = trace(lens, batch, "float64", device, clip=clip, plane_z_mm=plane_z_mm)
    return [res.part(k * m, (k + 1) * m) for k in range(len(wls))]


def chief_ray_at(lens: Lens, fp, wavelengths_nm: Sequence[float], plane_z_mm: float,
                 device: str | None = None):
    """The real chief ray (through the real stop's centre) of ``fp`` at each wavelength, traced without
    clipping to the plane z = ``plane_z_mm``: a :class:`lensrt.trace.RayResult`."""
    from ..trace import RayBatch, trace
    from ..trace.aiming import aim_rays
    from ..trace.api import kernel_to_stop
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    o, d, ok = aim_rays(lens, fp, np.zeros(len(wl)), np.zeros(len(wl)), wl, "real", kernel_to_stop(lens, device))
    res = trace(lens, RayBatch(o, d, wl), "float64", device, clip=False, plane_z_mm=plane_z_mm)
    if not (ok.all() and res.ok.all()):
        raise LensrtError("the real chief ray of this field point cannot be traced to the image",
                          hint="choose a field point inside the lens's coverage")
    return res


def chief_rays_at_many(lens: Lens, fps, wavelengths_nm: Sequence[float], plane_z_mm: float,
                       device: str | None = None) -> list:
    """:func:`chief_ray_at` of several field points, the same rays: one aiming run and one trace for all.
    An entry is the field point's RayResult, or the :class:`LensrtError` :func:`chief_ray_at` raises for it.
    The rays are aimed by :func:`~lensrt.analysis.raysets.aim_batches` (``aim_many``, each ray's Newton run its
    own): a chief ray aimed before in this process -- another wavelength set of the same fields -- is reused."""
    from ..trace import RayBatch, trace
    from .raysets import aim_batches
    fps = list(fps)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    w = len(wl)
    wls = np.tile(wl, len(fps))
    aimed = aim_batches(lens, [(fp, 0.0, 0.0, float(x)) for fp in fps for x in wl], "real", device)
    o, d = np.concatenate([b.origin_mm for b in aimed]), np.concatenate([b.direction for b in aimed])
    ok = np.concatenate([b.aimed for b in aimed])
    res = trace(lens, RayBatch(o, d, wls), "float64", device, clip=False, plane_z_mm=plane_z_mm)
    out = []
    for k in range(len(fps)):
        part = res.part(k * w, (k + 1) * w)
        out.append(part if ok[k * w:(k + 1) * w].all() and part.ok.all() else LensrtError(
            "the real chief ray of this field point cannot be traced to the image",
            hint="choose a field point inside the lens's coverage"))
    return out


def field_xy_of(lens: Lens, hx: float, hy: float) -> tuple[float, float]:
    """Normalised field (hx, hy) in the lens's field units (rad or mm), polar as in lensrt.trace.aiming."""
    r = lens.fields.max_radial
    return float(hx * r), float(hy * r)
