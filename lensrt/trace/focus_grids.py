"""The ray grids of the best-focus search (:mod:`lensrt.trace.focus`), on the host or on the device.

The search lays an n x n grid of rays over each job's pupil box (a job: field point, wavelength, plane
z0), looks at which grid rays pass, and in the end needs only weighted sums of the passing rays:
those of the grid's inner cells and of sub x sub rays in each cell on the pupil's boundary. Two
implementations of the same two steps -- :meth:`grid` (trace the grids of some jobs, return which
cells passed) and :meth:`moments` (the sums, from the final pass/fail grids):

* :class:`HostGrids` -- rays built in NumPy (:func:`lensrt.trace.aiming.ray_through_point`), traced by
  the store kernel, downloaded and reduced in NumPy (any lens: the oracle, and the path of lenses the
  device kernels do not take);
* :class:`DeviceGrids` -- rays made, traced and reduced in Warp kernels
  (:mod:`lensrt.trace.kernels.focus_grid`): a grid pass downloads one byte per cell, the sums one row
  of 9 numbers per grid row or boundary cell; rotationally symmetric lenses. Each job's rays are
  traced to its own plane, and its sums added in a fixed order: a job's moments are the same bits
  whatever the other jobs of the call and on every run. They agree with the host path to rounding
  (tests/trace/test_focus_grids.py: 1e-12 relative) -- the sums are in another order, and where a
  call's jobs have several planes the host path traces to the image surface and on in a straight line.

The launches are the same for both: one per grid round, one for the boundary sub-rays.
"""
from __future__ import annotations

import os
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from .aiming import FieldPoint, ray_through_point
from .api import RayBatch, trace
from .pupil_boxes import PupilBox

__all__ = ["HostGrids", "DeviceGrids", "focus_grids", "grids_on_device", "boundary_cells", "grid_rays"]

#: (mean p (2,), mean t (2,), E[p.p], E[p.t], E[t.t], rays) of one job
Moments = tuple


def grid_rays(fp: FieldPoint, box: PupilBox, a: np.ndarray, b: np.ndarray, wavelength_nm: float):
    """Rays through the pupil-plane points (a, b) of ``box`` and their stream-kernel weights."""
    pts = box.points(a, b)
    o, d = ray_through_point(fp, pts)
    if fp.infinite:
        w = np.ones(len(d))
    else:  # the kernel's weight: cos(theta_plane) (dist / rho)^2, times cos(theta_object) (Lambertian)
        obj = np.asarray(fp.point_mm, dtype=np.float64)
        axis = np.asarray(box.axis, dtype=np.float64)
        dist = float(np.dot(np.asarray(box.centre) - obj, axis))
        rho = np.linalg.norm(pts - obj, axis=1)
        w = (d @ axis) * (dist / rho) ** 2 * d[:, 2]
    return RayBatch(o, d, wavelength_nm), w


def boundary_cells(ok: np.ndarray) -> np.ndarray:
    """Cells near the pupil's edge: within one cell (8-neighbourhood) of a cell whose centre ray's fate
    differs from a neighbour's, or passing cells on the box's border (the edge may cut a corner of a cell
    whose centre and neighbours all agree, so the band is one cell wider than the change of state)."""
    padded = np.pad(ok, 1, mode="constant", constant_values=False)
    n0, n1 = ok.shape
    differs = np.zeros_like(ok)
    for da in (-1, 0, 1):
        for db in (-1, 0, 1):
            if da or db:
                differs |= padded[1 + da:1 + da + n0, 1 + db:1 + db + n1] != ok
    band = np.pad(differs, 1, mode="constant", constant_values=False)
    near = np.zeros_like(ok)
    for da in (-1, 0, 1):
        for db in (-1, 0, 1):
            near |= band[1 + da:1 + da + n0, 1 + db:1 + db + n1]
    return near


def _cell_size(box: PupilBox, n: int) -> tuple[float, float]:
    return (box.a1 - box.a0) / n, (box.b1 - box.b0) / n


def _too_few(rays: int) -> None:
    if rays < 16:
        raise LensrtError("too few real rays reach the image to find the best focus")


class HostGrids:
    """The grids built, traced and reduced on the host (module docstring)."""

    def __init__(self, lens: Lens, jobs: Sequence[tuple[FieldPoint, float, float]], n: int, sub: int,
                 stop_radius_mm: float | None, device: str | None) -> None:
        self.lens, self.jobs, self.n, self.sub = lens, list(jobs), int(n), int(sub)
        self.stop_radius_mm, self.device = stop_radius_mm, device
        self.found: dict = {}  # job -> (positions, directions, weights) of its last grid

    def grid(self, active: Sequence[int], boxes: Sequence[PupilBox]) -> dict[int, np.ndarray]:
        """Trace the grids of jobs ``active`` over ``boxes`` (one trace); {job: (n, n) bool, the cells that passed}."""
        n, parts = self.n, []
        ia, ib = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        for k in active:
            box = boxes[k]
            da, db = _cell_size(box, n)
            parts.append(grid_rays(self.jobs[k][0], box, box.a0 + (ia.ravel() + 0.5) * da,
                                   box.b0 + (ib.ravel() + 0.5) * db, self.jobs[k][1]))
        traced = self._trace_to_planes([r for r, _ in parts], [self.jobs[k][2] for k in active])
        out = {}
        for k, (pos, d, okr), (_, w) in zip(active, traced, parts):
            self.found[k] = (pos, d, w)
            out[k] = (okr & (d[:, 2] > 0)).reshape(n, n)
        return out

    def _trace_to_planes(self, batches: list, planes_mm: list[float]) -> list:
        """(positions (m, 2) on its plane, directions (m, 3), ok (m,)) of each batch, all in one trace."""
        if not batches:
            return []
        joined = RayBatch(np.concatenate([b.origin_mm for b in batches]),
                          np.concatenate([b.direction for b in batches]),
                          np.concatenate([b.wavelength_nm for b in batches]))
        one = len(set(planes_mm)) == 1
        res = trace(self.lens, joined, "float64", self.device, stop_radius_mm=self.stop_radius_mm,
                    plane_z_mm=planes_mm[0] if one else None)
        ends = np.cumsum([0] + [len(b) for b in batches])
        out = []
        for z0, a, b in zip(planes_mm, ends[:-1], ends[1:]):
            p, d = res.position_mm[a:b], res.direction[a:b]
            if not one:  # on from the image surface to the plane z0 in a straight line
                with np.errstate(divide="ignore", invalid="ignore"):
                    p = p + ((z0 - p[:, 2]) / d[:, 2])[:, None] * d
            out.append((p[:, :2], d, res.ok[a:b]))
        return out

    def moments(self, oks: Sequence[np.ndarray], boxes: Sequence[PupilBox]) -> list[Moments]:
        """Each job's moments: its grid's inner cells, and its boundary cells as sub x sub rays (one trace)."""
        n, sub = self.n, self.sub
        pos, dirs, wts, sub_parts = {}, {}, {}, []
        off = (np.arange(sub) + 0.5) / sub
        oa, ob = np.meshgrid(off, off, indexing="ij")
        for k, ok in enumerate(oks):
            p, d, w = self.found[k]
            edge = boundary_cells(ok)
            keep = ok & ~edge
            pos[k], dirs[k], wts[k] = [p.reshape(n, n, 2)[keep]], [d.reshape(n, n, 3)[keep]], [w.reshape(n, n)[keep]]
            if edge.any():  # replace each boundary cell by sub x sub rays of 1/sub^2 of its weight
                ea, eb = np.nonzero(edge)
                box = boxes[k]
                da, db = _cell_size(box, n)
                a = (box.a0 + (ea[:, None] + oa.ravel()[None, :]) * da).ravel()
                b = (box.b0 + (eb[:, None] + ob.ravel()[None, :]) * db).ravel()
                sub_parts.append((k, grid_rays(self.jobs[k][0], box, a, b, self.jobs[k][1])))
        traced = self._trace_to_planes([r for _, (r, _) in sub_parts], [self.jobs[k][2] for k, _ in sub_parts])
        for (k, (_, sw)), (sp, sd, sok) in zip(sub_parts, traced):
            sok = sok & (sd[:, 2] > 0)
            pos[k].append(sp[sok])
            dirs[k].append(sd[sok])
            wts[k].append(sw[sok] / sub ** 2)
        out = []
        for k in range(len(self.jobs)):
            p, d, wt = np.concatenate(pos[k]), np.concatenate(dirs[k]), np.concatenate(wts[k])
            _too_few(len(p))
            t = d[:, :2] / d[:, 2:3]
            wt = wt / wt.sum()
            out.append((wt @ p, wt @ t, float(wt @ np.sum(p * p, axis=1)), float(wt @ np.sum(p * t, axis=1)),
                        float(wt @ np.sum(t * t, axis=1)), int(len(p))))
        return out


class DeviceGrids:
    """The grids made, traced and reduced in Warp kernels (module docstring; rotationally symmetric lenses)."""

    def __init__(self, lens: Lens, jobs: Sequence[tuple[FieldPoint, float, float]], n: int, sub: int,
                 stop_radius_mm: float | None, device: str | None) -> None:
        from ..device import warp
        from .kernels.focus_grid import FOCUS_CELL_COLS
        from .kernels.surfaces import SymmetricLens
        from .pack import pack_lens
        wp = warp()
        self.lens, self.jobs, self.n, self.sub = lens, list(jobs), int(n), int(sub)
        self.packed = pack_lens(lens, "float64", device, None, stop_radius_mm)
        self.dev = self.packed.device
        self.cells = wp.empty((len(self.jobs), self.n * self.n, FOCUS_CELL_COLS), dtype=wp.float64, device=self.dev)
        self.dummies = [wp.zeros((1, 1), dtype=wp.float64, device=self.dev),
                        wp.zeros((1, 1, 1), dtype=wp.float64, device=self.dev), SymmetricLens()]

    def _rows(self, boxes: Sequence[PupilBox]):
        """The jobs' rows (kernels.focus_grid module docstring), uploaded."""
        from ..core.telemetry import upload
        from ..device import warp
        from .kernels.focus_grid import FOCUS_JOB_COLS
        rows = np.zeros((len(self.jobs), FOCUS_JOB_COLS))
        for k, ((fp, wl, z0), box) in enumerate(zip(self.jobs, boxes)):
            rows[k, 0] = 1.0 if fp.infinite else 0.0
            rows[k, 1:4] = fp.direction if fp.infinite else fp.point_mm
            rows[k, 4:7], rows[k, 7:10], rows[k, 10:13], rows[k, 13:16] = box.centre, box.e1, box.e2, box.axis
            da, db = _cell_size(box, self.n)
            rows[k, 16:20] = box.a0, da, box.b0, db
            if not fp.infinite:
                obj = np.asarray(fp.point_mm, dtype=np.float64)
                rows[k, 20] = float(np.linalg.norm(obj))
                rows[k, 21] = float(np.dot(np.asarray(box.centre) - obj, np.asarray(box.axis, dtype=np.float64)))
            w_um = wl * 1.0e-3
            rows[k, 22], rows[k, 23] = w_um * w_um, z0 - self.lens.image_z_mm
        return upload(rows, warp().float64, self.dev)

    def _lens_args(self) -> list:
        """The arguments every launch starts with."""
        p = self.packed
        return [p.surf, p.media, p.iris, self.lens.n_surfaces]

    def _launch(self, kernel, total: int, head: list, tail: list) -> None:
        """One logical launch of ``total`` threads; on the CPU in slices, one per core (no shared writes)."""
        from ..core.telemetry import launch_slices
        workers = 1 if self.dev.startswith("cuda") or total < 4096 else max(1, len(os.sched_getaffinity(0)))
        cuts = [total * w // workers for w in range(workers + 1)]
        launch_slices(kernel, cuts, self.dev, lambda w, start: head + [start] + tail)

    def grid(self, active: Sequence[int], boxes: Sequence[PupilBox]) -> dict[int, np.ndarray]:
        """:meth:`HostGrids.grid` in one launch; the cells' weights, positions and slopes stay on the device."""
        from ..core.telemetry import download, upload
        from ..device import warp
        from .kernels.focus_grid import focus_grid_pass_symmetric
        wp, n = warp(), self.n
        active = list(active)
        ok = wp.zeros((len(active), n * n), dtype=wp.uint8, device=self.dev)
        head = self._lens_args() + [
            self._rows(boxes), upload(np.asarray(active, dtype=np.int32), wp.int32, self.dev), n] + self.dummies
        self._launch(focus_grid_pass_symmetric, len(active) * n * n, head, [ok, self.cells])
        got = download(ok).reshape(len(active), n, n).astype(bool)
        return {k: got[j] for j, k in enumerate(active)}

    def moments(self, oks: Sequence[np.ndarray], boxes: Sequence[PupilBox]) -> list[Moments]:
        """:meth:`HostGrids.moments` in one launch: a work item per grid row with kept cells and per boundary
        cell, its 9 sums downloaded and each job's items added in order."""
        from ..core.telemetry import download, upload
        from ..device import warp
        from .kernels.focus_grid import FOCUS_SUM_COLS, focus_sums_symmetric
        wp, n = warp(), self.n
        keep = np.zeros((len(self.jobs), n * n), dtype=np.uint8)
        items, owner = [], []
        for k, ok in enumerate(oks):
            edge = boundary_cells(ok)
            keep[k] = (ok & ~edge).ravel()
            rows = np.flatnonzero(keep[k].reshape(n, n).any(axis=1))
            cells = np.flatnonzero(edge)
            items.append(np.stack([np.full(len(rows) + len(cells), k), np.concatenate([rows, n + cells])], axis=1))
            owner.append(np.full(len(rows) + len(cells), k))
        items_host = np.concatenate(items).astype(np.int32)
        owner_host = np.concatenate(owner)
        sums_dev = wp.empty((len(items_host), FOCUS_SUM_COLS), dtype=wp.float64, device=self.dev)
        head = self._lens_args() + [self._rows(boxes), n, self.sub] + self.dummies
        tail = [upload(items_host, wp.int32, self.dev), upload(keep, wp.uint8, self.dev), self.cells, sums_dev]
        if len(items_host):
            self._launch(focus_sums_symmetric, len(items_host), head, tail)
        sums = download(sums_dev) if len(items_host) else np.zeros((0, FOCUS_SUM_COLS))
        out = []
        for k in range(len(self.jobs)):
            s = np.sum(sums[owner_host == k], axis=0) if (owner_host == k).any() else np.zeros(FOCUS_SUM_COLS)
            _too_few(int(s[8]))
            out.append((s[1:3] / s[0], s[3:5] / s[0], float(s[5] / s[0]), float(s[6] / s[0]), float(s[7] / s[0]),
                        int(s[8])))
        return out


def grids_on_device(lens: Lens, device: str | None, stop_radius_mm: float | None = None,
                    on_device: bool | None = None) -> bool:
    """Whether :func:`focus_grids` takes the device path: for rotationally symmetric lenses unless ``on_device``
    is False; ``on_device=True`` for a lens that needs the general kernel variant is one clear error."""
    from .pack import pack_lens
    use = on_device is not False and not pack_lens(lens, "float64", device, None, stop_radius_mm).general
    if on_device and not use:
        raise LensrtError("the best-focus grids run on the device for rotationally symmetric lenses only",
                          hint="leave on_device unset to take the host path for this lens")
    return use


def focus_grids(lens: Lens, jobs: Sequence[tuple[FieldPoint, float, float]], n: int, sub: int,
                stop_radius_mm: float | None, device: str | None, on_device: bool | None = None):
    """The grids of ``jobs``: :class:`DeviceGrids` where :func:`grids_on_device`, else :class:`HostGrids`."""
    use = grids_on_device(lens, device, stop_radius_mm, on_device)
    return (DeviceGrids if use else HostGrids)(lens, jobs, n, sub, stop_radius_mm, device)
