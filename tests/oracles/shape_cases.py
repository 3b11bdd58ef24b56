"""Lenses with the surface kinds of :mod:`lensrt.prescription.shapes` (odd, Q-type, biconic, toroidal).

Steep cases on purpose: a phone-camera-like element (f ~ 4 mm, strongly aspheric rear surface with
an inflection), a fast Q-type singlet, and anamorphic (biconic, toroidal) elements. Used by the
kernel-versus-reference tests and the reader round trips.
"""
from __future__ import annotations

import math

import numpy as np

from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.prescription.shapes import SurfaceShape

WL_NM = 587.56
GLASS = ConstantIndex(1.544)


def _lens(surfaces: list[Surface], epd_mm: float) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", epd_mm), fields=Fields("angle", (0.0, math.radians(30.0))),
                wavelengths=Wavelengths((WL_NM,)))


def phone_odd_qcon() -> Lens:
    """A steep phone-camera-like doublet of two plastic elements: odd asphere front, Q^con rear with an
    inflection, Q^bfs on the second element."""
    return _lens([
        Surface(1 / 1.6, 0.9, GLASS, 1.2, conic=-0.3, is_stop=True,
                shape=SurfaceShape("odd", (0.0, 0.0, 0.012, -0.035, 0.02), 1.0)),
        Surface(1 / 6.0, 0.6, semi_diameter_mm=1.3, conic=4.0,
                shape=SurfaceShape("qcon", (0.02, -0.012, 0.004, -0.001), 1.3)),
        Surface(-1 / 3.0, 0.7, GLASS, 1.6, shape=SurfaceShape("qbfs", (0.03, -0.01, 0.004, 0.0015), 1.6)),
        Surface(1 / 2.4, 1.2, semi_diameter_mm=2.0, conic=-1.5,
                shape=SurfaceShape("qcon", (-0.05, 0.02, -0.006), 2.0)),
    ], 2.0)


def anamorphic() -> Lens:
    """A biconic front and a toroidal rear (y-profile with a conic and even terms)."""
    return _lens([
        Surface(1 / 12.0, 3.0, GLASS, 5.0, conic=-0.5, is_stop=True,
                shape=SurfaceShape("biconic", curvature_x_per_mm=1 / 20.0, conic_x=0.8)),
        Surface(-1 / 30.0, 20.0, semi_diameter_mm=5.0, conic=1.5, asphere=(0.0, 2e-5, -1e-7),
                shape=SurfaceShape("toroidal", curvature_x_per_mm=-1 / 15.0)),
    ], 8.0)


def ray_fan(half_width_mm: float, angle_deg: float = 0.0, n: int = 7, z0_mm: float = -2.0
            ) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of an n x n grid of parallel rays, tilted by ``angle_deg`` about x and y."""
    g = np.linspace(-half_width_mm, half_width_mm, n)
    x, y = (v.ravel() for v in np.meshgrid(g, g))
    t = math.radians(angle_deg)
    o = np.stack([x, y, np.full_like(x, z0_mm)], axis=1)
    d = np.tile([0.3 * math.sin(t), math.sin(t), math.cos(t)], (len(x), 1))
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def freeform() -> Lens:
    """An XY polynomial front (tilt, astigmatism, coma-like and trefoil terms) and a Zernike rear (defocus,
    astigmatism, coma, trefoil, spherical) over conics and even terms."""
    xy = (1e-3, -2e-3, 0.02, 0.01, -0.015, 0.004, -0.003, 0.002, 0.005, -0.002, 0.0, 0.001, 0.0, 0.003)
    zern = (0.01, 0.002, -0.003, 0.05, 0.02, -0.03, 0.01, 0.008, -0.006, 0.004, 0.015)
    return _lens([
        Surface(1 / 15.0, 3.0, GLASS, 5.0, conic=-0.4, asphere=(0.0, 1e-5), is_stop=True,
                shape=SurfaceShape("xy", xy, 5.0)),
        Surface(-1 / 25.0, 20.0, semi_diameter_mm=5.0, asphere=(0.0, -2e-5),
                shape=SurfaceShape("zernike", zern, 5.0)),
    ], 8.0)


def fringe() -> Lens:
    """A Zernike fringe sag front (OpticStudio's FZERNSAG: tilt, defocus, astigmatism, coma, spherical, trefoil and
    the 12th-order spherical term F_37) over a conic and an even term, and a fringe rear with a few terms."""
    front = (0.0, 2e-3, -1e-3, 0.02, 0.01, -0.008, 0.004, 0.003, 0.006, -0.002, 0.001, 0.0, 0.0, 0.0, 0.0, 0.002) + \
        (0.0,) * 20 + (5e-4,)
    return _lens([
        Surface(1 / 15.0, 3.0, GLASS, 5.0, conic=-0.4, asphere=(0.0, 1e-5), is_stop=True,
                shape=SurfaceShape("zernike_fringe", front, 5.0)),
        Surface(-1 / 25.0, 20.0, semi_diameter_mm=5.0, shape=SurfaceShape("zernike_fringe", (0.0, 0.0, 0.0, -0.01,
                                                                                           0.0, 0.004), 5.5)),
    ], 8.0)
