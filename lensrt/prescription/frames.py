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

from typing import Sequence

import numpy as np

from .geometry import CoordinateTransform, compose_frame, elementary_rotation
from .model import Lens, Surface

__all__ = ["surface_frames", "frames_of_surfaces", "travel_signs", "transform_between"]


def surface_frames(lens: Lens) -> list[tuple[np.ndarray, np.ndarray]]:
    """(origin, axes) of every surface, then of the image surface; axes as columns, global coordinates."""
    return frames_of_surfaces(lens.surfaces, lens.image_transform)


def frames_of_surfaces(surfaces: Sequence[Surface], image_transform: CoordinateTransform | None = None
                       ) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`surface_frames` of a surface list (a lens being assembled): one frame per surface, then the
    frame after the last thickness moved by ``image_transform``."""
    origin, axes = np.zeros(3), np.eye(3)
    frames = []
    for s in surfaces:
        origin, axes = compose_frame(origin, axes, s.transform_before)
        frames.append((origin, axes))
        origin, axes = compose_frame(origin, axes, s.transform_after)
        origin = origin + axes[:, 2] * s.thickness_mm
    frames.append(compose_frame(origin, axes, image_transform))
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


def transform_between(origin: np.ndarray, axes: np.ndarray, target_origin: np.ndarray, target_axes: np.ndarray,
                      tol: float = 1e-12) -> CoordinateTransform:
    """The order-0 :class:`CoordinateTransform` that moves the frame (``origin``, ``axes``) onto the frame
    (``target_origin``, ``target_axes``) -- both in global coordinates, lengths in mm.

    The relative rotation ``R = A^T A_target`` is split into lensrt's tilts
    ``R = Rx(alpha) Ry(beta) Rz(gamma)`` (:func:`~lensrt.prescription.geometry.elementary_rotation`:
    ``Rx(alpha) = rot_x(-alpha)``, ``Ry(beta) = rot_y(-beta)``, ``Rz(gamma) = rot_z(gamma)``), and the
    decenter is the target origin seen in the starting frame, ``d = A^T (o_target - o)``. Used for CODE V's
    ``RET Sk`` (return to surface k's coordinate system). Raises ``ValueError`` if the split does not
    rebuild ``R`` within ``tol`` (it always does for a proper rotation).
    """
    axes, target_axes = np.asarray(axes, dtype=float), np.asarray(target_axes, dtype=float)
    rot = axes.T @ target_axes
    dec = axes.T @ (np.asarray(target_origin, dtype=float) - np.asarray(origin, dtype=float))
    # right-handed rot_x(p) rot_y(q) rot_z(r): R[0,2] = sin q, R[1,2] = -sin p cos q, R[2,2] = cos p cos q,
    # R[0,0] = cos q cos r, R[0,1] = -cos q sin r; at cos q = 0 (gimbal lock) r = 0 and p from R[1,0], R[1,1]
    q = float(np.arcsin(np.clip(rot[0, 2], -1.0, 1.0)))
    if abs(rot[0, 2]) < 1.0 - 1e-12:
        p = float(np.arctan2(-rot[1, 2], rot[2, 2]))
        r = float(np.arctan2(-rot[0, 1], rot[0, 0]))
    else:
        p, r = float(np.arctan2(rot[2, 1], rot[1, 1])), 0.0
    # values at the rounding level of the products above (1e-13 mm or rad) are an exact zero in the file
    vals = [0.0 if abs(v) < 1e-13 else float(v) for v in (dec[0], dec[1], dec[2], -p, -q, r)]
    t = CoordinateTransform(*vals, 0)
    rebuilt = elementary_rotation("x", -p) @ elementary_rotation("y", -q) @ elementary_rotation("z", r)
    if not np.allclose(rebuilt, rot, rtol=0.0, atol=tol):
        raise ValueError("the relative orientation is not a proper rotation")
    return t
