"""Surfaces that cross inside the axial beam: impossible whether the file gives semi-diameters or not.

:func:`lensrt.prescription.validate.check_geometry` proves crossings within the file's own
semi-diameters. Computed semi-diameters (real chief and marginal rays of every field) cannot prove
one: real lenses let air-spaced elements touch at their rims and rely on vignetting, so adjacent
surfaces often "cross" at the full-field ray heights of a valid design. The axial beam is different:
every ray of the on-axis pencil must pass, so the two faces of a glass element that cross within the
paraxial marginal ray height (the largest over the lens's wavelengths) make an element of negative
thickness where the light goes. Air gaps are left to the file's semi-diameters: a paraxial height
can overshoot the real one on fast lenses, and elements nearly touching across a thin air gap are
common (the 105 mm macro's 0.26 mm gap would be flagged on paraxial heights).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import PrescriptionError
from ..prescription.frames import travel_signs
from ..prescription.model import Lens
from .first_order import entrance_pupil_diameter_mm, marginal_ray, pupils
from .ynu import paraxial_system

__all__ = ["axial_beam_heights", "check_axial_beam_crossing"]

#: sags may touch (cemented surfaces) within this tolerance (mm)
TOL_MM = 1e-6


def axial_beam_heights(lens: Lens) -> np.ndarray:
    """Largest |y| of the paraxial marginal ray at each surface over the lens's wavelengths (mm)."""
    heights = np.zeros(lens.n_surfaces)
    for w in lens.wavelengths.nm:
        sysm = paraxial_system(lens, w)
        pup = pupils(sysm)
        phi = -sysm.matrix(0, sysm.n_surfaces - 1)[1, 0]
        epd = entrance_pupil_diameter_mm(lens, sysm, pup, 1.0 / phi if phi else math.inf)
        m = marginal_ray(sysm, lens.object_distance_mm, pup.entrance_z_mm, epd)
        heights = np.maximum(heights, np.abs(np.asarray(m.y[:-1], dtype=np.float64)))
    return heights


def check_axial_beam_crossing(lens: Lens, samples: int = 65) -> None:
    """Raise :class:`PrescriptionError` if the faces of a glass element cross within the axial beam."""
    try:
        heights = axial_beam_heights(lens)
    except PrescriptionError:
        return  # no first-order data (afocal, ...): other checks report that
    if not np.isfinite(heights).all():
        return
    surfaces = lens.surfaces
    signs = travel_signs(lens)  # after an odd number of mirrors light travels toward -z: "in front" flips
    for i in range(len(surfaces) - 1):
        a, b = surfaces[i], surfaces[i + 1]
        if a.material.is_air or a.transform_after is not None or b.transform_before is not None:
            continue  # air gaps: the file's semi-diameters decide; transformed surfaces share no axis
        limits = [heights[i], heights[i + 1], a.max_semi_diameter_mm, b.max_semi_diameter_mm]
        limits += [s.semi_diameter_mm for s in (a, b) if s.semi_diameter_mm is not None]
        r_max = float(min(limits))
        if not r_max > 0:
            continue
        r = np.linspace(0.0, r_max, samples)
        gap = signs[i + 1] * (a.thickness_mm + np.asarray(b.sag(r)) - np.asarray(a.sag(r)))
        worst = int(np.argmin(gap))
        if gap[worst] < -TOL_MM:
            raise PrescriptionError(
                f"surfaces {i + 1} and {i + 2} (a glass element) cross inside the axial beam: at height {r[worst]:.4g} mm (the "
                f"marginal ray reaches {min(heights[i], heights[i + 1]):.4g} mm) surface {i + 2} lies "
                f"{-gap[worst]:.4g} mm in front of surface {i + 1} (thickness {a.thickness_mm:g} mm)",
                surface=i, line=a.line, hint="check the thickness and the radii")
