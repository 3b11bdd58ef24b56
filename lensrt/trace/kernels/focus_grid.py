"""The best-focus search's ray grids on the device: rays made, traced and reduced to sums in the kernel.

:func:`lensrt.trace.focus.focus_moments_fields` lays an n x n grid over each job's pupil box,
finds the pupil's boundary cells from the grid rays' fates and replaces each boundary cell by
sub x sub rays; what it needs of the rays is only weighted sums (first and second moments of
positions and slopes on a plane). On the host that is ~1.3 million rays per call built in NumPy,
uploaded, traced, downloaded and reduced. Here:

* :func:`focus_grid_pass` -- one thread per (job, grid cell): makes the cell-centre ray exactly
  as :func:`lensrt.trace.aiming.ray_through_point` does (the object-point weight of
  :func:`lensrt.trace.focus_grids.grid_rays` with it), traces it with the shared ``trace_ray`` (float64, every
  aperture) to the job's plane, writes whether it passed (one byte per cell: the only download)
  and keeps its weight, position and slopes on the device;
* :func:`focus_sums` -- one thread per work item, an item being either one grid row of a job (the
  kept inner cells of that row, read back from the grid pass) or one boundary cell (its sub x sub
  rays made and traced in the thread); each item writes its 9 sums (weight, weighted x, y, slopes
  x, y, p.p, p.t, t.t, and the number of passing rays) in a fixed order. The host adds the items
  of a job in a fixed order too: no atomics, the same bits on every run (the sums are in another
  order than the host path's, so they agree with it to rounding, ~1e-15 relative).

Each job's row of ``jobs`` (:data:`FOCUS_JOB_COLS` float64): infinite flag, beam direction (3) or
object point (3), aim-plane centre (3), e1 (3), e2 (3), beam axis (3), a0, da, b0, db (the grid's
first cell edge and cell size), |object point| (mm; 0 at infinity), (centre - object) . axis (mm),
wavelength^2 (um^2), the plane's distance behind the image surface (mm): each job's rays are traced
to its own plane, so a job's sums do not depend on the other jobs of the launch. Rotationally
symmetric lenses only (plane image square to the axis); the caller keeps the host path for the
others. float64 only.
"""
# No ``from __future__ import annotations`` here: Warp reads the annotations as objects.

from typing import Any

import warp as wp

from ..status import OK
from .boxes import aim_point_ray
from .surfaces import SymmetricLens, trace_ray

__all__ = ["focus_grid_pass", "focus_grid_pass_symmetric", "focus_sums", "focus_sums_symmetric",
           "FOCUS_JOB_COLS", "FOCUS_SUM_COLS", "FOCUS_CELL_COLS"]

wp.set_module_options({"enable_backward": False})

#: one work item's running sums (FOCUS_SUM_COLS of them)
vec9d = wp.types.vector(length=9, dtype=wp.float64)

#: columns of a job's row (module docstring)
FOCUS_JOB_COLS = 24
#: sums per work item: weight, w x, w y, w tx, w ty, w p.p, w p.t, w t.t, passing rays
FOCUS_SUM_COLS = 9
#: kept per grid cell on the device: weight, x, y, tx, ty (valid where the cell's ray passed)
FOCUS_CELL_COLS = 5


@wp.func
def _focus_ray(jobs: wp.array2d(dtype=wp.float64), k: int, a: wp.float64, b: wp.float64):
    """Job k's ray through the aim-plane point (a, b): origin, direction and its stream-kernel weight."""
    px = jobs[k, 4] + a * jobs[k, 7] + b * jobs[k, 10]
    py = jobs[k, 5] + a * jobs[k, 8] + b * jobs[k, 11]
    pz = jobs[k, 6] + a * jobs[k, 9] + b * jobs[k, 12]
    ox, oy, oz, dx, dy, dz, dist = aim_point_ray(jobs[k, 0], jobs[k, 1], jobs[k, 2], jobs[k, 3], px, py, pz,
                                                 jobs[k, 20])
    weight = wp.float64(1.0)
    if jobs[k, 0] == wp.float64(0.0):  # cos(theta_plane) (dist / rho)^2 x cos(theta_object), as grid_rays
        ratio = jobs[k, 21] / dist
        weight = (dx * jobs[k, 13] + dy * jobs[k, 14] + dz * jobs[k, 15]) * (ratio * ratio) * dz
    return ox, oy, oz, dx, dy, dz, weight


@wp.func
def _focus_trace(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
                 iris: wp.array(dtype=wp.float64), n_surfaces: int, jobs: wp.array2d(dtype=wp.float64), k: int,
                 ox: wp.float64, oy: wp.float64, oz: wp.float64, dx: wp.float64, dy: wp.float64, dz: wp.float64,
                 table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any):
    """Trace one ray to job k's plane: (passed with N > 0, x, y on the plane, slopes L/N, M/N)."""
    st, where, x, y, z, L, M, N, opl, min_cos = trace_ray(
        surf, media, iris, n_surfaces, ox, oy, oz, dx, dy, dz, jobs[k, 22], table, -1, n_surfaces, 1, jobs[k, 23],
        0, rec, 0, variant)
    passed = int(0)
    tx = wp.float64(0.0)
    ty = wp.float64(0.0)
    if st == int(OK) and N > wp.float64(0.0):
        passed = int(1)
        tx = L / N
        ty = M / N
    return passed, x, y, tx, ty


@wp.kernel
def focus_grid_pass(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
                    iris: wp.array(dtype=wp.float64), n_surfaces: int, jobs: wp.array2d(dtype=wp.float64),
                    active: wp.array(dtype=wp.int32), n: int,
                    table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any,
                    tid_base: int, ok: wp.array2d(dtype=wp.uint8), cells: wp.array3d(dtype=wp.float64)):
    tid = wp.tid() + tid_base
    nn = n * n
    j = tid // nn
    m = tid - j * nn
    k = active[j]
    a = jobs[k, 16] + (wp.float64(m // n) + wp.float64(0.5)) * jobs[k, 17]
    b = jobs[k, 18] + (wp.float64(m % n) + wp.float64(0.5)) * jobs[k, 19]
    ox, oy, oz, dx, dy, dz, weight = _focus_ray(jobs, k, a, b)
    passed, x, y, tx, ty = _focus_trace(surf, media, iris, n_surfaces, jobs, k, ox, oy, oz, dx, dy, dz, table, rec,
                                        variant)
    ok[j, m] = wp.uint8(passed)
    cells[k, m, 0] = weight
    cells[k, m, 1] = x
    cells[k, m, 2] = y
    cells[k, m, 3] = tx
    cells[k, m, 4] = ty


@wp.func
def _one_ray(w: wp.float64, x: wp.float64, y: wp.float64, tx: wp.float64, ty: wp.float64):
    """One passing ray of weight w as the sums it adds (FOCUS_SUM_COLS)."""
    return vec9d(w, w * x, w * y, w * tx, w * ty, w * (x * x + y * y), w * (x * tx + y * ty), w * (tx * tx + ty * ty),
                 wp.float64(1.0))


@wp.kernel
def focus_sums(surf: wp.array2d(dtype=wp.float64), media: wp.array2d(dtype=wp.float64),
               iris: wp.array(dtype=wp.float64), n_surfaces: int, jobs: wp.array2d(dtype=wp.float64), n: int,
               sub: int,
               table: wp.array2d(dtype=wp.float64), rec: wp.array3d(dtype=wp.float64), variant: Any, tid_base: int,
               items: wp.array2d(dtype=wp.int32), keep: wp.array2d(dtype=wp.uint8),
               cells: wp.array3d(dtype=wp.float64), sums: wp.array2d(dtype=wp.float64)):
    i = wp.tid() + tid_base
    k = items[i, 0]
    c = items[i, 1]
    acc = vec9d()
    if c < n:  # grid row c: its kept inner cells, as the grid pass left them
        for col in range(n):
            m = c * n + col
            if keep[k, m] != wp.uint8(0):
                acc = acc + _one_ray(cells[k, m, 0], cells[k, m, 1], cells[k, m, 2], cells[k, m, 3], cells[k, m, 4])
    else:  # boundary cell c - n: sub x sub rays, each of 1/sub^2 of the cell's weight
        m = c - n
        ia = wp.float64(m // n)
        ib = wp.float64(m % n)
        share = wp.float64(sub * sub)
        for s in range(sub * sub):
            fa = (wp.float64(s // sub) + wp.float64(0.5)) / wp.float64(sub)
            fb = (wp.float64(s % sub) + wp.float64(0.5)) / wp.float64(sub)
            a = jobs[k, 16] + (ia + fa) * jobs[k, 17]
            b = jobs[k, 18] + (ib + fb) * jobs[k, 19]
            ox, oy, oz, dx, dy, dz, weight = _focus_ray(jobs, k, a, b)
            passed, x, y, tx, ty = _focus_trace(surf, media, iris, n_surfaces, jobs, k, ox, oy, oz, dx, dy, dz, table,
                                                rec, variant)
            if passed != 0:
                acc = acc + _one_ray(weight / share, x, y, tx, ty)
    for q in range(9):
        sums[i, q] = acc[q]


#: the instances the host calls (rotationally symmetric lenses)
focus_grid_pass_symmetric = wp.overload(focus_grid_pass, {"variant": SymmetricLens})
focus_sums_symmetric = wp.overload(focus_sums, {"variant": SymmetricLens})
