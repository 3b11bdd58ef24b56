"""Through-focus spot diagrams: where a field point's rays land on planes before and behind the focus, beside the
through-focus MTF (``lensrt mtf --through-focus``).

A deterministic grid of rays over the field point's real (vignetted) pupil (:mod:`lensrt.analysis.pupil_rays`,
weighted as the stream kernel weights them) is traced once per wavelength of the set-up's spectrum to each plane
z = z_focus + dz (float64 store kernel). Each plane's spot is centred on its polychromatic centroid (the
centroid moves with focus off axis) and carries its RMS radius about it, pooled over wavelengths with the
spectrum's weights.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ..fields import FieldSpec
from ..pupil_rays import pupil_grid_rays, trace_pupil_rays
from .geometric import prepare_field
from .setup import PsfSetup

__all__ = ["FocusSpots", "through_focus_spots"]


@dataclass
class FocusSpots:
    """Spots of one field point on planes ``focus_mm`` (shifts) from the set-up's plane (lengths mm)."""

    label: str
    focus_mm: np.ndarray                    # (k,) shifts
    plane_z_mm: np.ndarray                  # (k,)
    wavelengths_nm: tuple[float, ...]
    x_mm: list[list[np.ndarray]]            # [plane][wavelength] ray x about the plane's centroid
    y_mm: list[list[np.ndarray]]
    centroid_mm: np.ndarray                 # (k, 2) on each plane
    rms_radius_mm: np.ndarray               # (k,) about the centroid, wavelengths pooled by weight
    rays: int
    seconds: float

    def to_dict(self) -> dict:
        return {"label": self.label, "focus_mm": self.focus_mm, "plane_z_mm": self.plane_z_mm,
                "wavelengths_nm": list(self.wavelengths_nm), "centroid_mm": self.centroid_mm,
                "rms_radius_mm": self.rms_radius_mm, "rays": self.rays, "seconds": self.seconds,
                "definition": "deterministic ray grid over the real pupil; RMS about each plane's centroid"}


def through_focus_spots(setup: PsfSetup, f: FieldSpec, dz_mm: Sequence[float], *, n_grid: int = 31,
                        device: str | None = None) -> FocusSpots:
    """Spot diagrams of field ``f`` at focus shifts ``dz_mm`` (module docstring)."""
    t0 = time.perf_counter()
    dz = np.asarray(dz_mm, dtype=np.float64)
    if dz.size < 1 or not np.all(np.isfinite(dz)):
        raise LensrtError("through-focus spots need finite focus shifts")
    geom = prepare_field(setup, f, device)
    rays = pupil_grid_rays(geom.fp, geom.box, int(n_grid))
    spec = setup.spectrum
    wls = tuple(float(w) for w in spec.lines_nm)
    lw = np.asarray(spec.line_weights, dtype=np.float64)
    xs, ys, cents, rms = [], [], [], []
    for d in dz:
        z = setup.plane_z_mm + float(d)
        pts, wts = [], []
        for w, wl in zip(lw, wls):
            r = trace_pupil_rays(setup.lens, rays, wl, z, device)
            ok = r.ok & (r.direction[:, 2] > 0)
            pts.append(r.position_mm[ok, :2])
            wts.append(rays.weight[ok] * (w / max(float(rays.weight[ok].sum()), 1e-300)))
        p, wt = np.concatenate(pts), np.concatenate(wts)
        if len(p) < 3:
            raise LensrtError(f"field {f.label}: too few rays reach the plane {z:.4f} mm for a spot diagram")
        c = (wt[:, None] * p).sum(axis=0) / wt.sum()
        cents.append(c)
        rms.append(math.sqrt(float((wt * ((p - c) ** 2).sum(axis=1)).sum() / wt.sum())))
        xs.append([q[:, 0] - c[0] for q in pts])
        ys.append([q[:, 1] - c[1] for q in pts])
    return FocusSpots(f.label, dz, setup.plane_z_mm + dz, wls, xs, ys, np.array(cents), np.array(rms),
                      int(n_grid * n_grid * len(wls) * dz.size), time.perf_counter() - t0)
