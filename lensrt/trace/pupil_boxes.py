"""Boxes of the real (vignetted) entrance pupils of many field points at once, for stream sources.

A stream source samples its rays uniformly over a rectangle in the plane through
the paraxial entrance-pupil centre perpendicular to the beam (infinite object)
or to the line from the object point (finite object). :func:`pupil_boxes` finds
that rectangle for every field point by tracing grids of rays through every
aperture -- a coarse grid over a region that surely holds the pupil (everything
that passes surface 1), then a finer grid over what passed -- so each box hugs
the *real* pupil, cat's eyes included; vignetted rays are rejected in the kernel.

All field points and wavelengths share each pass: one float64 store-kernel trace
per pass, whatever their number (a PSF map, a bokeh map, the lights of a scene); for
rotationally symmetric lenses one launch per pass (a slice per core on the CPU) that makes,
traces and reduces the grid rays on the device (:mod:`lensrt.trace.kernels.boxes`; no ray
arrays cross the bus; measured: 8.9 s -> 0.041 s for 450 sources on an H100).
The passing rays traced to the plane also give each field point's *footprint*
(the bounding box of its spot) for free. :func:`pupil_box` is the one-field
case (used by :func:`lensrt.trace.stream.stream_source`).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from functools import partial
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Iris, Lens
from ..prescription.frames import surface_frames
from .aiming import FieldPoint, aim_frames, pupil_geometry, rays_through_points

__all__ = ["PupilBox", "pupil_box", "pupil_boxes", "box_wavelengths", "coarse_grid"]

#: most rays one grid pass traces at once (its wavelengths are split into traces of at most this many)
_MAX_PASS_RAYS = 1 << 22


@dataclass(frozen=True)
class PupilBox:
    """A rectangle [a0, a1] x [b0, b1] in the aim plane through ``centre`` spanned by e1, e2 (mm)."""

    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    e1: tuple[float, float, float]
    e2: tuple[float, float, float]
    a0: float
    a1: float
    b0: float
    b1: float

    @property
    def area_mm2(self) -> float:
        return max(self.a1 - self.a0, 0.0) * max(self.b1 - self.b0, 0.0)

    def points(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        c, e1, e2 = (np.asarray(v) for v in (self.centre, self.e1, self.e2))
        return c + np.asarray(a)[:, None] * e1 + np.asarray(b)[:, None] * e2


def box_wavelengths(lens: Lens, wavelengths_nm: Sequence[float] | None) -> list[float]:
    """The wavelengths :func:`pupil_box` traces: the lens's shortest, primary and longest (default),
    else the shortest, first and longest of those given."""
    wls = list(lens.wavelengths.nm) if wavelengths_nm is None else [float(v) for v in wavelengths_nm]
    return sorted({min(wls), max(wls), lens.wavelengths.primary_nm if wavelengths_nm is None else wls[0]})


def _as_field_points(fields) -> list[FieldPoint]:
    if isinstance(fields, np.ndarray) or (len(fields) and not isinstance(fields[0], FieldPoint)):
        obj = np.atleast_2d(np.asarray(fields, dtype=np.float64))
        return [FieldPoint(False, None, tuple(float(v) for v in p)) for p in obj]
    return list(fields)


def _surface1_boxes(lens: Lens, fps: list[FieldPoint], c: np.ndarray, w: np.ndarray, e1: np.ndarray,
                    e2: np.ndarray) -> np.ndarray:
    """(S, 4) boxes a0, a1, b0, b1 in each aim plane that hold every ray passing surface 1."""
    s1 = lens.surfaces[0]
    sd = s1.semi_diameter_mm
    if sd is None:
        geom = pupil_geometry(lens)
        sd = 4.0 * geom.ep_radius_mm + abs(geom.ep_z_mm)
    sag = float(s1.sag(min(sd, s1.max_semi_diameter_mm)))
    # surface 1 in its own frame (a lens moved as a whole -- tilt-shift -- carries it in transform_before)
    o1, a1 = (np.zeros(3), np.eye(3)) if s1.transform_before is None else surface_frames(lens)[0]
    out = np.empty((len(fps), 4))
    inf = np.array([fp.infinite for fp in fps], dtype=bool)
    if inf.any():  # a collimated beam: the aperture's disc and sag, seen along the beam (any tilt: <= sd + |sag|)
        ca, cb = e1[inf] @ (o1 - c), e2[inf] @ (o1 - c)
        half = sd + abs(sag)
        out[inf] = np.stack([ca - half, ca + half, cb - half, cb + half], axis=1)
    if (~inf).any():  # an object point: the cone through the aperture's rims, projected on the plane
        obj = np.array([fp.point_mm for fp in fps if not fp.infinite], dtype=np.float64)
        wf, e1f, e2f = w[~inf], e1[~inf], e2[~inf]
        phi = np.linspace(0.0, 2.0 * np.pi, 181)
        rim = np.concatenate([np.stack([sd * np.cos(phi), sd * np.sin(phi), np.full_like(phi, z)], axis=1)
                              for z in (0.0, sag)])
        if s1.transform_before is not None:
            rim = o1 + rim @ np.asarray(a1).T
        v = rim[None, :, :] - obj[:, None, :]  # (S, M, 3)
        along = np.einsum("smk,sk->sm", v, wf)
        dist = np.einsum("sk,sk->s", c[None, :] - obj, wf)
        bad = np.any(along <= 0.0, axis=1) | (dist <= 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            proj = obj[:, None, :] + v * (dist[:, None] / along)[:, :, None] - c[None, None, :]
        a = np.einsum("smk,sk->sm", proj, e1f)
        b = np.einsum("smk,sk->sm", proj, e2f)
        pad = 0.02 * (a.max(axis=1) - a.min(axis=1) + b.max(axis=1) - b.min(axis=1))
        fin = np.stack([a.min(axis=1) - pad, a.max(axis=1) + pad, b.min(axis=1) - pad, b.max(axis=1) + pad], axis=1)
        fin[bad] = np.array([-10.0 * sd, 10.0 * sd, -10.0 * sd, 10.0 * sd])
        out[~inf] = fin
    return out


def _grid_pass(lens: Lens, fps: list[FieldPoint], c: np.ndarray, e1: np.ndarray, e2: np.ndarray, box: np.ndarray,
               n: int, wls: list[float], plane_z_mm: float | None, trace_kw: dict, device: str | None,
               field_wl: np.ndarray | None = None):
    """Trace an n x n grid over each field point's box at every wavelength (one trace for all), or
    field point k at ``field_wl[k]`` alone.

    Returns (lo, hi, cell, footprint): per field point the min/max aim coordinates (a, b) of the
    passing grid points (inf/-inf when none passed), the cell size (a, b) and the footprint
    x_min, x_max, y_min, y_max of the passing rays on the plane.
    """
    from .api import RayBatch, trace
    S = len(fps)
    t = (np.arange(n) + 0.5) / n
    ga = box[:, 0:1] + t[None, :] * (box[:, 1:2] - box[:, 0:1])  # (S, n)
    gb = box[:, 2:3] + t[None, :] * (box[:, 3:4] - box[:, 2:3])
    A = np.repeat(ga, n, axis=1)  # (S, n*n): rays of field point k are the k-th row
    B = np.tile(gb, (1, n))
    src = np.repeat(np.arange(S), n * n)
    pts = c[None, :] + A.reshape(-1, 1) * e1[src] + B.reshape(-1, 1) * e2[src]
    o, d = rays_through_points(fps, pts, src)
    ok = np.zeros((S, n * n), dtype=bool)
    foot = np.tile(np.array([np.inf, -np.inf, np.inf, -np.inf]), (S, 1))
    m = len(o)
    if field_wl is not None:  # each field point at its own wavelength: one trace
        res = trace(lens, RayBatch(o, d, np.repeat(np.asarray(field_wl, dtype=np.float64), n * n)), "float64",
                    device, plane_z_mm=plane_z_mm, **trace_kw)
        _merge_pass(res, 0, S, n, ok, foot)
        wls = []
    # the grid's copies at several wavelengths in one trace (one launch per pass unless that is over
    # _MAX_PASS_RAYS rays: a bokeh map of hundreds of sources)
    per = max(1, min(len(wls), _MAX_PASS_RAYS // max(m, 1)))
    for g in range(0, len(wls), per):
        part = wls[g:g + per]
        res = trace(lens, RayBatch(np.tile(o, (len(part), 1)), np.tile(d, (len(part), 1)),
                                   np.repeat(np.asarray(part, dtype=np.float64), m)),
                    "float64", device, plane_z_mm=plane_z_mm, **trace_kw)
        for j in range(len(part)):
            _merge_pass(res, j * m, S, n, ok, foot)
    lo = np.stack([np.where(ok, A, np.inf).min(axis=1), np.where(ok, B, np.inf).min(axis=1)], axis=1)
    hi = np.stack([np.where(ok, A, -np.inf).max(axis=1), np.where(ok, B, -np.inf).max(axis=1)], axis=1)
    cell = np.stack([(box[:, 1] - box[:, 0]) / n, (box[:, 3] - box[:, 2]) / n], axis=1)
    return lo, hi, cell, foot


def _merge_pass(res, start: int, S: int, n: int, ok: np.ndarray, foot: np.ndarray) -> None:
    """Fold the S * n * n rays of ``res`` from ``start`` on into ``ok`` (S, n*n) and the footprints ``foot`` (S, 4)."""
    got = res.ok[start:start + S * n * n].reshape(S, n * n)
    ok |= got
    for k in (0, 1):
        v = res.position_mm[start:start + S * n * n, k].reshape(S, n * n)
        foot[:, 2 * k] = np.minimum(foot[:, 2 * k], np.where(got, v, np.inf).min(axis=1))
        foot[:, 2 * k + 1] = np.maximum(foot[:, 2 * k + 1], np.where(got, v, -np.inf).max(axis=1))


def _grid_pass_device(lens: Lens, fps: list[FieldPoint], c: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                      box: np.ndarray, n: int, wls: list[float], plane_z_mm: float | None, trace_kw: dict,
                      device: str | None):
    """:func:`_grid_pass` in one launch (:mod:`lensrt.trace.kernels.boxes`); same returns. The rays are
    those of the host pass, made on the device; bounds agree with the host pass to rounding."""
    from ..core.telemetry import download, launch_slices, upload
    from ..device import warp
    from .kernels.boxes import BOX_FIELD_COLS, box_grid_pass_symmetric
    from .kernels.surfaces import SymmetricLens
    from .pack import pack_lens
    wp = warp()
    packed = pack_lens(lens, "float64", device, trace_kw.get("iris"), trace_kw.get("stop_radius_mm"))
    dev, S = packed.device, len(fps)
    rows = np.zeros((S, BOX_FIELD_COLS))
    for k, fp in enumerate(fps):
        rows[k, 0] = 1.0 if fp.infinite else 0.0
        rows[k, 1:4] = fp.direction if fp.infinite else fp.point_mm
    rows[:, 4:7], rows[:, 7:10], rows[:, 10:14] = e1, e2, box
    w_um = np.asarray(wls, dtype=np.float64) * 1.0e-3
    plane_dz = 0.0 if plane_z_mm is None else float(plane_z_mm) - lens.image_z_mm
    init = np.tile(np.array([np.inf, -np.inf, np.inf, -np.inf]), (S, 1))
    total = S * n * n * len(wls)
    # CPU atomics are plain adds: one slice of the threads and its own bounds per core
    workers = 1 if dev.startswith("cuda") else max(1, min(len(os.sched_getaffinity(0)), total // 4096))
    cuts = [total * w // workers for w in range(workers + 1)]
    args = [packed.surf, packed.media, packed.iris, lens.n_surfaces, plane_dz, upload(rows, wp.float64, dev),
            float(c[0]), float(c[1]), float(c[2]), int(n), upload(w_um * w_um, wp.float64, dev),
            wp.zeros((1, 1), dtype=wp.float64, device=dev), wp.zeros((1, 1, 1), dtype=wp.float64, device=dev),
            SymmetricLens()]
    outs = [(upload(init, wp.float64, dev), upload(init, wp.float64, dev)) for _ in range(workers)]

    launch_slices(box_grid_pass_symmetric, cuts, dev, lambda w, start: args + [start] + list(outs[w]))
    got = [(download(bo), download(fo)) for bo, fo in outs]
    b = np.stack([g[0] for g in got])
    f = np.stack([g[1] for g in got])
    b = np.stack([b[:, :, 0].min(0), b[:, :, 1].max(0), b[:, :, 2].min(0), b[:, :, 3].max(0)], axis=1)
    f = np.stack([f[:, :, 0].min(0), f[:, :, 1].max(0), f[:, :, 2].min(0), f[:, :, 3].max(0)], axis=1)
    cell = np.stack([(box[:, 1] - box[:, 0]) / n, (box[:, 3] - box[:, 2]) / n], axis=1)
    return b[:, [0, 2]], b[:, [1, 3]], cell, f


def _use_device_pass(lens: Lens, device: str | None, on_device: bool | None) -> bool:
    """The device grid pass runs for rotationally symmetric lenses (``on_device=False`` asks for the
    host pass; a general lens always takes it). On the CPU both give the same bits."""
    from .pack import pack_lens
    if on_device is False:
        return False
    return not pack_lens(lens, "float64", device).general


def _shrink(box: np.ndarray, lo: np.ndarray, hi: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """The passing region's bounds padded by 1.5 cells, within ``box``; unchanged where nothing passed."""
    lit = np.isfinite(lo[:, 0])
    out = box.copy()
    out[:, 0] = np.where(lit, np.maximum(lo[:, 0] - 1.5 * cell[:, 0], box[:, 0]), box[:, 0])
    out[:, 1] = np.where(lit, np.minimum(hi[:, 0] + 1.5 * cell[:, 0], box[:, 1]), box[:, 1])
    out[:, 2] = np.where(lit, np.maximum(lo[:, 1] - 1.5 * cell[:, 1], box[:, 2]), box[:, 2])
    out[:, 3] = np.where(lit, np.minimum(hi[:, 1] + 1.5 * cell[:, 1], box[:, 3]), box[:, 3])
    return out


def _coarse_for(lens: Lens, box1: np.ndarray, coarse: int, min_cells_across_pupil: int) -> int:
    """``coarse``, raised (up to 128) until the widest surface-1 box has ``min_cells_across_pupil`` cells
    across the paraxial entrance pupil's diameter."""
    if not min_cells_across_pupil:
        return int(coarse)
    width = float(np.max(np.maximum(box1[:, 1] - box1[:, 0], box1[:, 3] - box1[:, 2])))
    need = math.ceil(min_cells_across_pupil * width / (2.0 * pupil_geometry(lens).ep_radius_mm))
    return max(int(coarse), min(128, need))


def coarse_grid(lens: Lens, fields, coarse: int = 128, min_cells_across_pupil: int = 0) -> int:
    """The coarse grid :func:`pupil_boxes` would use for all of ``fields`` together: a caller that splits
    the field points into several calls passes it as ``coarse`` to each, so that every call uses the same
    grid (the boxes then do not depend on the split)."""
    fps = _as_field_points(fields)
    if not fps or not min_cells_across_pupil:
        return int(coarse)
    c, w, e1, e2 = aim_frames(fps, pupil_geometry(lens))
    return _coarse_for(lens, _surface1_boxes(lens, fps, c, w, e1, e2), coarse, min_cells_across_pupil)


def pupil_boxes(lens: Lens, fields, wavelengths_nm: Sequence[float] | None = None, *,
                plane_z_mm: float | None = None, iris: Iris | None = None, stop_radius_mm: float | None = None,
                device: str | None = None, coarse: int = 128, fine: int = 64, min_cells_across_pupil: int = 0,
                footprint: bool = False, on_device: bool | None = None,
                field_wavelengths_nm: Sequence[float] | None = None):
    """Real pupil boxes of many field points (module docstring).

    Parameters
    ----------
    fields : sequence of FieldPoint, or array (S, 3)
        Field points (infinite or finite), or object points in the lens frame (mm).
    wavelengths_nm : sequence of float, optional
        Every wavelength is traced (default: the lens's shortest, primary and longest).
    plane_z_mm : float, optional
        Plane of the footprints (default: the image surface).
    iris, stop_radius_mm, device
        As for :func:`lensrt.trace.trace`.
    coarse, fine : int
        Rays per side of the two grids.
    min_cells_across_pupil : int
        Raise ``coarse`` (up to 128) until the coarse grid has that many cells across the paraxial
        entrance pupil's diameter (a front element much larger than the pupil: wide angles, fisheyes).
    footprint : bool
        Also return the (S, 4) footprints x_min, x_max, y_min, y_max (mm; NaN when nothing passes).
    on_device : bool, optional
        Run each grid pass as one kernel launch that makes, traces and reduces the grid rays on the
        device (:mod:`lensrt.trace.kernels.boxes`; default: for rotationally symmetric lenses)
        instead of host arrays traced by the store kernel.
    field_wavelengths_nm : sequence of float, optional
        One wavelength (nm) per field point: field point k is traced at that wavelength alone, instead of
        at ``wavelengths_nm`` (the boxes of one field point at several wavelengths, repeated in ``fields``);
        always the host pass.

    Returns
    -------
    list of PupilBox (area 0 where no ray passes), and the footprints when asked for.
    """
    fps = _as_field_points(fields)
    if not fps:
        return ([], np.zeros((0, 4))) if footprint else []
    wls = sorted({float(v) for v in (wavelengths_nm if wavelengths_nm is not None
                                     else box_wavelengths(lens, None))})
    c, w, e1, e2 = aim_frames(fps, pupil_geometry(lens))
    kw = {"iris": iris, "stop_radius_mm": stop_radius_mm}
    box1 = _surface1_boxes(lens, fps, c, w, e1, e2)
    coarse = _coarse_for(lens, box1, coarse, min_cells_across_pupil)
    fw = None if field_wavelengths_nm is None else np.asarray(field_wavelengths_nm, dtype=np.float64)
    if fw is not None and fw.shape != (len(fps),):
        raise LensrtError(f"field_wavelengths_nm has {fw.size} values for {len(fps)} field points",
                          hint="give one wavelength per field point")
    if fw is None and _use_device_pass(lens, device, on_device):
        grid_pass = _grid_pass_device
    else:  # the host pass (a wavelength per field point, or a general lens)
        grid_pass = partial(_grid_pass, field_wl=fw)
    lo, hi, cell, foot = grid_pass(lens, fps, c, e1, e2, box1, coarse, wls, plane_z_mm, kw, device)
    lit = np.isfinite(lo[:, 0])
    box2 = _shrink(box1, lo, hi, cell)
    lo2, hi2, cell2, foot2 = grid_pass(lens, fps, c, e1, e2, box2, fine, wls, plane_z_mm, kw, device)
    lit2 = np.isfinite(lo2[:, 0])
    final = _shrink(box2, lo2, hi2, cell2)  # a sliver the fine grid missed keeps the coarse box
    foot = np.where(lit2[:, None], foot2, foot)
    boxes = []
    ct = tuple(float(v) for v in c)
    for k in range(len(fps)):
        a0, a1, b0, b1 = (float(v) for v in final[k]) if lit[k] else (0.0, 0.0, 0.0, 0.0)
        boxes.append(PupilBox(ct, tuple(float(v) for v in w[k]), tuple(float(v) for v in e1[k]),
                              tuple(float(v) for v in e2[k]), a0, a1, b0, b1))
    if not footprint:
        return boxes
    foot[~lit] = np.nan
    return boxes, foot


def pupil_box(lens: Lens, fp: FieldPoint, wavelengths_nm: Sequence[float] | None = None, *,
              iris: Iris | None = None, stop_radius_mm: float | None = None, device: str | None = None,
              coarse: int = 128, fine: int = 64) -> PupilBox:
    """The box of the real (vignetted) entrance pupil of field point ``fp`` (:func:`pupil_boxes` for one).

    Traced in float64 with every aperture, at :func:`box_wavelengths`. An empty box (area 0) means
    no ray gets through.
    """
    if not isinstance(fp, FieldPoint):
        raise LensrtError("pupil_box needs a FieldPoint (lensrt.trace.aiming.field_point)")
    return pupil_boxes(lens, [fp], box_wavelengths(lens, wavelengths_nm), iris=iris, stop_radius_mm=stop_radius_mm,
                       device=device, coarse=coarse, fine=fine)[0]
