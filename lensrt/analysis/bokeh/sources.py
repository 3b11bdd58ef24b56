"""Point sources for bokeh: a grid of sources over the frame at chosen depths, or one source at a field point."""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...units import MM_PER_M
from .focus import Focus
from .trace import Frame, object_heights_for_image

__all__ = ["INTENSITY_SCALINGS", "map_sources", "nice_pitch_mm", "spot_source"]

#: how a map's sources' luminous intensities depend on their depth (see :func:`map_sources`)
INTENSITY_SCALINGS = ("distance2", "none")


def map_sources(lens: Lens, focus: Focus, frame: Frame, grid: tuple[int, int], depths_mm: Sequence[float],
                wavelength_nm: float | None = None, device: str | None = None, intensity_cd: float = 1.0,
                intensity_scaling: str = "distance2") -> list[dict]:
    """Point sources on a grid over the frame at each depth, placed by the real chief ray.

    The picture is divided into ``grid`` = (cols, rows) cells; each cell holds one source per
    depth side by side (left to right in the order of ``depths_mm``), at the cell's vertical
    centre. Each source's object point at its depth is the one whose real chief ray (primary
    wavelength, through the centre of the real stop) meets the sensor at its grid position,
    so the grid is uniform on the sensor whatever the distortion. Sources whose chief ray
    cannot be found are left out with a warning.

    ``intensity_scaling``: ``"distance2"`` (default) gives a source at depth d the luminous
    intensity ``intensity_cd * (d / 1 m)^2`` -- as bright as ``intensity_cd`` at 1 m, so discs of
    every depth show in one exposure, as street lights of similar apparent brightness do;
    ``"none"``: every source has ``intensity_cd``.
    """
    if intensity_scaling not in INTENSITY_SCALINGS:
        raise LensrtError(f"unknown intensity scaling {intensity_scaling!r}",
                          hint=f"use one of {', '.join(INTENSITY_SCALINGS)}")
    import warnings
    cols, rows = (int(v) for v in grid)
    if cols < 1 or rows < 1:
        raise LensrtError(f"a bokeh map needs at least one column and row, not {cols} x {rows}")
    depths = [float(d) for d in depths_mm]
    if not depths or any(not (d > 0) for d in depths):
        raise LensrtError("source depths must be positive distances in front of the lens (mm)")
    nd = len(depths)
    w, h = frame.nx * frame.pitch_mm, frame.ny * frame.pitch_mm
    specs = []
    for r in range(rows):
        for c in range(cols):
            for j, d in enumerate(depths):
                u = (c + (j + 0.5) / nd) / cols  # picture x fraction (left to right)
                v = (r + 0.5) / rows  # picture y fraction (top to bottom)
                inten = intensity_cd * ((d / MM_PER_M) ** 2 if intensity_scaling == "distance2" else 1.0)
                specs.append({"kind": "map", "row": r, "col": c, "depth_index": j, "depth_mm": d,
                              "target_mm": [frame.x0_mm + w * (1.0 - u), frame.y0_mm + h * v],
                              "intensity_cd": inten})
    tx = np.array([s["target_mm"][0] for s in specs])
    ty = np.array([s["target_mm"][1] for s in specs])
    dep = np.array([s["depth_mm"] for s in specs])
    wl = focus.wavelength_nm if wavelength_nm is None else float(wavelength_nm)
    rad = np.hypot(tx, ty)
    y_obj, ok = object_heights_for_image(lens, dep, focus.sensor_z_mm, rad, wl, device)
    out = []
    for k, s in enumerate(specs):
        if not ok[k]:
            continue
        ux, uy = (tx[k] / rad[k], ty[k] / rad[k]) if rad[k] > 0 else (0.0, 1.0)
        s["object_mm"] = [float(ux * y_obj[k]), float(uy * y_obj[k]), -float(dep[k])]
        out.append(s)
    if len(out) < len(specs):
        warnings.warn(f"{len(specs) - len(out)} of {len(specs)} map sources have no real chief ray to their "
                      "sensor position and are left out")
    return out


def spot_source(lens: Lens, focus: Focus, depth_mm: float, *, field_deg: tuple[float, float] | None = None,
                object_mm: tuple[float, float] | None = None, image_mm: tuple[float, float] | None = None,
                device: str | None = None) -> dict:
    """One source at ``depth_mm`` in front of the first vertex, placed by at most one of:

    ``field_deg`` (x, y): seen from the paraxial entrance pupil at these angles (a positive
    angle puts the object below the axis and its image above, as lens files' fields do);
    ``object_mm`` (x, y): the object point's lateral position; ``image_mm`` (x, y): where its
    real chief ray meets the sensor. Default: on the axis.
    """
    from ...paraxial import first_order
    d = float(depth_mm)
    if not (d > 0 and math.isfinite(d)):
        raise LensrtError(f"source distance {depth_mm!r} mm must be a finite positive distance")
    given = [v for v in (field_deg, object_mm, image_mm) if v is not None]
    if len(given) > 1:
        raise LensrtError("place the source by one of: a field angle, an object position or an image position")
    src: dict[str, Any] = {"kind": "spot", "depth_mm": d, "depth_index": 0}
    if field_deg is not None:
        z_ep = first_order(lens, focus.wavelength_nm).entrance_pupil_z_mm
        tx, ty = (math.tan(math.radians(float(a))) for a in field_deg)
        src["field_deg"] = [float(a) for a in field_deg]
        src["object_mm"] = [-(d + z_ep) * tx, -(d + z_ep) * ty, -d]
    elif image_mm is not None:
        x, y = (float(v) for v in image_mm)
        r = math.hypot(x, y)
        yo, ok = object_heights_for_image(lens, d, focus.sensor_z_mm, r, focus.wavelength_nm, device)
        if not ok[0]:
            raise LensrtError(f"no real chief ray from {d:g} mm reaches the sensor at ({x:g}, {y:g}) mm")
        ux, uy = (x / r, y / r) if r > 0 else (0.0, 1.0)
        src["target_mm"] = [x, y]
        src["object_mm"] = [ux * float(yo[0]), uy * float(yo[0]), -d]
    else:
        x, y = (0.0, 0.0) if object_mm is None else (float(v) for v in object_mm)
        src["object_mm"] = [x, y, -d]
    return src


# ---- the two entry points ------------------------------------------------------------------

def nice_pitch_mm(extent_mm: float, n: int) -> float:
    """A pitch of 1, 2 or 5 x 10^k um near extent / n."""
    raw = max(extent_mm / n, 1e-5) * 1000.0
    k = math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10 ** k >= raw:
            return m * 10 ** k / 1000.0
    return 10 ** (k + 1) / 1000.0  # pragma: no cover


