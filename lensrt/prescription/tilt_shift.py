"""Tilt-shift: the whole lens tilted and/or shifted relative to the camera's sensor.

A tilt-shift (view-camera) lens moves as one rigid body in front of a fixed
sensor. lensrt keeps the camera frame -- the sensor plane is z = const, centred
on the camera axis x = y = 0 -- and moves the lens in it with the per-surface
frames of :mod:`.geometry`: the first surface carries a lens-wide
``transform_before`` T (the lens turned by ``tilt`` about the x axis through the
pivot (0, 0, ``pivot_z_mm``) on its own axis, then moved across by ``shift``),
and the image surface carries ``Lens.image_transform`` = the frame change that
takes the lens's image frame back to the camera's: axes along the camera's,
origin at (0, 0, z_image) where z_image is the untilted lens's image-surface z.
Every real ray then goes through the generic (geometry) kernels; the sensor
plane z = Z of a trace or a stream (``plane_z_mm``) is the camera's plane z = Z.

Signs: ``tilt_rad`` > 0 turns the lens's axis (+z) toward +y (the tilt of
:func:`lensrt.prescription.geometry.elementary_rotation` about x); ``swing_rad``
> 0 then turns it toward +x (about the lens's own y axis); ``shift_mm`` moves
the lens's axis to (x, y). The sensor seen from the lens is then tilted
by -tilt: the plane of sharp focus obeys the Scheimpflug condition (J. E. Greivenkamp,
Field Guide to Geometrical Optics, "Scheimpflug condition": tan(theta') = m tan(theta)
for the object and image planes' tilts from the plane normal to the lens axis,
m the magnification of the axial conjugates).

Only a centred, refractive lens can be tilted (a lens with mirrors or its own
transforms gets one clear error).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import LensrtError
from .frames import surface_frames
from .geometry import CoordinateTransform
from .model import Lens

__all__ = ["tilt_shift_lens", "lens_frame"]


def _turn(tilt_rad: float, swing_rad: float) -> CoordinateTransform:
    """The lens's turn: tilt about x (+z toward +y), then swing about the new y (+z toward +x)."""
    return CoordinateTransform(tilt_x_rad=float(tilt_rad), tilt_y_rad=-float(swing_rad))


def lens_frame(tilt_rad: float, shift_mm: tuple[float, float], pivot_z_mm: float, swing_rad: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """(origin, axes) of the tilted, swung, shifted lens's first-vertex frame in the camera frame.

    ``axes`` columns are the lens's x, y, z axes in camera coordinates; a lens-frame point p is
    the camera point ``origin + axes @ p``.
    """
    t = _turn(tilt_rad, swing_rad)
    rot = t.rotation()
    pivot = np.array([0.0, 0.0, float(pivot_z_mm)])
    origin = np.array([float(shift_mm[0]), float(shift_mm[1]), 0.0]) + pivot - rot @ pivot
    return origin, rot


def tilt_shift_lens(lens: Lens, tilt_rad: float = 0.0, shift_mm: tuple[float, float] = (0.0, 0.0),
                    pivot_z_mm: float | None = None, swing_rad: float = 0.0) -> Lens:
    """``lens`` tilted by ``tilt_rad`` about the x axis through (0, 0, ``pivot_z_mm``), swung by
    ``swing_rad`` about its own y axis (+z toward +x) and shifted by ``shift_mm`` (x, y) in front of a
    fixed sensor (module docstring).

    ``pivot_z_mm`` defaults to the stop's vertex. A zero tilt, swing and shift return ``lens`` itself.
    """
    tilt, swing = float(tilt_rad), float(swing_rad)
    sx, sy = (float(v) for v in shift_mm)
    if not all(math.isfinite(v) for v in (tilt, swing, sx, sy)):
        raise LensrtError("lens tilt, swing and shift must be finite numbers")
    for what, v in (("tilt", tilt), ("swing", swing)):
        if abs(v) >= math.radians(45.0):
            raise LensrtError(f"lens {what} {math.degrees(v):g} deg is beyond 45 deg",
                              hint="tilt-shift lenses tilt and swing by a few degrees (about 8 to 15 at most)")
    if tilt == 0.0 and swing == 0.0 and sx == 0.0 and sy == 0.0:
        return lens
    if not lens.is_centred or lens.has_mirrors:
        raise LensrtError("only a centred refractive lens can be tilted or shifted as a whole", path=lens.path,
                          hint="this lens already has mirrors, tilts/decenters or surface apertures")
    z = lens.vertex_z_mm()
    pivot = float(z[lens.stop_index]) if pivot_z_mm is None else float(pivot_z_mm)
    origin, _ = lens_frame(tilt, (sx, sy), pivot, swing)
    turn = _turn(tilt, swing)
    # T at the first surface: decenter first (in the camera frame), then the turn: o' = d, A' = R
    first = CoordinateTransform(*origin, tilt_x_rad=turn.tilt_x_rad, tilt_y_rad=turn.tilt_y_rad, order=0)
    moved = lens.replace_surface(0, transform_before=first)
    o_img, _ = surface_frames(moved)[-1]
    # back to the camera frame: the turn undone first (order 1, values negated: A'' = A R^T = I), then the
    # decenter in that frame
    back = CoordinateTransform(*(np.array([0.0, 0.0, float(z[-1])]) - o_img), tilt_x_rad=-turn.tilt_x_rad,
                               tilt_y_rad=-turn.tilt_y_rad, order=1)
    what = f"tilt {math.degrees(tilt):g} deg" + (f", swing {math.degrees(swing):g} deg" if swing else "")
    return moved.replace(image_transform=back, name=f"{lens.name} ({what}, shift {sx:g}, {sy:g} mm)")
