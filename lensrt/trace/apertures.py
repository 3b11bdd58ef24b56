"""Clear semi-diameters a lens file does not give, from real rays (OpticStudio's automatic mode).

For every field point and wavelength of the lens, the chief ray and the four
marginal rays at pupil coordinates (Px, Py) = (0, +-1), (+-1, 0) are aimed at the
real stop (:mod:`.aiming`, ``aim="real"``) and traced without clipping by the
float64 reference tracer; a surface's semi-diameter is the largest height any
of them reaches there. The stop's is the real stop radius (the specified
entrance pupil holds exactly on axis). This runs on the host, without Warp, so
loading a lens never compiles a kernel.

Where real rays fail (a ray that cannot be aimed, misses a surface or is
totally reflected), the paraxial estimate of
:mod:`lensrt.paraxial.apertures` (|y_chief| + |y_marginal|) is the fallback:
every surface then takes the larger of the two, so no aperture is
underestimated; ``lens.meta["clear_apertures"]`` says which method was used.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import PrescriptionError
from ..prescription.model import Lens
from .aiming import aim_rays, field_point, pupil_geometry
from .reference import trace_reference
from .status import OK

__all__ = ["real_ray_heights", "compute_clear_apertures", "METHOD_REAL", "METHOD_FALLBACK", "MAX_FAILED_FRACTION"]

#: more than this fraction of failed rays is an error, not a paraxial fallback (the 28 mm f/1.4 loses
#: 6 of 45 at its rim field, a 1 um radius 42 of 45)
MAX_FAILED_FRACTION = 0.5

METHOD_REAL = ("real rays: chief and marginal rays (Px, Py = (0, +-1), (+-1, 0)) aimed at the real stop, "
               "every field and wavelength, traced without clipping")
METHOD_FALLBACK = METHOD_REAL + "; paraxial marginal+chief heights where larger ({} of {} rays failed)"

_PUPIL = np.array([[0.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 0.0], [-1.0, 0.0]])


def real_ray_heights(lens: Lens) -> tuple[np.ndarray, int, int]:
    """Largest real-ray height (mm) at each surface; also (rays failed, rays tried)."""
    heights = np.zeros(lens.n_surfaces)
    geom = pupil_geometry(lens)
    fmax = lens.fields.max_radial
    failed = tried = 0
    for fx, fy in zip(lens.fields.x, lens.fields.y):
        hx, hy = (fx / fmax, fy / fmax) if fmax > 0 else (0.0, 0.0)
        fp = field_point(lens, hx, hy)
        for wl in lens.wavelengths.nm:
            o, d, aimed = aim_rays(lens, fp, _PUPIL[:, 0], _PUPIL[:, 1], wl, "real", geometry=geom)
            for k in range(len(_PUPIL)):
                tried += 1
                if not aimed[k]:
                    failed += 1
                    continue
                ray = trace_reference(lens, o[k], d[k], wl, clip=False)
                if ray.status != OK:
                    failed += 1
                    continue
                for i, hit in enumerate(ray.hits[:lens.n_surfaces]):
                    heights[i] = max(heights[i], math.hypot(hit.x_mm, hit.y_mm))
    heights[lens.stop_index] = geom.stop_radius_mm
    return heights, failed, tried


def compute_clear_apertures(lens: Lens, max_failed_fraction: float = MAX_FAILED_FRACTION) -> Lens:
    """A copy of ``lens`` with every missing semi-diameter computed from real rays (flagged automatic).

    A value beyond the largest radius the surface can have (|R| for a sphere) is
    limited to that radius. More than ``max_failed_fraction`` of the chief and marginal rays failing is an
    error; a study of a lens pushed beyond what it passes (a stability case opened past its design
    f-number) may opt in to a larger fraction, the failed rays' heights then taken from the paraxial ones.
    """
    if all(s.semi_diameter_mm is not None for s in lens.surfaces):
        return lens
    heights, failed, tried = real_ray_heights(lens)
    method = METHOD_REAL
    if failed > max_failed_fraction * tried:
        raise PrescriptionError(
            f"the clear apertures cannot be computed: {failed} of {tried} real chief and marginal rays fail "
            "(cannot be aimed, miss a surface or are totally reflected)",
            hint="check the radii, thicknesses and aperture, or give semi-diameters in the file")
    if failed:
        from ..paraxial.apertures import paraxial_ray_heights
        heights = np.maximum(heights, paraxial_ray_heights(lens))
        method = METHOD_FALLBACK.format(failed, tried)
    surfaces = list(lens.surfaces)
    for i, s in enumerate(surfaces):
        if s.semi_diameter_mm is None:
            sd = float(min(heights[i], s.max_semi_diameter_mm))
            surfaces[i] = replace(s, semi_diameter_mm=max(sd, 1e-6), semi_diameter_auto=True)
    return lens.replace(surfaces=tuple(surfaces)).with_note("clear_apertures", method)
