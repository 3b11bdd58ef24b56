"""Best focus: the one routine every table, ``--focus best`` and the render use.

Best focus is the plane z that minimises the RMS spot radius (about its centroid) of one field point (the
axis by default), over the rays that fill its real pupil uniformly (weighted as the stream kernel weights
them: uniform in the pupil plane for an object at infinity, Lambertian x inverse-square for a finite one),
with several wavelengths pooled by their weights (each wavelength's rays carry its weight in total).

The search in z has a closed form: a ray that meets the plane z0 at p with slopes t = (L/N, M/N) meets
z0 + dz at p + dz t, so the mean square radius is var(p) + 2 dz cov(p, t) + dz^2 var(t), a parabola with
its minimum at dz* = -cov(p, t) / var(t) -- exact for the traced rays.

What makes it converge is the pupil's edge. A grid of cell-centred rays gives each edge cell all or
nothing, an O(1/n) error in the weight of the marginal zone that is not monotonic in n (4-16 um on f/1.4
lenses at 32-48 rays a side). Here the pupil box gets an n x n grid (default 128) and every cell on the
pupil's boundary (a cell whose centre ray's fate differs from a neighbour's) is replaced by s x s sub-rays
(default 8), so the edge is resolved as finely as an (n s) x (n s) grid at a fraction of the rays: on the
two f/1.4 library lenses it agrees with a 2048 x 2048 grid to < 0.1 um (tests/trace/test_focus.py).

The real pupil is the beam through the stop's opening around the chief ray. Some prescriptions also pass a
disconnected ring of rays far outside it -- e.g. a wide-angle zoom whose large aspheric front elements (sized
for the off-axis beams) bend axial rays at 20 mm height back through the stop when the patent's flare-cut
stop is left out; those rays land millimetres off axis and would drag the "best focus" tens of mm away. So
the grid's passing cells are split into 8-connected regions (a thin annulus stays one), only the region holding the chief ray's cell
(the ray toward the paraxial entrance pupil's centre) is kept, and the grid is laid again over that region
alone (:func:`main_pupil_box`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from .aiming import FieldPoint, field_point
from .pupil_boxes import PupilBox, box_wavelengths, pupil_boxes

__all__ = ["BEST_FOCUS_DEFINITION", "FocusMoments", "focus_moments", "focus_moments_fields", "focus_moments_many",
           "best_focus_plane",
           "BestFocusPlane"]

BEST_FOCUS_DEFINITION = ("minimum RMS spot radius about the centroid, rays filling the real pupil uniformly "
                         "(stream-kernel weights), wavelengths pooled by weight; pupil edge resolved by "
                         "sub-sampling the boundary cells of the ray grid")


@dataclass(frozen=True)
class FocusMoments:
    """Weighted first and second moments of one wavelength's rays at the plane ``z0_mm`` (weights sum to 1).

    ``p`` are the ray positions (x, y) on the plane, ``t`` their slopes (L/N, M/N).
    """

    wavelength_nm: float
    z0_mm: float
    mean_p: np.ndarray   # (2,)
    mean_t: np.ndarray   # (2,)
    pp: float            # E[p . p]
    pt: float            # E[p . t]
    tt: float            # E[t . t]
    rays: int


def _chief_cell_ab(lens: Lens, fp: FieldPoint, box: PupilBox) -> tuple[float, float]:
    """(a, b) in ``box`` of the ray from ``fp`` toward the paraxial entrance pupil's centre."""
    from ..paraxial import first_order
    centre, axis = np.asarray(box.centre, dtype=np.float64), np.asarray(box.axis, dtype=np.float64)
    target = np.array([0.0, 0.0, first_order(lens).entrance_pupil_z_mm])
    if fp.infinite:
        d = np.asarray(fp.direction, dtype=np.float64)
        o = target
    else:
        o = np.asarray(fp.point_mm, dtype=np.float64)
        d = target - o
    t = float(np.dot(centre - o, axis) / np.dot(d, axis))
    q = o + t * d - centre
    return float(np.dot(q, box.e1)), float(np.dot(q, box.e2))


def main_pupil_box(lens: Lens, fp: FieldPoint, box: PupilBox, ok: np.ndarray) -> PupilBox | None:
    """The box of the 8-connected region of passing cells ``ok`` (n x n over ``box``) that holds the chief
    ray's cell (or the passing cell nearest it), one cell wider each side; None when that region is all
    there is (nothing to cut away)."""
    from dataclasses import replace
    from scipy import ndimage
    labels, count = ndimage.label(ok, structure=np.ones((3, 3), dtype=bool))
    if count <= 1:
        return None
    n0, n1 = ok.shape
    da, db = (box.a1 - box.a0) / n0, (box.b1 - box.b0) / n1
    a, b = _chief_cell_ab(lens, fp, box)
    ia, ib = np.nonzero(ok)
    k = int(np.argmin((box.a0 + (ia + 0.5) * da - a) ** 2 + (box.b0 + (ib + 0.5) * db - b) ** 2))
    ra, rb = np.nonzero(labels == labels[ia[k], ib[k]])
    return replace(box, a0=box.a0 + (ra.min() - 1) * da, a1=box.a0 + (ra.max() + 2) * da,
                   b0=box.b0 + (rb.min() - 1) * db, b1=box.b0 + (rb.max() + 2) * db)


def focus_moments(lens: Lens, wavelength_nm: float, *, fp: FieldPoint | None = None, z0_mm: float | None = None,
                  n: int = 128, sub: int = 8, stop_radius_mm: float | None = None,
                  device: str | None = None, reuse: bool = True) -> FocusMoments:
    """The focus moments of one wavelength (module docstring): an n x n grid, boundary cells sub x sub."""
    fp = field_point(lens, 0.0, 0.0) if fp is None else fp
    z0 = lens.image_z_mm if z0_mm is None else float(z0_mm)
    return focus_moments_fields(lens, [(fp, wavelength_nm, z0)], n=n, sub=sub, stop_radius_mm=stop_radius_mm,
                                device=device, reuse=reuse)[0]


#: moments already found, per (lens, field point, wavelength, plane, n, sub, stop radius, device, path): the
#: report asks for the same ones in several sections (the comparison's tables, the PSFs' best focus, focus
#: breathing at infinity); at most _KNOWN_KEPT kept
_KNOWN: dict = {}
_KNOWN_KEPT = 256


def focus_moments_fields(lens: Lens, jobs: Sequence[tuple[FieldPoint, float, float]], *, n: int = 128,
                         sub: int = 8, stop_radius_mm: float | None = None, device: str | None = None,
                         on_device: bool | None = None, reuse: bool = True) -> list[FocusMoments]:
    """:func:`focus_moments` of several (field point, wavelength nm, plane z0 mm) jobs of one lens, traced together.

    Each job gets its own pupil box, grid, main-pupil refinement and boundary sub-rays, as alone; the
    pupil boxes of a wavelength's jobs are found in one search, and each round of grids, then the
    sub-rays, of all jobs are one launch. Where the jobs' planes differ, the rays are traced to the image
    surface and carried on in a straight line to each plane (the same rays; positions differ from a
    trace to the plane by rounding). For rotationally symmetric lenses the rays are made, traced and
    reduced to the moments' sums on the device (:mod:`lensrt.trace.focus_grids`; ``on_device=False``
    takes the host path, which agrees to rounding). Jobs found before in this process (same lens, field
    point, wavelength, plane, grid, stop radius, device and path) are not traced again (``reuse=False``
    traces every job). Raises :class:`LensrtError` as :func:`focus_moments` does.
    """
    from ..device import resolve_device
    from .focus_grids import grids_on_device
    if not (int(n) == n >= 2 and int(sub) == sub >= 1):
        raise LensrtError(f"a best-focus grid needs n >= 2 cells a side and sub >= 1 sub-rays (got n={n!r}, "
                          f"sub={sub!r})", hint="the defaults are n=128, sub=8")
    jobs = [(fp, float(w), float(z0)) for fp, w, z0 in jobs]
    dev = resolve_device(device)
    path = grids_on_device(lens, dev, stop_radius_mm, on_device)
    keys = [(lens, fp, w, z0, int(n), int(sub), stop_radius_mm, dev, path) for fp, w, z0 in jobs]
    known = {k: _KNOWN.get(k) for k in keys} if reuse else {}  # one look each (another thread may clear it)
    missing = list(dict.fromkeys(k for k in keys if known.get(k) is None))
    found = dict(zip(missing, _traced_moments(lens, [k[1:4] for k in missing], n, sub, stop_radius_mm, dev,
                                              path))) if missing else {}
    known.update(found)
    out = [known[k] for k in keys]
    if reuse and found:
        if len(_KNOWN) + len(found) > _KNOWN_KEPT:
            _KNOWN.clear()
        _KNOWN.update(found)
    return out


def _traced_moments(lens: Lens, jobs: list, n: int, sub: int, stop_radius_mm: float | None, device: str,
                    on_device: bool) -> list[FocusMoments]:
    """:func:`focus_moments_fields` of ``jobs``, all traced."""
    from .focus_grids import focus_grids
    boxes: list = [None] * len(jobs)
    for w in sorted({j[1] for j in jobs}):
        ks = [k for k, j in enumerate(jobs) if j[1] == w]
        got = pupil_boxes(lens, [jobs[k][0] for k in ks], box_wavelengths(lens, [w]), stop_radius_mm=stop_radius_mm,
                          device=device)
        for k, b in zip(ks, got):
            boxes[k] = b
    if not all(b.area_mm2 > 0 for b in boxes):
        raise LensrtError("no ray of this field point passes the lens: no best focus",
                          hint="choose a field point inside the lens's coverage")
    grids = focus_grids(lens, jobs, n, sub, stop_radius_mm, device, on_device)
    oks: list = [None] * len(jobs)  # each job's last grid: which cells passed
    active = list(range(len(jobs)))
    for attempt in range(3):  # the grid, then again over the main pupil alone (module docstring)
        got = grids.grid(active, boxes) if active else {}
        still = []
        for k in active:
            oks[k] = got[k]
            main = main_pupil_box(lens, jobs[k][0], boxes[k], oks[k]) if oks[k].any() else None
            if main is None:
                continue
            if attempt == 2:  # still disconnected pieces inside the refined box: keep the main region's cells only
                oks[k] = _main_region(lens, jobs[k][0], boxes[k], oks[k], n)
                continue
            boxes[k] = main
            still.append(k)
        active = still
    return [FocusMoments(wl, z0, mp, mt, pp, pt, tt, rays)
            for (_, wl, z0), (mp, mt, pp, pt, tt, rays) in zip(jobs, grids.moments(oks, boxes))]


def _main_region(lens: Lens, fp: FieldPoint, box: PupilBox, ok: np.ndarray, n: int) -> np.ndarray:
    """``ok`` restricted to the 8-connected region of the chief ray's cell (when that cell passes)."""
    from scipy import ndimage
    labels, _ = ndimage.label(ok, structure=np.ones((3, 3), dtype=bool))
    a, b = _chief_cell_ab(lens, fp, box)
    ca = int(np.clip((a - box.a0) / ((box.a1 - box.a0) / n), 0, n - 1))
    cb = int(np.clip((b - box.b0) / ((box.b1 - box.b0) / n), 0, n - 1))
    return ok & (labels == labels[ca, cb]) if labels[ca, cb] else ok


def focus_moments_many(lens: Lens, wavelengths_nm: Sequence[float], *, fp: FieldPoint | None = None,
                       z0_mm: float | None = None, n: int = 128, sub: int = 8, stop_radius_mm: float | None = None,
                       device: str | None = None) -> list[FocusMoments]:
    """:func:`focus_moments` of several wavelengths (each wavelength's grid refined to its main pupil on its
    own), their grids traced together (:func:`focus_moments_fields`)."""
    fp = field_point(lens, 0.0, 0.0) if fp is None else fp
    z0 = lens.image_z_mm if z0_mm is None else float(z0_mm)
    return focus_moments_fields(lens, [(fp, float(w), z0) for w in wavelengths_nm], n=n, sub=sub,
                                stop_radius_mm=stop_radius_mm, device=device)


@dataclass(frozen=True)
class BestFocusPlane:
    """Best focus z (lens frame, mm), the RMS spot radius there and on the reference plane ``z0_mm`` (mm)."""

    z_mm: float
    rms_radius_mm: float
    z0_mm: float
    rms_radius_z0_mm: float
    rays: int


def _pool(moments: Sequence[FocusMoments], weights: Sequence[float]) -> tuple[float, float, float]:
    """var(p), cov(p, t), var(t) of the pooled rays (each wavelength's rays carry its weight)."""
    w = np.asarray(weights, dtype=np.float64)
    if not (np.all(np.isfinite(w)) and np.all(w >= 0) and w.sum() > 0):
        raise LensrtError(f"wavelength weights {list(weights)} must be non-negative and not all zero")
    w = w / w.sum()
    mp = sum(wi * m.mean_p for wi, m in zip(w, moments))
    mt = sum(wi * m.mean_t for wi, m in zip(w, moments))
    pp = sum(wi * m.pp for wi, m in zip(w, moments)) - float(mp @ mp)
    pt = sum(wi * m.pt for wi, m in zip(w, moments)) - float(mp @ mt)
    tt = sum(wi * m.tt for wi, m in zip(w, moments)) - float(mt @ mt)
    return pp, pt, tt


def best_focus_plane(moments: Sequence[FocusMoments], weights: Sequence[float] | None = None) -> BestFocusPlane:
    """Best focus of the pooled wavelengths (module docstring) from their :func:`focus_moments`."""
    if not moments:
        raise LensrtError("best focus needs at least one wavelength")
    z0 = moments[0].z0_mm
    if any(m.z0_mm != z0 for m in moments):
        raise LensrtError("focus moments taken on different planes cannot be pooled")
    pp, pt, tt = _pool(moments, [1.0] * len(moments) if weights is None else weights)
    dz = -pt / tt if tt > 0 else 0.0   # a collimated image-side beam: every plane is equally good
    rms = math.sqrt(max(pp + 2.0 * dz * pt + dz * dz * tt, 0.0))
    return BestFocusPlane(z0 + dz, rms, z0, math.sqrt(max(pp, 0.0)), sum(m.rays for m in moments))
