"""The one check of an asked f-number against what the lens opens to, shared by render, bokeh, sweep and report."""
from __future__ import annotations

import math

from ..errors import LensrtError
from ..prescription.model import Lens

__all__ = ["MAX_F_NUMBER", "TOLERANCE", "full_aperture_f_number", "check_f_number"]

#: the largest f-number asked of a lens (a pinhole camera is about f/200; beyond this no ray gets through)
MAX_F_NUMBER = 1000.0
#: an asked f-number may be this much (relative) below the lens's own and still count as full aperture
TOLERANCE = 1e-3


def full_aperture_f_number(lens: Lens) -> float:
    """The lens's own paraxial f-number at infinity focus (image space, N = f/D), at the primary wavelength."""
    from .first_order import first_order
    return float(first_order(lens, None, math.inf).f_number)


def check_f_number(lens: Lens, f_number: float, flag: str = "--f-number") -> float:
    """Refuse an ``f_number`` that is not finite and positive, or wider than the lens opens.

    Stopping a lens down works; opening it beyond its own stop would trace rays the lens's clear
    apertures do not pass. Returns the lens's full-aperture f-number.
    """
    if not (isinstance(f_number, (int, float)) and math.isfinite(f_number) and 0 < f_number <= MAX_F_NUMBER):
        raise LensrtError(f"{flag} {f_number!r} must be a positive f-number up to f/{MAX_F_NUMBER:g}")
    n_full = full_aperture_f_number(lens)
    if f_number < n_full * (1.0 - TOLERANCE):
        raise LensrtError(f"f/{f_number:g} is wider than the lens opens (f/{n_full:.3g})",
                          hint=f"use {flag} {n_full:.3g} or more, or leave it out for full aperture")
    return n_full
