"""Surface geometry beyond the rotationally symmetric lens: coordinate transforms and surface apertures.

Both are immutable values that a :class:`~lensrt.prescription.model.Surface`
may carry; a rotationally symmetric lens carries none (identity transforms,
circular semi-diameters) and keeps every result it had.

Coordinate transforms (``docs/guide/geometry.md`` sets the Zemax and CODE V
semantics side by side). A transform maps the current local frame -- origin
``o``, axes the columns of ``A`` (global coordinates) -- to a new one. With
``order = 0`` (OpticStudio's coordinate break order 0, CODE V's decenters)
the decenter comes first, then the tilts about x, then the new y, then the
new z::

    o' = o + A d,       A' = A R,       R = Rx(alpha) Ry(beta) Rz(gamma)

and with ``order = 1`` the tilts come first, in reverse order (z, y, x), and
the decenter is measured in the tilted frame::

    A' = A R',   R' = Rz(gamma) Ry(beta) Rx(alpha),   o' = o + A' d

so that the transform with every value negated and the order toggled undoes
it exactly (OpticStudio's rule; :meth:`CoordinateTransform.inverse`).

Sign of the tilts: lensrt follows the optical-design convention of CODE V
(and rayoptics' readers of both formats): alpha and beta are *left-handed*,
gamma right-handed. A positive alpha turns the new +z axis toward +y, a
positive beta turns it toward -x, a positive gamma turns +x toward +y
(:func:`elementary_rotation`). Written
as right-handed rotation matrices, ``Rx(alpha) = rot_x(-alpha)``,
``Ry(beta) = rot_y(-beta)``, ``Rz(gamma) = rot_z(gamma)``.

Surface apertures (OpticStudio's ``CLAP``/``OBSC``/``SQAP``/``ELAP``, CODE V's
``CIR``/``REX``/``ELX`` with ``OBS``/``HOL``): a shape in the surface's local
x-y plane, optionally decentred, that either passes (a clear aperture) or
blocks (an obscuration) the rays inside it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import PrescriptionError

__all__ = ["CoordinateTransform", "SurfaceAperture", "APERTURE_SHAPES", "elementary_rotation",
           "compose_frame"]

#: shapes of a surface aperture: circle (``a`` = radius), annulus (``b`` inner radius, ``a`` outer),
#: rectangle (``a``, ``b`` = half-widths in x, y), ellipse (``a``, ``b`` = semi-axes in x, y)
APERTURE_SHAPES = ("circle", "annulus", "rectangle", "ellipse")


def _num(value: float, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PrescriptionError(f"{what} {value!r} is not a number") from None
    if not math.isfinite(v):
        raise PrescriptionError(f"{what} is {value!r}", hint="give a finite number")
    return v


def elementary_rotation(axis: str, angle_rad: float) -> np.ndarray:
    """The rotation matrix of one tilt in lensrt's (CODE V's) sign convention.

    Columns are the new axes in the old frame. ``axis`` "x" (alpha) and "y"
    (beta) are left-handed: alpha > 0 turns +z toward +y, beta > 0 turns +z
    toward -x; "z" (gamma) is right-handed: gamma > 0 turns +x toward +y.
    """
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    if axis == "x":  # right-handed rot_x(-alpha)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])
    if axis == "y":  # right-handed rot_y(-beta)
        return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    if axis == "z":
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    raise ValueError(f"axis {axis!r} is not x, y or z")


@dataclass(frozen=True)
class CoordinateTransform:
    """A rigid change of the local frame: decenters (mm), tilts (rad) and their order.

    See the module docstring for the composition and signs. ``order`` 0:
    decenter, then tilt x, y, z; 1: tilt z, y, x, then decenter.
    """

    decenter_x_mm: float = 0.0
    decenter_y_mm: float = 0.0
    decenter_z_mm: float = 0.0
    tilt_x_rad: float = 0.0
    tilt_y_rad: float = 0.0
    tilt_z_rad: float = 0.0
    order: int = 0

    def __post_init__(self) -> None:
        for name in ("decenter_x_mm", "decenter_y_mm", "decenter_z_mm", "tilt_x_rad", "tilt_y_rad", "tilt_z_rad"):
            object.__setattr__(self, name, _num(getattr(self, name), name.replace("_", " ")))
        if self.order not in (0, 1) or isinstance(self.order, bool):
            raise PrescriptionError(f"transform order {self.order!r} is not 0 or 1",
                                    hint="0: decenter then tilts x, y, z; 1: tilts z, y, x then decenter")

    @property
    def is_identity(self) -> bool:
        return not any((self.decenter_x_mm, self.decenter_y_mm, self.decenter_z_mm,
                        self.tilt_x_rad, self.tilt_y_rad, self.tilt_z_rad))

    @property
    def has_tilt(self) -> bool:
        return bool(self.tilt_x_rad or self.tilt_y_rad or self.tilt_z_rad)

    @property
    def decenter_mm(self) -> np.ndarray:
        return np.array([self.decenter_x_mm, self.decenter_y_mm, self.decenter_z_mm])

    def rotation(self) -> np.ndarray:
        """R (order 0) or R' (order 1): the new axes, as columns, in the old frame."""
        rx = elementary_rotation("x", self.tilt_x_rad)
        ry = elementary_rotation("y", self.tilt_y_rad)
        rz = elementary_rotation("z", self.tilt_z_rad)
        return rx @ ry @ rz if self.order == 0 else rz @ ry @ rx

    def apply(self, origin: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The new frame (origin, axes) from the frame (``origin``, ``axes``), global coordinates."""
        rot = axes @ self.rotation()
        if self.order == 0:
            return origin + axes @ self.decenter_mm, rot
        return origin + rot @ self.decenter_mm, rot

    def inverse(self) -> "CoordinateTransform":
        """The transform that undoes this one: values negated, order toggled (exact)."""
        return CoordinateTransform(-self.decenter_x_mm, -self.decenter_y_mm, -self.decenter_z_mm,
                                   -self.tilt_x_rad, -self.tilt_y_rad, -self.tilt_z_rad, 1 - self.order)


def compose_frame(origin: np.ndarray, axes: np.ndarray, transform: CoordinateTransform | None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``transform`` applied to a frame; the frame itself when ``transform`` is None."""
    if transform is None:
        return origin, axes
    return transform.apply(origin, axes)


@dataclass(frozen=True)
class SurfaceAperture:
    """A clear aperture or an obscuration on one surface (local x-y plane, mm).

    ``shape`` in :data:`APERTURE_SHAPES`; ``a``/``b`` as documented there;
    ``decenter_x_mm``/``decenter_y_mm`` move the shape's centre;
    ``rotation_rad`` turns it (counter-clockwise from +x). ``obscuration``
    True blocks the inside instead of passing it.
    """

    shape: str = "circle"
    a: float = 0.0
    b: float = 0.0
    decenter_x_mm: float = 0.0
    decenter_y_mm: float = 0.0
    rotation_rad: float = 0.0
    obscuration: bool = False

    def __post_init__(self) -> None:
        if self.shape not in APERTURE_SHAPES:
            raise PrescriptionError(f"unknown aperture shape {self.shape!r}",
                                    hint=f"use one of {', '.join(APERTURE_SHAPES)}")
        for name in ("a", "b", "decenter_x_mm", "decenter_y_mm", "rotation_rad"):
            object.__setattr__(self, name, _num(getattr(self, name), f"aperture {name}"))
        if self.a <= 0.0:
            raise PrescriptionError(f"{self.shape} aperture size {self.a:g} mm must be positive")
        if self.shape in ("rectangle", "ellipse") and self.b <= 0.0:
            raise PrescriptionError(f"{self.shape} aperture y size {self.b:g} mm must be positive")
        if self.shape == "annulus" and not 0.0 <= self.b < self.a:
            raise PrescriptionError(f"annular aperture inner radius {self.b:g} mm must be within [0, {self.a:g})")
        if self.shape == "circle" and self.b != 0.0:
            raise PrescriptionError("a circular aperture has one size (its radius)")
        object.__setattr__(self, "obscuration", bool(self.obscuration))

    def inside(self, x_mm: float, y_mm: float, tolerance: float = 0.0) -> bool:
        """True when (x, y) lies inside the shape (its edge grown by the relative ``tolerance``)."""
        u, v = x_mm - self.decenter_x_mm, y_mm - self.decenter_y_mm
        if self.rotation_rad:
            c, s = math.cos(self.rotation_rad), math.sin(self.rotation_rad)
            u, v = c * u + s * v, -s * u + c * v
        g = 1.0 + tolerance
        if self.shape == "circle":
            return u * u + v * v <= (self.a * g) ** 2
        if self.shape == "annulus":
            r2 = u * u + v * v
            return (self.b / g) ** 2 <= r2 <= (self.a * g) ** 2
        if self.shape == "rectangle":
            return abs(u) <= self.a * g and abs(v) <= self.b * g
        return (u / (self.a * g)) ** 2 + (v / (self.b * g)) ** 2 <= 1.0

    def passes(self, x_mm: float, y_mm: float, tolerance: float = 0.0) -> bool:
        """True when a ray at (x, y) goes on: inside a clear aperture, outside an obscuration."""
        if self.obscuration:
            return not self.inside(x_mm, y_mm, -tolerance)
        return self.inside(x_mm, y_mm, tolerance)

    def describe(self) -> str:
        what = "obscuration" if self.obscuration else "aperture"
        size = {"circle": f"r {self.a:g}", "annulus": f"r {self.b:g}..{self.a:g}",
                "rectangle": f"{2 * self.a:g} x {2 * self.b:g}", "ellipse": f"{self.a:g} x {self.b:g} semi-axes"}
        dec = f" at ({self.decenter_x_mm:g}, {self.decenter_y_mm:g})" if self.decenter_x_mm or self.decenter_y_mm \
            else ""
        return f"{self.shape} {what} {size[self.shape]} mm{dec}"
