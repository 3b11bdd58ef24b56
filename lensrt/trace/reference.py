"""The reference real-ray tracer: one ray at a time, float64, plain Python ``math``.

The oracle the Warp kernels are tested against; the intersection and
refraction formulas, and the sequential rules, are in :mod:`.ray_surface`.
A centred refractive lens (``Lens.is_plain``) is traced here in each
surface's vertex frame; a lens with mirrors, tilts/decenters, surface
apertures or OpticStudio's aperture rule goes to :mod:`.reference_general`,
which adds the rigid transforms into and out of each local frame.
"""
from __future__ import annotations

import math

from ..prescription.model import Iris, Lens
from ..prescription.shapes import profile_of
from .ray_surface import (NEWTON_MAX_ITER, NEWTON_TOL_MM, ReferenceRay, SurfaceHit, conic_t, ideal_lens,
                          inside_iris, intersect, reflect, refract, sag_and_slope)
from .ray_shapes import intersect_profile
from .reference_general import trace_general
from .status import APERTURE_TOLERANCE, INVALID, MISSED, OK, VIGNETTED

__all__ = ["NEWTON_MAX_ITER", "NEWTON_TOL_MM", "SurfaceHit", "ReferenceRay", "trace_reference",
           "intersect", "refract", "reflect", "inside_iris", "sag_and_slope", "conic_t"]


def trace_reference(lens: Lens, origin_mm: tuple[float, float, float], direction: tuple[float, float, float],
                    wavelength_nm: float, *, clip: bool = True, end: int | None = None,
                    iris: Iris | None = None, stop_radius_mm: float | None = None) -> ReferenceRay:
    """Trace one ray through ``lens``.

    Parameters
    ----------
    lens : Lens
        A complete lens (semi-diameters known where ``clip`` is wanted).
    origin_mm : (x, y, z)
        A point of the ray in object space (lens frame, mm). The ray is a line:
        the origin may lie behind the first surface.
    direction : (L, M, N)
        Direction cosines (normalised here).
    wavelength_nm : float
        Wavelength in air, nm.
    clip : bool
        Apply clear semi-diameters and the iris (False: trace the bare surfaces).
    end : int, optional
        Refract at surfaces ``0 .. end-1`` and stop at the intersection with
        surface ``end`` (default: the image surface, index ``n_surfaces``).
    iris, stop_radius_mm : optional
        Override the lens's iris and the stop's clear radius.

    Returns
    -------
    ReferenceRay
        ``hits`` has one entry per surface met (the image surface last).
    """
    if not lens.is_plain:
        return trace_general(lens, origin_mm, direction, wavelength_nm, clip=clip, end=end, iris=iris,
                             stop_radius_mm=stop_radius_mm)
    n_surf = lens.n_surfaces
    end = n_surf if end is None else int(end)
    iris = lens.iris if iris is None else iris
    stop = lens.stop_index
    if stop_radius_mm is None:
        stop_radius_mm = lens.surfaces[stop].semi_diameter_mm
    index = [float(v) for v in lens.indices(float(wavelength_nm))]
    vertex_z = lens.vertex_z_mm()
    x, y, z = (float(v) for v in origin_mm)
    L, M, N = (float(v) for v in direction)
    norm = math.sqrt(L * L + M * M + N * N)
    ray = ReferenceRay(OK, -1, x, y, z, L, M, N, 0.0)
    if not (math.isfinite(norm) and norm > 0.0 and all(math.isfinite(v) for v in (x, y, z))) \
            or not all(math.isfinite(n) and n > 0.0 for n in index):
        ray.status, ray.surface = INVALID, 0
        return ray
    L, M, N = L / norm, M / norm, N / norm
    opl = 0.0
    for i in range(end + 1):
        if i < n_surf:
            s = lens.surfaces[i]
            c, kp1, asph = s.curvature_per_mm, 1.0 + s.conic, s.asphere
        else:  # the image surface: a plane or a sphere (Lens.image_curvature_per_mm)
            c, kp1, asph = lens.image_curvature_per_mm, 1.0, ()
        if i < n_surf and s.shape is not None:  # odd, Q-type, biconic, toroidal (.ray_shapes)
            status, t, normal = intersect_profile(profile_of(s), x, y, z, L, M, N)
        else:
            status, t, normal = intersect(c, kp1, asph, x, y, z, L, M, N)
        if status == OK and L * normal[0] + M * normal[1] + N * normal[2] < 0.0:
            status = MISSED  # met from behind, from the medium after the surface: no sequential path
        if status != OK:
            ray.status, ray.surface = status, i
            break
        x, y, z = x + t * L, y + t * M, z + t * N
        opl += index[i] * t
        ray.x_mm, ray.y_mm, ray.z_mm, ray.opl_mm = x, y, z + vertex_z[i], opl
        if i == end:  # the last surface: met, not refracted
            ray.hits.append(SurfaceHit(x, y, z, L, M, N, 0.0, 0.0, t))
            break
        if clip:
            if i == stop and stop_radius_mm is not None:
                passed = inside_iris(x, y, stop_radius_mm, iris)
            else:
                sd = s.semi_diameter_mm
                passed = sd is None or x * x + y * y <= (sd * (1.0 + APERTURE_TOLERANCE)) ** 2
            if not passed:
                ray.status, ray.surface = VIGNETTED, i
                ray.hits.append(SurfaceHit(x, y, z, L, M, N, 0.0, 0.0, t))
                break
        if s.ideal_focal_mm is not None:  # an ideal paraxial lens: the direction change of a perfect lens
            status, L, M, N, ang_i, ang_r, added = ideal_lens(L, M, N, x, y, 1.0 / s.ideal_focal_mm, index[i],
                                                              index[i + 1])
            opl += added
            ray.opl_mm = opl
        else:
            status, L, M, N, ang_i, ang_r = refract(L, M, N, normal, index[i], index[i + 1])
        ray.hits.append(SurfaceHit(x, y, z, L, M, N, ang_i, ang_r, t))
        ray.L, ray.M, ray.N = L, M, N
        if status != OK:
            ray.status, ray.surface = status, i
            break
        z -= lens.surfaces[i].thickness_mm  # into the next vertex frame
    return ray
