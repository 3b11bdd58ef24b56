"""Global placement of every surface: the local frames that coordinate transforms and mirrors make.

The first surface's vertex is the global origin with the global axes
(``CONVENTIONS.md``). Surface i's frame is the running frame after its
``transform_before``; after the surface its ``transform_after`` applies and
the thickness moves the origin along the new local z. The image surface's
frame is the running frame after the last thickness, moved by
``lens.image_transform`` (CODE V's decentred image surface).

Light travels toward local +z until a mirror reflects it; after an odd
number of mirrors it travels toward local -z (the thicknesses are negative
there, as in Zemax and CODE V): :func:`travel_signs`.
"""
from __future__ import annotations

import numpy as np

from .geometry import compose_frame
from .model import Lens

__all__ = ["surface_frames", "travel_signs"]


def surface_frames(lens: Lens) -> list[tuple[np.ndarray, np.ndarray]]:
    """(origin, axes) of every surface, then of the image surface; axes as columns, global coordinates."""
    origin, axes = np.zeros(3), np.eye(3)
    frames = []
    for s in lens.surfaces:
        origin, axes = compose_frame(origin, axes, s.transform_before)
        frames.append((origin, axes))
        origin, axes = compose_frame(origin, axes, s.transform_after)
        origin = origin + axes[:, 2] * s.thickness_mm
    frames.append(compose_frame(origin, axes, lens.image_transform))
    return frames


def travel_signs(lens: Lens) -> list[float]:
    """+1 or -1 per surface and the image: the local z direction light travels in as it arrives there."""
    sign, out = 1.0, []
    for s in lens.surfaces:
        out.append(sign)
        if s.mirror:
            sign = -sign
    out.append(sign)
    return out
