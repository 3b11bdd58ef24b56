"""Triangles of rays traced on a regular grid: two a cell, by the grid's own topology.

A wavefront's rays start on an m x m grid over the pupil box (:mod:`lensrt.analysis.pupil_rays`) and land at
smoothly mapped pupil positions (px, py). Their linear interpolant needs a triangulation; a Delaunay
triangulation of the scattered positions (qhull, O(N log N)) costs ~50 ms for a 128 x 128 grid and was the
largest host cost of a pupil function. The grid already says which rays are neighbours, so
:func:`grid_triangles` cuts each grid cell whose four corner rays are present into two triangles, and a cell
with three present corners into the one triangle they span -- about 2 ms, vectorised.

The diagonal of a four-corner cell is chosen by the Delaunay rule (the empty-circumcircle test on the cell's
four points), so wherever the mapped cells are convex and the choice is not a tie, the triangles are the
Delaunay triangles of the same rays. Two things differ from a Delaunay triangulation of the scattered
positions, both at the size of the linear interpolation error itself:

* **ties** -- a cell whose four corners are cocircular (a cell straddling a symmetry line of the pupil is an
  isosceles trapezoid) has two Delaunay triangulations; qhull picks one by rounding, :func:`grid_triangles` the
  diagonal from the cell's first corner (row i, column j) to its opposite corner;
* **the hull** -- a Delaunay triangulation covers the convex hull of the points: along a staircase edge of the
  grid (the rim of a circular pupil cut out of the square ray grid) it adds thin triangles joining rays many
  cells apart. The grid triangles stop at the rays' own outline; points between the outline and the hull are
  outside, which :func:`lensrt.analysis.wave.pupil_grid.pupil_from_rays` fills by its local quadratic fit as it
  does every point outside the triangles.

:class:`GridLinear` interpolates on these triangles. A pupil function interpolates on two of them, the mesh of
every placed ray (the "ray passed" flag, for the aperture) and the mesh of the valid rays (OPD, amplitude);
both cut a cell with four corners along the same diagonal, so one point location in the first serves both:
a point in a cell whose four corners are valid lies in the same triangle of either mesh, in a cell with
three valid corners it is tested against their triangle. Locations are kept for the last query points, which
the aperture, the OPD and the amplitude share.
"""
from __future__ import annotations

import hashlib
import threading

import numpy as np

from ...errors import LensrtError

__all__ = ["grid_triangles", "GridLinear"]


def _orient(x: np.ndarray, y: np.ndarray, p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles (p, q, r): > 0 anticlockwise."""
    return (x[q] - x[p]) * (y[r] - y[p]) - (x[r] - x[p]) * (y[q] - y[p])


def _incircle(x: np.ndarray, y: np.ndarray, p: np.ndarray, q: np.ndarray, r: np.ndarray,
              s: np.ndarray) -> np.ndarray:
    """The in-circle determinant: > 0 where s lies inside the circle through anticlockwise (p, q, r)."""
    ax, ay = x[p] - x[s], y[p] - y[s]
    bx, by = x[q] - x[s], y[q] - y[s]
    cx, cy = x[r] - x[s], y[r] - y[s]
    return ((ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay)
            + (cx * cx + cy * cy) * (ax * by - bx * ay))


def _cell_triangles(x: np.ndarray, y: np.ndarray, present: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(triangles (T, 3), cell (T,)): :func:`grid_triangles` and the flat index (i * (m1 - 1) + j) of each
    triangle's cell."""
    m0, m1 = x.shape
    if m0 < 2 or m1 < 2:
        return np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    idx = np.arange(m0 * m1, dtype=np.int64).reshape(m0, m1)
    # the cell's corners in order around it: a = (i, j), b = (i+1, j), c = (i+1, j+1), d = (i, j+1)
    a, b, c, d = (v.ravel() for v in (idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]))
    cell = np.arange(a.size, dtype=np.int64)
    have = present.ravel()
    pa, pb, pc, pd = have[a], have[b], have[c], have[d]
    full = np.nonzero(pa & pb & pc & pd)[0]
    xf = np.where(have, x.ravel(), 0.0)
    yf = np.where(have, y.ravel(), 0.0)
    fa, fb, fc, fd = a[full], b[full], c[full], d[full]
    # diagonal a-c unless d lies strictly inside the circumcircle of (a, b, c): then b-d is the Delaunay edge
    flip = _incircle(xf, yf, fa, fb, fc, fd) * np.sign(_orient(xf, yf, fa, fb, fc)) > 0
    keep = ~flip
    parts = [np.stack([fa[keep], fb[keep], fc[keep]], axis=1), np.stack([fa[keep], fc[keep], fd[keep]], axis=1),
             np.stack([fa[flip], fb[flip], fd[flip]], axis=1), np.stack([fb[flip], fc[flip], fd[flip]], axis=1)]
    cells = [full[keep], full[keep], full[flip], full[flip]]
    three = (pa.astype(np.int8) + pb + pc + pd) == 3
    for missing, corners in ((pa, (b, c, d)), (pb, (a, c, d)), (pc, (a, b, d)), (pd, (a, b, c))):
        sel = np.nonzero(three & ~missing)[0]
        parts.append(np.stack([v[sel] for v in corners], axis=1))
        cells.append(sel)
    return np.concatenate(parts).astype(np.int64, copy=False), np.concatenate(cells)


def grid_triangles(x: np.ndarray, y: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of flat indices into the (m0, m1) grid of points (``x``, ``y``) where ``present``.

    Parameters
    ----------
    x, y : arrays (m0, m1)
        Positions of the grid's points (any unit); entries that are not ``present`` are ignored.
    present : bool array (m0, m1)
        Which points exist (e.g. the rays that reached the image).

    Returns
    -------
    int64 array (T, 3)
        Per cell (i, j)-(i+1, j+1) with four present corners two triangles, split along the diagonal the
        Delaunay rule picks (corner (i, j) to (i+1, j+1) on a tie); with three present corners the one they
        span; none otherwise. Grouped: the cells split along (i, j)-(i+1, j+1), those split the other way,
        then the three-corner cells; a triangle's orientation is the grid's (either sign).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    present = np.asarray(present, dtype=bool)
    if not (x.shape == y.shape == present.shape) or x.ndim != 2:
        raise LensrtError(f"grid_triangles needs three arrays of one 2-D shape, not {x.shape}, {y.shape}, "
                          f"{present.shape}")
    return _cell_triangles(x, y, present & np.isfinite(x) & np.isfinite(y))[0]


def _key(*arrays: np.ndarray) -> bytes:
    h = hashlib.blake2b(digest_size=20)
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
        h.update(b"|")
    return h.digest()


class GridLinear:
    """Piecewise-linear interpolation of ray data on the triangles of the ray grid (:func:`grid_triangles`).

    Parameters
    ----------
    m : int
        The rays were traced on an m x m grid.
    index : int array (k,)
        Each ray's flat index in it (distinct, 0 .. m*m - 1).
    x, y : arrays (k,)
        The rays' positions (e.g. normalised pupil coordinates); rays with a non-finite position are left out.

    Notes
    -----
    :meth:`interp` takes values on the k rays and, optionally, the subset of rays to interpolate between
    (``use``): the answer is that of ``GridLinear`` built on those rays alone (module docstring), from one
    point location. Near-degenerate triangles (area below 1e-6 of the median) are left out, as
    :class:`~lensrt.analysis.wave.pupil_grid.TriLinear` masks them. :meth:`of` returns the same object for the
    same rays (the most recent :attr:`KEEP`).
    """

    _recent: "dict[bytes, GridLinear]" = {}
    _lock = threading.Lock()
    #: meshes :meth:`of` keeps (the most recent ones)
    KEEP = 8

    @classmethod
    def of(cls, m: int, index: np.ndarray, x: np.ndarray, y: np.ndarray) -> "GridLinear":
        """``GridLinear(m, index, x, y)``, the same object again for the same rays (by content)."""
        index = np.ascontiguousarray(index, dtype=np.int64)
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        key = _key(np.asarray([int(m)]), index, x, y)
        with cls._lock:
            hit = cls._recent.get(key)
        if hit is not None:
            return hit
        made = cls(m, index, x, y)
        with cls._lock:
            cls._recent[key] = made
            while len(cls._recent) > cls.KEEP:
                cls._recent.pop(next(iter(cls._recent)))
        return made

    def __init__(self, m: int, index: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        m = int(m)
        index = np.ravel(np.asarray(index, dtype=np.int64))
        x = np.ravel(np.asarray(x, dtype=np.float64))
        y = np.ravel(np.asarray(y, dtype=np.float64))
        if m < 2 or not (index.size == x.size == y.size):
            raise LensrtError(f"a ray grid needs m >= 2 and one grid index per ray (m = {m}, {index.size} indices "
                              f"for {x.size} rays)")
        slot = np.full(m * m, -1, dtype=np.int64)
        if index.size and (index.min() < 0 or index.max() >= m * m):
            raise LensrtError(f"ray grid indices must lie in 0 .. {m * m - 1} for a {m} x {m} grid")
        slot[index] = np.arange(index.size)
        if np.count_nonzero(slot >= 0) != index.size:
            raise LensrtError("two rays have the same ray grid index", hint="give each ray its own grid cell")
        gx, gy = np.zeros(m * m), np.zeros(m * m)
        gx[index], gy[index] = x, y
        present = (slot >= 0) & np.isfinite(gx) & np.isfinite(gy)
        tris, cell = _cell_triangles(gx.reshape(m, m), gy.reshape(m, m), present.reshape(m, m))
        if len(tris) == 0:
            raise LensrtError("cannot triangulate the pupil rays: no cell of the ray grid has three rays",
                              hint="trace more pupil rays")
        xt, yt = gx[tris], gy[tris]
        area = np.abs((xt[:, 1] - xt[:, 0]) * (yt[:, 2] - yt[:, 0]) - (xt[:, 2] - xt[:, 0]) * (yt[:, 1] - yt[:, 0]))
        self.min_area = 1e-6 * float(np.median(area))
        good = area > self.min_area
        self.m, self.index, self.gx, self.gy, self.present = m, index, gx, gy, present
        self.triangles, self.cell = tris[good], cell[good]   # vertices as flat grid indices
        self._locator = None
        self._found: dict[bytes, np.ndarray] = {}
        self._found_lock = threading.Lock()

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        for k in ("_found_lock", "_found", "_locator"):   # a lock cannot be pickled; caches are rebuilt
            state.pop(k, None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._locator, self._found, self._found_lock = None, {}, threading.Lock()

    def find(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """The triangle (row of :attr:`triangles`) holding each point of (qx, qy), flattened; -1 outside.
        The answers for the last three sets of query points are kept (by content)."""
        from .point_location import BucketLocator
        qx = np.ravel(np.asarray(qx, dtype=np.float64))
        qy = np.ravel(np.asarray(qy, dtype=np.float64))
        key = _key(qx, qy)
        with self._found_lock:   # a mesh from :meth:`of` may serve several analysis threads
            hit = self._found.get(key)
            if hit is not None:
                return hit
            if self._locator is None:
                self._locator = BucketLocator(self.gx, self.gy, self.triangles)
        t = self._locator.find(qx, qy)
        with self._found_lock:
            self._found[key] = t
            while len(self._found) > 3:
                self._found.pop(next(iter(self._found)))
        return t

    def interp(self, values: np.ndarray, qx: np.ndarray, qy: np.ndarray, fill: float = np.nan,
               use: np.ndarray | None = None) -> np.ndarray:
        """Values (k,) on the rays interpolated at (qx, qy); ``fill`` outside the triangles. ``use`` (k,) bool:
        interpolate between those rays only (the mesh of the ``use`` rays)."""
        qx = np.asarray(qx, dtype=np.float64)
        shape = qx.shape
        x, y = np.ravel(qx), np.ravel(np.asarray(qy, dtype=np.float64))
        t = self.find(x, y)
        hit = np.nonzero(t >= 0)[0]
        verts = self.triangles[t[hit]]
        v = np.full(self.m * self.m, np.nan)
        v[self.index] = np.ravel(np.asarray(values, dtype=np.float64))
        if use is not None:
            on = np.zeros(self.m * self.m, dtype=bool)
            on[self.index] = np.ravel(np.asarray(use, dtype=bool))
            on &= self.present
            keep, verts = self._subset(on, t[hit], verts, x[hit], y[hit])
            hit = hit[keep]
        out = np.full(x.size, np.nan)
        out[hit] = self._planar(verts, v, x[hit], y[hit])[1]
        out[~np.isfinite(out)] = fill
        return out.reshape(shape)

    def _subset(self, on: np.ndarray, tri: np.ndarray, verts: np.ndarray, x: np.ndarray,
                y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which points (x, y) -- in triangles ``tri`` of the full mesh, vertices ``verts`` -- the mesh of the
        ``on`` rays holds (bool), and their triangles in it: the same triangle where the cell's four corners
        are on, the triangle of the three that are where one is off (the point tested against it), none where
        fewer are on."""
        m = self.m
        i, j = np.divmod(self.cell[tri], m - 1)
        a = i * m + j
        corners = np.stack([a, a + m, a + m + 1, a + 1], axis=1)  # (i, j), (i+1, j), (i+1, j+1), (i, j+1)
        flags = on[corners]
        count = flags.sum(axis=1)
        keep = count == 4
        three = np.nonzero(count == 3)[0]
        if three.size:
            order = np.argsort(~flags[three], axis=1, kind="stable")[:, :3]   # the three corners that are on
            tri3 = np.take_along_axis(corners[three], order, axis=1)
            (l1, l2), area2 = self._planar(tri3, None, x[three], y[three])[0], self._area2(tri3)
            tol = 1e-12
            inside = (l1 >= -tol) & (l2 >= -tol) & (l1 + l2 <= 1.0 + tol) & (np.abs(area2) > self.min_area)
            verts = verts.copy()
            verts[three] = tri3
            keep[three[inside]] = True
        return keep, verts[keep]

    def _area2(self, verts: np.ndarray) -> np.ndarray:
        xt, yt = self.gx[verts], self.gy[verts]
        return (xt[:, 1] - xt[:, 0]) * (yt[:, 2] - yt[:, 0]) - (xt[:, 2] - xt[:, 0]) * (yt[:, 1] - yt[:, 0])

    def _planar(self, verts: np.ndarray, v: np.ndarray | None, x: np.ndarray, y: np.ndarray):
        """((l1, l2), value): barycentric coordinates of (x, y) in the triangles ``verts`` (weights of their
        second and third vertex) and the linear interpolant of ``v`` there (None without ``v``)."""
        x0, y0 = self.gx[verts[:, 0]], self.gy[verts[:, 0]]
        ux, uy = self.gx[verts[:, 1]] - x0, self.gy[verts[:, 1]] - y0
        wx, wy = self.gx[verts[:, 2]] - x0, self.gy[verts[:, 2]] - y0
        dx, dy = x - x0, y - y0
        with np.errstate(divide="ignore", invalid="ignore"):
            det = ux * wy - wx * uy
            l1 = (dx * wy - wx * dy) / det
            l2 = (ux * dy - dx * uy) / det
        if v is None:
            return (l1, l2), None
        v0 = v[verts[:, 0]]
        return (l1, l2), v0 + l1 * (v[verts[:, 1]] - v0) + l2 * (v[verts[:, 2]] - v0)
