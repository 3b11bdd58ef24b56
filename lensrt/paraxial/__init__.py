"""Stage 2: Gaussian optics -- the ynu paraxial trace and first-order data (float64, host)."""
from __future__ import annotations

from .first_order import FirstOrder, Pupils, first_order, pupils
from .ynu import ParaxialRay, ParaxialSystem, paraxial_system, trace_ynu

__all__ = ["FirstOrder", "Pupils", "first_order", "pupils", "ParaxialRay", "ParaxialSystem",
           "paraxial_system", "trace_ynu"]
