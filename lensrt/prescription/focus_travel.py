"""Moving a lens's focus mechanism, and the secant search for the travel that focuses it.

The residual (where the lens focuses against its image surface) needs rays, so it is
passed in: :mod:`lensrt.analysis.focusing` uses the analysis best focus and
:mod:`lensrt.render.camera` the renderer's; both move the mechanism the same way.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

import numpy as np

from ..errors import LensrtError
from .model import Lens

__all__ = ["move_mechanism", "travel_start", "solve_travel"]


def move_mechanism(lens: Lens, travel: float) -> Lens:
    """``lens`` with its focus mechanism at ``travel``.

    Unit focusing: the last thickness grows by the extension ``travel`` (mm). A focus
    group: each gap changes by ``sign * travel`` (mm). Floating groups: the gaps are
    read from the table at the object vergence ``travel`` (1/mm).
    """
    mech = lens.focus
    surfaces = list(lens.surfaces)
    if mech.is_unit:
        last = len(surfaces) - 1
        return lens.replace_surface(last, thickness_mm=surfaces[last].thickness_mm + travel)
    if mech.kind == "group":
        new = {g: surfaces[g].thickness_mm + s * travel for g, s in zip(mech.gaps, mech.signs)}
    else:
        new = dict(zip(mech.gaps, (float(v) for v in mech.floating_thickness_mm(travel))))
    for g, t in new.items():
        if t < 0.0:
            raise LensrtError(f"the focus mechanism would close the gap after surface {g + 1} ({t:.4g} mm)",
                              hint="the focus distance is beyond the mechanism's range")
        surfaces[g] = replace(surfaces[g], thickness_mm=t)
    return lens.replace(surfaces=tuple(surfaces))


def travel_start(lens: Lens, distance_mm: float) -> tuple[float, float, str]:
    """First two travels of the secant search and the travel's unit."""
    if lens.focus.is_unit:
        return 0.0, 0.0, "mm (extension)"
    if lens.focus.kind == "floating":
        v = 0.0 if math.isinf(distance_mm) else 1.0 / distance_mm
        span = float(np.ptp(lens.focus.vergences_per_mm)) or 1e-4
        return v, v + 0.01 * span, "1/mm (object vergence of the floating table)"
    return 0.0, 0.05, "mm (group travel)"


def solve_travel(lens: Lens, distance_mm: float, residual_mm: Callable[[Lens], float], tol_mm: float = 1e-9,
                 max_iter: int = 40) -> tuple[float, float, int, str]:
    """The travel that drives ``residual_mm(moved lens)`` to zero: (travel, residual, evaluations, unit).

    Unit focusing takes one step (the last gap does not change the rays); the other
    mechanisms the secant method. Raises :class:`LensrtError` when it does not converge.
    """
    t0, t1, unit = travel_start(lens, distance_mm)

    def residual(t: float) -> float:
        return residual_mm(move_mechanism(lens, t))

    r0 = residual(t0)
    if lens.focus.is_unit:
        t, it = r0, 2
        r = residual(t)
    else:
        r1 = residual(t1)
        t, r, it = t1, r1, 2
        while abs(r) > tol_mm and it < max_iter and r1 != r0:
            t2 = t1 - r1 * (t1 - t0) / (r1 - r0)
            t0, r0, t1 = t1, r1, t2
            r1 = residual(t1)
            t, r, it = t1, r1, it + 1
    if not abs(r) <= 10.0 * max(tol_mm, 1e-12 * abs(lens.image_z_mm)):
        where = "infinity" if math.isinf(distance_mm) else f"{distance_mm:g} mm"
        raise LensrtError(f"the focus mechanism could not focus at {where} (best focus {r:.3g} mm from the image "
                          f"surface after {it} steps)", hint="the distance may be outside the mechanism's range")
    return float(t), float(r), it, unit
