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

:func:`chief_heights` is the other search over many field points that the bokeh map used to run on the
host: for each (image height, depth) the object height whose real chief ray meets the sensor at that
height -- Newton on the aim point inside a secant on the object height, one thread per point, every
trace the shared ``trace_ray`` -- in one launch instead of a launch per Newton step of every secant
step (:func:`lensrt.analysis.bokeh.trace.object_heights_for_image` documents the algorithm, which the
host version there runs for general lenses; the arithmetic is the host's, operation for operation).
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..status import OK
from .surfaces import SymmetricLens, trace_ray

__all__ = ["box_grid_pass", "box_grid_pass_symmetric", "aim_point_ray", "BOX_FIELD_COLS", "chief_heights",
           "chief_heights_symmetric", "CHIEF_CONVERGED", "CHIEF_NO_PROBE"]

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


#: chief_heights flags: the solve met its tolerance; the near-axis probe found no chief ray (nothing else ran)
CHIEF_CONVERGED = 1
CHIEF_NO_PROBE = 2


@wp.func
def _height_on(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
               iris: wp.array(dtype=wp.float64), n_surfaces: int, y_obj: wp.float64, depth: wp.float64,
               b: wp.float64, z_ep: wp.float64, w2: wp.float64, end: int, plane_dz: wp.float64,
               table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any):
    """y where the ray from the object point (0, y_obj, -depth) through the aim point (0, b, z_ep) meets
    surface ``end`` (unclipped; the plane when end = n_surfaces), and whether it got there. The ray starts
    on the sphere through the first vertex centred on the object point, as the host's
    ``_rays_from_points`` makes it (the same operations in the same order)."""
    vy = b - y_obj
    vz = z_ep - (-depth)
    dist = wp.sqrt((wp.float64(0.0) + vy * vy) + vz * vz)
    dx = wp.float64(0.0) / dist
    dy = vy / dist
    dz = vz / dist
    r0 = wp.sqrt((wp.float64(0.0) + y_obj * y_obj) + depth * depth)
    dot = (wp.float64(0.0) + b * (b - wp.float64(2.0) * y_obj)) + z_ep * (z_ep - wp.float64(2.0) * (-depth))
    back = dot / (dist + r0)
    st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
        surf, media, iris, n_surfaces, wp.float64(0.0) - back * dx, b - back * dy, z_ep - back * dz, dx, dy, dz,
        w2, table, -1, end, 0, plane_dz, 0, rec, 0, variant)
    return y, st == int(OK)


@wp.func
def _chief_on_plane(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
                    iris: wp.array(dtype=wp.float64), n_surfaces: int, stop: int, y_obj: wp.float64,
                    depth: wp.float64, z_ep: wp.float64, h_fd: wp.float64, w2: wp.float64, plane_dz: wp.float64,
                    table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any):
    """Image height (on the plane) of the real chief ray of the object point (0, y_obj, -depth) and whether
    it was found: Newton on the aim point b until the ray crosses the stop's centre (finite-difference
    slope, at most 30 steps, |y_stop| < 1e-11 mm; found when < 1e-8 mm).

    Written as a loop with one trace per pass (the stop height at b, at b + h_fd, then the plane), so
    that the kernel holds one copy of the tracer, not one per call site."""
    b = wp.float64(0.0)
    f0 = wp.float64(0.0)
    f1 = wp.float64(0.0)
    ok = bool(False)
    ok_new = bool(False)
    ok1 = bool(False)
    h = wp.float64(0.0)
    found = bool(False)
    first = bool(True)
    it = int(0)
    phase = int(0)  # 0: stop height at b, 1: at b + h_fd, 2: the plane, 3: done
    while phase != 3:
        bb = b
        end = stop
        dz = wp.float64(0.0)
        if phase == 1:
            bb = b + h_fd
        if phase == 2:
            end = n_surfaces
            dz = plane_dz
        v, ok_v = _height_on(surf, media, iris, n_surfaces, y_obj, depth, bb, z_ep, w2, end, dz, table, rec, variant)
        if phase == 0:
            f0 = v
            ok_new = ok_v
            phase = 1
        elif phase == 1:
            f1 = v
            ok1 = ok_v
            ok = wp.where(first, ok_new, ok and ok_new)
            first = False
            phase = 2
            if it < 30 and ok and wp.abs(f0) >= wp.float64(1e-11):
                slope = (f1 - f0) / h_fd
                if ok1 and slope != wp.float64(0.0):  # else no step: the host loop would retrace b until its end
                    b = b - f0 / slope
                    it = it + 1
                    phase = 0
            if phase == 2:
                ok = ok and wp.abs(f0) < wp.float64(1e-8)
        else:
            h = v
            found = ok and ok_v
            phase = 3
    return h, found


@wp.kernel
def chief_heights(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
                  iris: wp.array(dtype=wp.float64), n_surfaces: int, stop: int, z_ep: wp.float64,
                  h_fd: wp.float64, wavelength_nm: wp.float64, plane_dz: wp.float64, tol: wp.float64,
                  image_r: wp.array(dtype=wp.float64), depths: wp.array(dtype=wp.float64),
                  table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any,
                  y_out: wp.array(dtype=wp.float64), flags: wp.array(dtype=wp.int32)):
    # one thread per (image height r, depth s): a probe near the axis gives the scale, then secant steps on
    # the object height (a start or a step into heights with no chief ray moves back toward the axis: strong
    # distortion). One chief ray per pass of the loop (one copy of the tracer); ``phase`` says which:
    # 0 the probe, 1 the start y0 (shrunk by 0.7 up to 20 times), 2 y1 = 1.001 y0, 3 a secant step y2
    # (halved back toward y1 up to 12 times), 4 done
    tid = wp.tid()
    r = image_r[tid]
    s = depths[tid]
    w_um = wavelength_nm * wp.float64(1.0e-3)
    w2 = w_um * w_um
    probe = wp.float64(1e-3) * (s + wp.abs(z_ep))
    y0 = wp.float64(0.0)
    h0 = wp.float64(0.0)
    ok0 = bool(False)
    y1 = wp.float64(0.0)
    h1 = wp.float64(0.0)
    ok1 = bool(False)
    y2 = wp.float64(0.0)
    conv = bool(False)
    flag = int(0)
    shrink = int(0)
    halve = int(0)
    it = int(0)
    y = -probe
    phase = int(0)
    while phase != 4:
        hv, ok_v = _chief_on_plane(surf, media, iris, n_surfaces, stop, y, s, z_ep, h_fd, w2, plane_dz, table, rec,
                                   variant)
        if phase == 0:
            if not ok_v or hv == wp.float64(0.0):
                flag = CHIEF_NO_PROBE
                y1 = wp.float64(0.0)
                phase = 4
            else:
                y0 = r * (-probe / hv)
                y = y0
                phase = 1
        elif phase == 1:
            h0 = hv
            ok0 = ok_v
            if not ok0 and shrink < 20:
                y0 = wp.float64(0.7) * y0
                y = y0
                shrink = shrink + 1
            else:
                y1 = y0 * wp.float64(1.001)
                y = y1
                phase = 2
        elif phase == 2 or (phase == 3 and (ok_v or halve >= 12)):
            if phase == 2:
                h1 = hv
                ok1 = ok_v
                conv = ok1 and wp.abs(h1 - r) <= tol
            else:  # the secant step's point is settled: it becomes y1
                y0 = y1
                h0 = h1
                ok0 = ok1
                y1 = y2
                h1 = hv
                ok1 = ok_v
                conv = conv or (ok1 and wp.abs(h1 - r) <= tol)
                it = it + 1
            phase = 4
            if it < 40 and ok0 and ok1 and h1 != h0 and not conv:
                y2 = y1 - (h1 - r) * (y1 - y0) / (h1 - h0)
                y = y2
                halve = 0
                phase = 3
        else:  # phase 3, a step into heights with no chief ray: halve it
            y2 = wp.float64(0.5) * (y1 + y2)
            y = y2
            halve = halve + 1
    if flag == 0 and conv:
        flag = CHIEF_CONVERGED
    y_out[tid] = y1
    flags[tid] = wp.int32(flag)


#: the instance the host calls (rotationally symmetric lenses; general lenses keep the host search)
chief_heights_symmetric = wp.overload(chief_heights, {"variant": SymmetricLens})
