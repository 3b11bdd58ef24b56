"""The pupil-box grid pass on the device: grid rays made, traced and reduced in one launch.

:func:`lensrt.trace.pupil_boxes.pupil_boxes` traces an n x n grid over each field point's box
at every wavelength and keeps, per field point, the bounds of the passing grid points (aim
coordinates a, b) and of their footprint on a plane. On the host that is arrays of S n^2 rays
built, uploaded, traced and downloaded per wavelength -- seconds for a bokeh map's hundreds of
sources. :func:`box_grid_pass` does it in one launch: one thread per (field point, grid point,
wavelength) makes its ray exactly as :func:`lensrt.trace.aiming.rays_through_points` does,
traces it with the shared ``trace_ray`` (float64, clipping, to the plane) and folds a passing
ray into its field point's bounds with atomic min/max (order-free: the same bounds whatever the
thread order; on the CPU, where Warp's atomics are plain adds, each worker thread launches a
slice of the threads into its own bounds, folded with min/max on the host). Rotationally symmetric lenses only (the footprint is read in the image
surface's frame); the caller keeps the host pass for the others.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..status import OK
from .surfaces import SymmetricLens, trace_ray

__all__ = ["box_grid_pass", "box_grid_pass_symmetric", "aim_point_ray", "BOX_FIELD_COLS"]

wp.set_module_options({"enable_backward": False})

#: per field point: infinite flag, direction (3) or object point (3), e1 (3), e2 (3), box a0 a1 b0 b1
BOX_FIELD_COLS = 14


@wp.func
def aim_point_ray(infinite: wp.float64, fx: wp.float64, fy: wp.float64, fz: wp.float64, px: wp.float64,
                  py: wp.float64, pz: wp.float64, r0: wp.float64):
    """The ray of a field point through the aim-plane point p, as :func:`lensrt.trace.aiming.ray_through_point`
    makes it: (origin, direction, distance object -> p). ``infinite`` != 0: a collimated beam along f, started
    at the foot of p on the plane through 0 normal to it (distance 0); else from the object point f (|f| =
    ``r0``) through p, started on the sphere |x - f| = |f| without cancellation."""
    if infinite != wp.float64(0.0):
        s = px * fx + py * fy + pz * fz
        return px - s * fx, py - s * fy, pz - s * fz, fx, fy, fz, wp.float64(0.0)
    vx = px - fx
    vy = py - fy
    vz = pz - fz
    dist = wp.sqrt(vx * vx + vy * vy + vz * vz)
    dx = vx / dist
    dy = vy / dist
    dz = vz / dist
    back = ((px * px + py * py + pz * pz) - wp.float64(2.0) * (px * fx + py * fy + pz * fz)) / (dist + r0)
    return px - back * dx, py - back * dy, pz - back * dz, dx, dy, dz, dist


@wp.kernel
def box_grid_pass(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
                  iris: wp.array(dtype=wp.float64), n_surfaces: int, plane_dz: wp.float64,
                  fields: wp.array2d(dtype=wp.float64), cx: wp.float64, cy: wp.float64, cz: wp.float64,
                  n: int, w2s: wp.array(dtype=wp.float64), table: wp.array2d(dtype=wp.float64),
                  rec: wp.array3d(dtype=wp.float64), variant: Any, tid_base: int,
                  bounds: wp.array2d(dtype=wp.float64), foot: wp.array2d(dtype=wp.float64)):
    tid = wp.tid() + tid_base
    nn = n * n
    k = tid // (nn * w2s.shape[0])
    rest = tid - k * nn * w2s.shape[0]
    wl = rest // nn
    m = rest - wl * nn
    t_a = (wp.float64(m // n) + wp.float64(0.5)) / wp.float64(n)
    t_b = (wp.float64(m % n) + wp.float64(0.5)) / wp.float64(n)
    a = fields[k, 10] + t_a * (fields[k, 11] - fields[k, 10])
    b = fields[k, 12] + t_b * (fields[k, 13] - fields[k, 12])
    px = cx + a * fields[k, 4] + b * fields[k, 7]
    py = cy + a * fields[k, 5] + b * fields[k, 8]
    pz = cz + a * fields[k, 6] + b * fields[k, 9]
    r0 = wp.sqrt(fields[k, 1] * fields[k, 1] + fields[k, 2] * fields[k, 2] + fields[k, 3] * fields[k, 3])
    ox, oy, oz, dx, dy, dz, dist = aim_point_ray(fields[k, 0], fields[k, 1], fields[k, 2], fields[k, 3], px, py, pz,
                                                 r0)
    st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
        surf, media, iris, n_surfaces, ox, oy, oz, dx, dy, dz, w2s[wl], table, -1, n_surfaces, 1, plane_dz,
        0, rec, 0, variant)
    if st == int(OK):
        wp.atomic_min(bounds, k, 0, a)
        wp.atomic_max(bounds, k, 1, a)
        wp.atomic_min(bounds, k, 2, b)
        wp.atomic_max(bounds, k, 3, b)
        wp.atomic_min(foot, k, 0, x)
        wp.atomic_max(foot, k, 1, x)
        wp.atomic_min(foot, k, 2, y)
        wp.atomic_max(foot, k, 3, y)


#: the instance the host calls (rotationally symmetric lenses)
box_grid_pass_symmetric = wp.overload(box_grid_pass, {"variant": SymmetricLens})
