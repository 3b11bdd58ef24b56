"""The Scheimpflug condition in first order: the plane of sharp focus of a lens tilted in front of a sensor.

Field Guide to Geometrical Optics (Greivenkamp), "Scheimpflug condition": tan(theta') = m tan(theta) for the
object and image planes' tilts from the plane normal to the lens axis, m the magnification of the axial
conjugates. Here the sensor's tilt is seen from the lens (its normal in the lens frame), m comes from the
lens's first-order data at the point where the lens axis meets the sensor (Newton), and the plane in focus
is returned as z = z0 + (dz/dx) x + (dz/dy) y in the lens frame.
"""
from __future__ import annotations

import numpy as np

from lensrt.paraxial import first_order
from lensrt.prescription.tilt_shift import lens_frame

__all__ = ["scheimpflug_slopes"]


def scheimpflug_slopes(lens, tilt_rad: float, shift_mm, sensor_z_mm: float, swing_rad: float = 0.0
                       ) -> tuple[float, np.ndarray]:
    """(z of the axial object in focus, (dz/dx, dz/dy) of the plane in focus), lens frame, first order."""
    fo = first_order(lens)
    origin, rot = lens_frame(tilt_rad, shift_mm, float(lens.vertex_z_mm()[lens.stop_index]), swing_rad)
    q = rot.T @ (np.array([0.0, 0.0, sensor_z_mm]) - origin)   # a sensor point, lens frame
    n = rot.T @ np.array([0.0, 0.0, 1.0])                       # the sensor's normal, lens frame
    z_axis = q[2] + (n[0] * q[0] + n[1] * q[1]) / n[2]          # where the lens axis meets the sensor
    x_img = z_axis - fo.rear_focal_z_mm
    m = -x_img / fo.efl_mm                                       # Newton: m = -x'/f'
    return fo.front_focal_z_mm - fo.efl_mm ** 2 / x_img, np.array([-n[0] / n[2], -n[1] / n[2]]) / m
