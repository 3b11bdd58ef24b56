"""Which triangle of a triangulation holds each query point: a bucket grid, vectorised in NumPy.

:class:`lensrt.analysis.wave.pupil_grid.TriLinear` interpolates real-ray data linearly on the
Delaunay triangulation of the rays. Matplotlib's default point locator
(``TrapezoidMapTriFinder``) builds a trapezoid map first, which for the tens of thousands of
triangles of a wavefront's ray grid costs about as much as the triangulation itself, and each
pupil function builds two. The rays' triangles are small and of similar size, so a uniform
grid of buckets is enough: every triangle is listed in the buckets its bounding box touches,
and a query point is tested (three edge functions, inclusive) against the triangles of its
bucket only. A point on an edge shared by two triangles takes the one with the lower index;
the linear interpolant is continuous there, so which one changes the value by rounding only.
"""
from __future__ import annotations

import numpy as np

__all__ = ["BucketLocator"]


def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, k): for owner i repeated counts[i] times, k = 0 .. counts[i] - 1."""
    owner = np.repeat(np.arange(counts.size), counts)
    start = np.cumsum(counts) - counts
    return owner, np.arange(owner.size) - start[owner]


class BucketLocator:
    """Point location in a triangulation (vertices ``x``, ``y``; ``triangles`` (T, 3) vertex indices;
    triangles where ``mask`` is True are left out, as are those of zero area).

    ``find(qx, qy)`` gives the index of a triangle holding each point (boundary included), -1 where
    none does.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, triangles: np.ndarray, mask: np.ndarray | None = None) -> None:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        tri = np.asarray(triangles, dtype=np.int64)
        xt, yt = x[tri], y[tri]
        area2 = (xt[:, 1] - xt[:, 0]) * (yt[:, 2] - yt[:, 0]) - (xt[:, 2] - xt[:, 0]) * (yt[:, 1] - yt[:, 0])
        use = area2 != 0
        if mask is not None:
            use &= ~np.asarray(mask, dtype=bool)
        self.index = np.nonzero(use)[0]
        xt, yt, a2 = xt[self.index], yt[self.index], area2[self.index]
        # per triangle: its vertices, the sign that orients it anticlockwise, and a tolerance relative to
        # its size that keeps points on an edge inside
        self.pack = np.column_stack([xt, yt, np.sign(a2), 1e-12 * np.abs(a2)])
        self.nb = int(min(max(np.sqrt(max(self.index.size, 1) / 2.0), 1.0), 2048))
        lo = np.array([x.min(), y.min()]) if x.size else np.zeros(2)
        hi = np.array([x.max(), y.max()]) if x.size else np.ones(2)
        self.lo = lo
        self.step = np.where(hi > lo, (hi - lo) / self.nb, 1.0)
        i0, i1 = self._cell(xt.min(axis=1), 0), self._cell(xt.max(axis=1), 0)
        j0, j1 = self._cell(yt.min(axis=1), 1), self._cell(yt.max(axis=1), 1)
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        owner, k = _expand(ni * nj)
        bucket = (j0[owner] + k // ni[owner]) * self.nb + (i0[owner] + k % ni[owner])
        order = np.argsort(bucket, kind="stable")
        self.members = owner[order]  # triangles (local index) bucket by bucket, ascending within a bucket
        self.start = np.searchsorted(bucket[order], np.arange(self.nb * self.nb + 1))

    def _cell(self, v: np.ndarray, axis: int) -> np.ndarray:
        c = np.floor((v - self.lo[axis]) / self.step[axis]).astype(np.int64)
        return np.clip(c, 0, self.nb - 1)

    def find(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """Triangle index (into the ``triangles`` given) holding each point of (qx, qy) (flattened), -1 if none."""
        qx = np.ravel(np.asarray(qx, dtype=np.float64))
        qy = np.ravel(np.asarray(qy, dtype=np.float64))
        out = np.full(qx.size, -1, dtype=np.int64)
        if self.index.size == 0 or qx.size == 0:
            return out
        fx = (qx - self.lo[0]) / self.step[0]
        fy = (qy - self.lo[1]) / self.step[1]
        # points beyond the vertices' bounding box (or NaN) lie in no triangle
        q = np.nonzero((fx >= 0) & (fx <= self.nb) & (fy >= 0) & (fy <= self.nb))[0]
        b = np.minimum(fy[q].astype(np.int64), self.nb - 1) * self.nb + np.minimum(fx[q].astype(np.int64), self.nb - 1)
        first, count = self.start[b], self.start[b + 1] - self.start[b]
        owner, k = _expand(count)
        cand = self.members[first[owner] + k]
        px, py = qx[q][owner], qy[q][owner]
        t = self.pack[cand]  # (pairs, 8): x0 x1 x2 y0 y1 y2 sign tol
        hit = np.ones(cand.size, dtype=bool)
        for a, c in ((0, 1), (1, 2), (2, 0)):
            e = (t[:, c] - t[:, a]) * (py - t[:, 3 + a]) - (t[:, 3 + c] - t[:, 3 + a]) * (px - t[:, a])
            hit &= t[:, 6] * e >= -t[:, 7]
        # pairs run query by query, each bucket's triangles in ascending order: the first hit is the lowest
        h = np.nonzero(hit)[0]
        if h.size:
            h = h[np.r_[True, owner[h[1:]] != owner[h[:-1]]]]
            out[q[owner[h]]] = self.index[cand[h]]
        return out
