"""An aperture the lens cannot pass (an image-space f-number below 0.5), or no first-order image at all;
the paraxial image distance the geometry check needs to accept a virtual image.

In air the image-space numerical aperture is below 1, so the f-number N = 1/(2 NA') of an aplanatic
lens is at least 0.5 (Field Guide p. 30). An entrance pupil given as a diameter (``epd = 1e9``) can
ask for much less; the aperture checks in :mod:`lensrt.prescription.model` see only f-numbers that
are given as such. (A stop semi-diameter smaller than the specified beam is not refused: CODE V
files in the rayoptics test set do that on purpose, the CIR clipping the beam.)
"""
from __future__ import annotations

import math

from ..errors import LensrtError, PrescriptionError
from ..prescription.model import Lens
from .first_order import first_order

__all__ = ["MIN_F_NUMBER", "check_aperture", "paraxial_image_distance_mm"]

#: the smallest image-space f-number in air (NA' < 1)
MIN_F_NUMBER = 0.5
#: relative slack of the stop-size check
SLACK = 1e-3


def check_aperture(lens: Lens) -> None:
    """Raise :class:`PrescriptionError` when the aperture specification is beyond what the lens passes, or the
    lens has no first-order image (afocal, the object at the front focal point)."""
    try:
        fo = first_order(lens)
    except LensrtError as err:  # afocal, or an image at infinity: no lens to image with; the loader names the file
        raise PrescriptionError(err.message, hint=err.hint) from None
    line = getattr(lens, "aperture_line", None)
    n = fo.f_number
    if n == n and 0 < abs(n) < MIN_F_NUMBER * (1.0 - SLACK):
        raise PrescriptionError(
            f"the aperture ({lens.aperture.kind} = {lens.aperture.value:g}) gives f/{abs(n):.3g}, below f/0.5, "
            f"the limit for a lens in air", line=line,
            hint=f"an entrance pupil of at most {abs(fo.efl_mm) / MIN_F_NUMBER:.4g} mm")


def paraxial_image_distance_mm(lens: Lens) -> float | None:
    """Last vertex to the paraxial image of the lens's object (mm, a z offset; < 0 in front of the last
    vertex when light travels toward +z), or None when there is none (afocal, image at infinity)."""
    try:
        fo = first_order(lens)
    except LensrtError:
        return None
    return float(fo.image_distance_mm) if math.isfinite(fo.image_distance_mm) else None
