"""Clear semi-diameters a lens file does not give, from paraxial rays.

OpticStudio's automatic mode takes the largest height at which the real rays of
the aperture and field specification cross each surface. Until a real-ray
version replaces it (``lensrt.trace``), this uses the paraxial marginal and
chief rays: sd_i = max over fields and wavelengths of |y_chief,i| + |y_marginal,i|,
and records that in ``lens.meta["clear_apertures"]``.
"""
from __future__ import annotations

import math

import numpy as np

from ..prescription.model import Lens
from .first_order import chief_ray, entrance_pupil_diameter_mm, marginal_ray, pupils
from .ynu import paraxial_system

__all__ = ["paraxial_ray_heights", "compute_clear_apertures"]

METHOD = "paraxial marginal+chief ray heights (all fields and wavelengths)"


def paraxial_ray_heights(lens: Lens) -> np.ndarray:
    """Largest |y_chief| + |y_marginal| at each surface over fields and wavelengths (mm)."""
    heights = np.zeros(lens.n_surfaces)
    d_obj = lens.object_distance_mm
    for w in lens.wavelengths.nm:
        sysm = paraxial_system(lens, w)
        pup = pupils(sysm)
        phi = -sysm.matrix(0, sysm.n_surfaces - 1)[1, 0]
        epd = entrance_pupil_diameter_mm(lens, sysm, pup, 1.0 / phi if phi else math.inf)
        m = marginal_ray(sysm, d_obj, pup.entrance_z_mm, epd)
        for fx, fy in zip(lens.fields.x, lens.fields.y):
            c = chief_ray(lens, sysm, math.hypot(fx, fy), d_obj, pup.entrance_z_mm, epd)
            heights = np.maximum(heights, np.abs(c.y[:-1]) + np.abs(m.y[:-1]))
    return heights


def compute_clear_apertures(lens: Lens) -> Lens:
    """A copy of ``lens`` with every missing semi-diameter computed (and flagged automatic).

    A computed value beyond the largest radius the surface can have (|R| for
    a sphere) is limited to that radius.
    """
    heights = paraxial_ray_heights(lens)
    surfaces = list(lens.surfaces)
    changed = False
    for i, s in enumerate(surfaces):
        if s.semi_diameter_mm is None:
            sd = float(min(heights[i], s.max_semi_diameter_mm))
            surfaces[i] = _with_sd(s, max(sd, 1e-6))
            changed = True
    if not changed:
        return lens
    return lens.replace(surfaces=tuple(surfaces)).with_note("clear_apertures", METHOD)


def _with_sd(surface, sd: float):
    from dataclasses import replace
    return replace(surface, semi_diameter_mm=sd, semi_diameter_auto=True)
