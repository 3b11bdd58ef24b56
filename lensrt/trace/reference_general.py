"""The float64 reference tracer for every lens: mirrors, tilts/decenters, surface apertures.

Written to be read, like :mod:`.reference`. The ray is carried in global
coordinates between surfaces; at surface i it is taken into the surface's
local frame (:func:`lensrt.prescription.frames.surface_frames`: origin o,
axes A as columns), ``p_local = A^T (p - o)``, ``d_local = A^T d``, met,
refracted or reflected there, and taken back, ``p = o + A p_local``.

After an odd number of mirrors light travels toward local -z
(:func:`~lensrt.prescription.frames.travel_signs`). The surface is then met
in the frame mirrored in z (z -> -z, so the sag's c and asphere terms change
sign and the conic stays): light again runs toward +z there and every rule of
:mod:`.ray_surface` (the vertex branch, the crossing toward the +z side, a
surface met from behind is ``MISSED``) holds unchanged. Reflection is the
vector law d' = d - 2 (d . n) n (:func:`~.ray_surface.reflect`); the index
does not change at a mirror.

Clipping (``clip=True``): the stop's iris, every surface aperture
(``Surface.apertures``: clear apertures pass the inside, obscurations block
it; status ``VIGNETTED``), and the circular semi-diameters the lens's
aperture rule makes vignette (:meth:`Lens.clips_semi_diameter`).

The returned ray's end point and direction are in the local frame of the
last surface met (the image surface by default), with ``z`` shifted by that
surface's unfolded vertex position ``lens.vertex_z_mm()[i]``: for a centred
refractive lens this is the lens frame of :mod:`.reference`.
"""
from __future__ import annotations

import math
from functools import lru_cache

from ..prescription.frames import surface_frames, travel_signs
from ..prescription.model import Iris, Lens
from ..prescription.shapes import profile_of
from .ray_shapes import intersect_profile
from .ray_surface import ReferenceRay, SurfaceHit, ideal_lens, inside_iris, intersect, reflect, refract
from .status import APERTURE_TOLERANCE, INVALID, MISSED, OK, VIGNETTED

__all__ = ["trace_general", "local_frames"]

Frame = tuple[tuple[float, float, float], tuple[float, ...]]


@lru_cache(maxsize=64)
def local_frames(lens: Lens) -> tuple[tuple[Frame, ...], tuple[float, ...], tuple[float, ...]]:
    """Frames (origin, axes row-major 3x3) of every surface and the image, travel signs, unfolded vertex z."""
    frames = tuple((tuple(float(v) for v in o), tuple(float(v) for v in a.ravel()))
                   for o, a in surface_frames(lens))
    return frames, tuple(travel_signs(lens)), tuple(float(z) for z in lens.vertex_z_mm())


def _to_local(frame: Frame, p: tuple[float, float, float], d: tuple[float, float, float],
              sign: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    (ox, oy, oz), a = frame
    x, y, z = p[0] - ox, p[1] - oy, p[2] - oz
    # A^T v: the components along the local axes (the columns of A)
    lx, ly, lz = (a[0] * x + a[3] * y + a[6] * z, a[1] * x + a[4] * y + a[7] * z,
                  sign * (a[2] * x + a[5] * y + a[8] * z))
    L, M, N = (a[0] * d[0] + a[3] * d[1] + a[6] * d[2], a[1] * d[0] + a[4] * d[1] + a[7] * d[2],
               sign * (a[2] * d[0] + a[5] * d[1] + a[8] * d[2]))
    return (lx, ly, lz), (L, M, N)


def _to_global(frame: Frame, v: tuple[float, float, float], sign: float, point: bool) -> tuple[float, float, float]:
    (ox, oy, oz), a = frame
    x, y, z = v[0], v[1], sign * v[2]
    gx, gy, gz = a[0] * x + a[1] * y + a[2] * z, a[3] * x + a[4] * y + a[5] * z, a[6] * x + a[7] * y + a[8] * z
    return (gx + ox, gy + oy, gz + oz) if point else (gx, gy, gz)


def _passes(lens: Lens, i: int, x: float, y: float, iris: Iris, stop_radius_mm: float | None) -> bool:
    """The clipping of surface ``i`` at local (x, y) (module docstring)."""
    s = lens.surfaces[i]
    if not all(a.passes(x, y, APERTURE_TOLERANCE) for a in s.apertures):
        return False
    if i == lens.stop_index and stop_radius_mm is not None:
        return inside_iris(x, y, stop_radius_mm, iris)
    if lens.clips_semi_diameter(i):
        sd = s.semi_diameter_mm * (1.0 + APERTURE_TOLERANCE)  # type: ignore[operator]
        return x * x + y * y <= sd * sd
    return True


def _start(origin_mm, direction, index: list[float]) -> tuple[ReferenceRay, tuple, tuple]:
    """The ray's state before the first surface (status INVALID for a bad ray or index)."""
    x, y, z = (float(v) for v in origin_mm)
    L, M, N = (float(v) for v in direction)
    norm = math.sqrt(L * L + M * M + N * N)
    ray = ReferenceRay(OK, -1, x, y, z, L, M, N, 0.0)
    if not (math.isfinite(norm) and norm > 0.0 and all(math.isfinite(v) for v in (x, y, z))) \
            or not all(math.isfinite(n) and n > 0.0 for n in index):
        ray.status, ray.surface = INVALID, 0
        return ray, (), ()
    return ray, (x, y, z), (L / norm, M / norm, N / norm)


def trace_general(lens: Lens, origin_mm: tuple[float, float, float], direction: tuple[float, float, float],
                  wavelength_nm: float, *, clip: bool = True, end: int | None = None,
                  iris: Iris | None = None, stop_radius_mm: float | None = None) -> ReferenceRay:
    """Trace one ray through any ``lens``; the parameters and result are those of
    :func:`lensrt.trace.reference.trace_reference` (module docstring for the frames)."""
    n_surf = lens.n_surfaces
    end = n_surf if end is None else int(end)
    iris = lens.iris if iris is None else iris
    if stop_radius_mm is None:
        stop_radius_mm = lens.surfaces[lens.stop_index].semi_diameter_mm
    index = [float(v) for v in lens.indices(float(wavelength_nm))]
    ray, p, d = _start(origin_mm, direction, index)
    if ray.status != OK:
        return ray
    frames, signs, vertex_z = local_frames(lens)
    opl = 0.0
    for i in range(end + 1):
        s = lens.surfaces[i] if i < n_surf else None
        sign = signs[i]
        c = sign * (lens.image_curvature_per_mm if s is None else s.curvature_per_mm)  # the image: plane or sphere
        kp1 = 1.0 if s is None else 1.0 + s.conic
        asph = () if s is None else tuple(sign * a for a in s.asphere)
        (x, y, z), (L, M, N) = _to_local(frames[i], p, d, sign)
        if s is not None and s.shape is not None:  # odd, Q-type, biconic, toroidal (.ray_shapes)
            status, t, normal = intersect_profile(profile_of(s, sign), x, y, z, L, M, N)
        else:
            status, t, normal = intersect(c, kp1, asph, x, y, z, L, M, N)
        if status == OK and L * normal[0] + M * normal[1] + N * normal[2] < 0.0:
            status = MISSED  # met from behind, from the medium after the surface: no sequential path
        if status != OK:
            ray.status, ray.surface = status, i
            break
        x, y, z = x + t * L, y + t * M, z + t * N
        opl += index[i] * t
        ray.x_mm, ray.y_mm, ray.z_mm, ray.opl_mm = x, y, sign * z + vertex_z[i], opl
        ray.L, ray.M, ray.N = L, M, sign * N
        if i == end:  # the last surface: met, not refracted
            ray.hits.append(SurfaceHit(x, y, sign * z, L, M, sign * N, 0.0, 0.0, t))
            break
        if clip and not _passes(lens, i, x, y, iris, stop_radius_mm):
            ray.status, ray.surface = VIGNETTED, i
            ray.hits.append(SurfaceHit(x, y, sign * z, L, M, sign * N, 0.0, 0.0, t))
            break
        if s.mirror:  # type: ignore[union-attr]
            status, L, M, N, ang_i, ang_r = reflect(L, M, N, normal)
        elif s.ideal_focal_mm is not None:  # type: ignore[union-attr]  # an ideal paraxial lens (local frame)
            status, L, M, N, ang_i, ang_r, added = ideal_lens(L, M, N, x, y, 1.0 / s.ideal_focal_mm, index[i],
                                                              index[i + 1])
            opl += added
            ray.opl_mm = opl
        else:
            status, L, M, N, ang_i, ang_r = refract(L, M, N, normal, index[i], index[i + 1])
        ray.hits.append(SurfaceHit(x, y, sign * z, L, M, sign * N, ang_i, ang_r, t))
        ray.L, ray.M, ray.N = L, M, sign * N
        if status != OK:
            ray.status, ray.surface = status, i
            break
        p = _to_global(frames[i], (x, y, z), sign, True)
        d = _to_global(frames[i], (L, M, N), sign, False)
    return ray
