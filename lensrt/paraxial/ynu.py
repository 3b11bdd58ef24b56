"""The ynu paraxial trace (Field Guide p. 3-4), float64 on the host.

At each surface ``n'u' = n u - y Phi`` with surface power ``Phi = c (n' - n)``,
then the transfer ``y_next = y + t u'``. u > 0 for a rising ray. The paraxial
curvature of an even asphere includes its r^2 term: c_par = c + 2 A2.

Mirrors (Field Guide p. 3; Zemax's and CODE V's convention): after a
reflection light travels toward -z, the thicknesses are negative and the
index is given the sign of the travel direction (n' = -n at a mirror), so
the same equations hold: a mirror's power is Phi = -2 n c and every reduced
thickness t / n stays positive. ``ParaxialSystem.index`` holds these signed
indices. Tilts and decenters are ignored here: the paraxial data of a lens
with coordinate transforms are those of its unfolded axis (exact for fold
mirrors that are tilted flats).

An ideal paraxial lens (``Surface.ideal_focal_mm``, OpticStudio's ``TYPE
PARAXIAL``) is a plane of power Phi = 1 / f: ``n'u' = n u - y / f`` whatever
the media (as OpticStudio and optiland define it), so its focal lengths are
f_E = f, and n f, n' f in the media on either side.

Everything here also works with 2x2 reduced matrices on (y, n u): refraction
``[[1, 0], [-Phi, 1]]`` and transfer ``[[1, t / n], [0, 1]]`` (det = 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.keep import kept
from ..prescription.model import Lens

__all__ = ["ParaxialSystem", "ParaxialRay", "paraxial_system", "trace_ynu", "trace_ynu_reverse"]


@dataclass(frozen=True)
class ParaxialSystem:
    """A lens reduced to paraxial data at one wavelength.

    Attributes
    ----------
    curvature_per_mm : ndarray (N,)
        Paraxial curvature of each surface (c + 2 A2).
    thickness_mm : ndarray (N,)
        Thickness after each surface (the last runs to the image surface).
    index : ndarray (N + 1,)
        Object-space index, then the index after each surface, signed by the
        direction of travel (negative after an odd number of mirrors).
    power_per_mm : ndarray (N,)
        Surface powers Phi = c (n' - n).
    stop_index : int
        0-based index of the stop surface.
    wavelength_nm : float
    """

    curvature_per_mm: np.ndarray
    thickness_mm: np.ndarray
    index: np.ndarray
    power_per_mm: np.ndarray
    stop_index: int
    wavelength_nm: float

    @property
    def n_surfaces(self) -> int:
        return len(self.curvature_per_mm)

    @property
    def vertex_z_mm(self) -> np.ndarray:
        """z of each vertex (first = 0), then of the image surface."""
        return np.concatenate([[0.0], np.cumsum(self.thickness_mm)])

    def refraction(self, i: int) -> np.ndarray:
        return np.array([[1.0, 0.0], [-self.power_per_mm[i], 1.0]])

    def transfer(self, i: int) -> np.ndarray:
        return np.array([[1.0, self.thickness_mm[i] / self.index[i + 1]], [0.0, 1.0]])

    def matrix(self, first: int, last: int, include_last_transfer: bool = False) -> np.ndarray:
        """Reduced matrix from just before surface ``first`` to just after surface ``last``.

        Transfers between the surfaces are included; the transfer after
        ``last`` only if ``include_last_transfer``.
        """
        m = np.eye(2)
        for i in range(first, last + 1):
            m = self.refraction(i) @ m
            if i < last or include_last_transfer:
                m = self.transfer(i) @ m
        return m


def paraxial_system(lens: Lens, wavelength_nm: float | None = None) -> ParaxialSystem:
    """Reduce ``lens`` to paraxial data at ``wavelength_nm`` (default: the primary).

    Kept per (lens, wavelength) in this process (first-order data, paraxial chief rays and Seidel sums
    ask for the same ones many times); the arrays of a kept system are read-only."""
    w = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    return kept(_KNOWN, (lens, w), lambda: _read_only(_paraxial_system(lens, w)), _KNOWN_KEPT)


def _read_only(sysm: ParaxialSystem) -> ParaxialSystem:
    for a in (sysm.curvature_per_mm, sysm.thickness_mm, sysm.index, sysm.power_per_mm):
        a.flags.writeable = False
    return sysm


#: paraxial systems already reduced, per (lens, wavelength nm); at most _KNOWN_KEPT
_KNOWN: dict = {}
_KNOWN_KEPT = 512


def _paraxial_system(lens: Lens, w: float) -> ParaxialSystem:
    """:func:`paraxial_system` at wavelength ``w`` (nm), computed."""
    c = np.array([s.paraxial_curvature_per_mm for s in lens.surfaces])  # the vertex's osculating sphere
    t = np.array([s.thickness_mm for s in lens.surfaces], dtype=np.float64)
    n = np.asarray(lens.indices(w), dtype=np.float64)
    if lens.has_mirrors:
        sign, signs = 1.0, [1.0]
        for sf in lens.surfaces:
            sign = -sign if sf.mirror else sign
            signs.append(sign)
        n = n * np.asarray(signs)
    phi = c * (n[1:] - n[:-1])
    for i, sf in enumerate(lens.surfaces):
        if sf.ideal_focal_mm is not None:
            phi[i] = 1.0 / sf.ideal_focal_mm  # an ideal lens: power 1/f (a plane, c = 0)
    return ParaxialSystem(c, t, n, phi, lens.stop_index, w)


@dataclass(frozen=True)
class ParaxialRay:
    """A traced paraxial ray.

    ``y[i]`` is the height at surface i (i = N: the image surface); ``u[0]``
    the object-space slope and ``u[i + 1]`` the slope after surface i.
    ``i_angle[i]`` is the paraxial angle of incidence at surface i
    (i = y c + u), so ``n[i] * i_angle[i]`` is CODE V's N*I column.
    """

    y: np.ndarray
    u: np.ndarray
    n: np.ndarray
    i_angle: np.ndarray

    @property
    def nu(self) -> np.ndarray:
        """Reduced slopes n u (object space first)."""
        return self.n * self.u

    def height_at(self, distance_mm: float) -> float:
        """Height (mm) in image space at ``distance_mm`` after the last surface's vertex."""
        return float(self.y[-2] + distance_mm * self.u[-1])

    def axis_crossing_mm(self) -> float:
        """Distance after the last vertex where the ray crosses the axis (inf if parallel)."""
        return float("inf") if self.u[-1] == 0.0 else float(-self.y[-2] / self.u[-1])


def trace_ynu(system: ParaxialSystem, y1_mm: float, u0: float) -> ParaxialRay:
    """Trace a paraxial ray that meets surface 1 at height ``y1_mm`` with object-space slope ``u0``.

    Returns heights at every surface and at the image surface, and slopes.
    """
    N = system.n_surfaces
    y = np.empty(N + 1)
    u = np.empty(N + 1)
    inc = np.empty(N)
    n = system.index
    y[0], u[0] = y1_mm, u0
    for i in range(N):
        inc[i] = y[i] * system.curvature_per_mm[i] + u[i]
        u[i + 1] = (n[i] * u[i] - y[i] * system.power_per_mm[i]) / n[i + 1]
        y[i + 1] = y[i] + system.thickness_mm[i] * u[i + 1]
    return ParaxialRay(y, u, n.copy(), inc)


def trace_ynu_reverse(system: ParaxialSystem, y_last_mm: float, u_image: float) -> ParaxialRay:
    """Trace a paraxial ray backward from image space to object space.

    The ray is given by its height ``y_last_mm`` at the last surface and its
    image-space slope ``u_image`` (after the last surface). Each refraction is
    inverted, ``n u = n' u' + y Phi``, and each transfer runs backward,
    ``y_prev = y - t u``. The result has the same layout as :func:`trace_ynu`
    (heights at every surface and at the image surface, object-space slope
    first), so a reverse trace of a forward-traced ray returns that ray.
    """
    N = system.n_surfaces
    y = np.empty(N + 1)
    u = np.empty(N + 1)
    inc = np.empty(N)
    n = system.index
    y[N - 1], u[N] = y_last_mm, u_image
    y[N] = y_last_mm + system.thickness_mm[N - 1] * u_image
    for i in range(N - 1, -1, -1):
        u[i] = (n[i + 1] * u[i + 1] + y[i] * system.power_per_mm[i]) / n[i]
        inc[i] = y[i] * system.curvature_per_mm[i] + u[i]
        if i > 0:
            y[i - 1] = y[i] - system.thickness_mm[i - 1] * u[i]
    return ParaxialRay(y, u, n.copy(), inc)
