"""Shared geometry test systems: a fold mirror, a tilted/decentred pair, a Mangin mirror, a Cassegrain.

Used by the optiland comparison, the kernel-vs-reference tests and the reader/model tests
(``tests/trace/test_geometry_*.py``, ``tests/prescription/test_geometry.py``).
"""
from __future__ import annotations

import math

import numpy as np

from lensrt.prescription.geometry import CoordinateTransform, SurfaceAperture
from lensrt.prescription.materials import AIR, ModelGlass
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths

__all__ = ["WL_NM", "BK7", "ray_grid", "folded_system", "tilted_decentred_system", "mangin_system",
           "cassegrain_system", "SYSTEMS"]

WL_NM = 587.5618
BK7 = ModelGlass(1.5168, 64.17, name="BK7-model")


def ray_grid(half_width_mm: float, angle_deg: float = 0.0, z0_mm: float = -5.0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of a 7 x 7 grid of parallel rays (global), tilted by ``angle_deg`` about x."""
    g = np.linspace(-half_width_mm, half_width_mm, 7)
    x, y = (v.ravel() for v in np.meshgrid(g, g))
    t = math.radians(angle_deg)
    o = np.stack([x, y, np.full_like(x, z0_mm)], axis=1)
    d = np.tile([0.0, math.sin(t), math.cos(t)], (len(x), 1))
    return o, d


def _lens(surfaces: list[Surface], **kw) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0, math.radians(1.0))),
                wavelengths=Wavelengths((WL_NM,)), **kw)


def folded_system() -> Lens:
    """A singlet, then a flat mirror tilted 45 deg about x that folds the beam (CODE V BEN)."""
    tilt = CoordinateTransform(tilt_x_rad=math.radians(45.0))
    return _lens([Surface(1 / 60.0, 4.0, BK7, is_stop=True), Surface(-1 / 200.0, 40.0, AIR),
                  Surface(0.0, -55.0, AIR, mirror=True, transform_before=tilt,
                          transform_after=CoordinateTransform(tilt_x_rad=math.radians(45.0)))])


def tilted_decentred_system() -> Lens:
    """A singlet decentred 1.5 mm in x and y, tilted 4 deg about y and 3 about x (then returned, CODE V DAR),
    and a second element behind a basic decenter with a tilt about z (order 1)."""
    t = CoordinateTransform(decenter_x_mm=1.5, decenter_y_mm=-1.0, tilt_x_rad=math.radians(3.0),
                            tilt_y_rad=math.radians(4.0))
    u = CoordinateTransform(decenter_y_mm=0.7, tilt_x_rad=math.radians(-2.0), tilt_z_rad=math.radians(20.0), order=1)
    return _lens([Surface(1 / 50.0, 5.0, BK7, is_stop=True, transform_before=t),
                  Surface(-1 / 80.0, 10.0, AIR, transform_after=t.inverse()),
                  Surface(1 / 120.0, 3.0, BK7, transform_before=u), Surface(0.0, 60.0, AIR)])


def mangin_system() -> Lens:
    """rayoptics' mangin.seq (R -1200 front, R -1000 silvered back, BK7-like glass), scaled to 1/10."""
    return _lens([Surface(-1 / 120.0, 1.0, BK7, is_stop=True), Surface(-1 / 100.0, -1.0, BK7, mirror=True),
                  Surface(-1 / 120.0, -50.0, AIR)])


def cassegrain_system(obscuration_mm: float = 4.0) -> Lens:
    """A classical Cassegrain with the secondary's central obscuration in the stop plane.

    Paraboloid primary R = -200 mm (f1 = 100), convex secondary R = -70 mm 70 mm in front of it, so 30 mm
    inside the primary focus: it images that focus 210 mm away, magnification m = 7, and its conic
    -((m + 1) / (m - 1))^2 = -16/9 leaves the axial image free of spherical aberration (EFL 700 mm).
    """
    obs = SurfaceAperture("circle", obscuration_mm, obscuration=True)
    return _lens([Surface(0.0, 30.0, AIR, is_stop=True, apertures=(obs,)),
                  Surface(-1 / 200.0, -70.0, AIR, mirror=True, conic=-1.0),
                  Surface(-1 / 70.0, 110.0, AIR, mirror=True, conic=-16.0 / 9.0)])


SYSTEMS = {"folded": folded_system, "tilted_decentred": tilted_decentred_system, "mangin": mangin_system,
           "cassegrain": cassegrain_system}
