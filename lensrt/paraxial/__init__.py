"""Stage 2: Gaussian optics -- the ynu paraxial trace, first-order data, Seidel sums and the
Field Guide's photographic formulas (float64, host).

Public API (see each module):

* :func:`paraxial_system` (Lens -> :class:`ParaxialSystem` at a wavelength),
  :func:`trace_ynu` / :func:`trace_ynu_reverse` (forward / backward ynu trace);
* :func:`first_order` -> :class:`FirstOrder`; :func:`pupils`; :func:`paraxial_rays`
  (marginal and chief rays, CODE V's ``fio``); :func:`marginal_ray`, :func:`chief_ray`;
* :func:`seidel_sums` -> :class:`SeidelSums` (per surface, totals, CODE V ``tho`` columns);
* :mod:`lensrt.paraxial.photographic` (AFoV, unit focusing, DoF, camera equation, APEX).
"""
from __future__ import annotations

from .first_order import (FirstOrder, Pupils, chief_ray, entrance_pupil_diameter_mm, first_order,
                          marginal_ray, paraxial_rays, pupils)
from .seidel import CODEV_THO_COLUMNS, SEIDEL_NAMES, SeidelSums, seidel_sums
from .ynu import ParaxialRay, ParaxialSystem, paraxial_system, trace_ynu, trace_ynu_reverse

__all__ = ["FirstOrder", "Pupils", "first_order", "pupils", "paraxial_rays", "marginal_ray", "chief_ray",
           "entrance_pupil_diameter_mm", "ParaxialRay", "ParaxialSystem", "paraxial_system", "trace_ynu",
           "trace_ynu_reverse", "SeidelSums", "seidel_sums", "SEIDEL_NAMES", "CODEV_THO_COLUMNS"]
