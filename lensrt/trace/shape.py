"""The *shape* of a packed lens, and its constants laid out for a lens-specialised kernel.

A specialised kernel (:mod:`.specialised`) is generated per lens shape: the number
of surfaces, each surface's kind (plane, sphere, conic, even asphere with its
number of terms), which surfaces clip, the stop and the iris's kind (none, circle,
N-blade polygon, obstruction, rounded blades), and per medium whether it is a
constant index or which terms of the general dispersion formula it uses. The
numbers themselves -- curvatures, thicknesses, apertures, coefficients -- are not
part of the shape: they travel as one vector of constants, passed to the kernel
as a parameter (on a GPU it lands in the constant bank, read by the instructions
that use it), so refocusing or changing glasses compiles nothing; a new shape
compiles one module, cached on disk by Warp.

Everything here is host-side NumPy: :func:`lens_shape` reads the arrays of
:func:`lensrt.trace.pack.pack_arrays`; :class:`Layout` gives each constant's
position in the vector (static offsets for the kernel generator) and
:func:`constants` fills the vector.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from .pack import (IRIS_BLADES, IRIS_COS_HALF, IRIS_HALF, IRIS_OBSTRUCTION, IRIS_RADIUS, IRIS_ROTATION,
                   IRIS_ROUNDNESS, IRIS_STOP, MEDIUM_CONSTANT, S_ASPH, S_C, S_GEOM, S_IDEAL, S_KIND, S_KP1, S_NASPH,
                   S_SD2, S_THICK)

__all__ = ["PLANE", "SPHERE", "CONIC", "ASPHERE", "IRIS_NONE", "IRIS_CIRCLE", "IRIS_POLYGON", "MediumShape",
           "LensShape", "Layout", "lens_shape", "constants", "specialisable", "describe", "MAX_CONSTANTS", "MAX_BLADES_UNROLLED"]

PLANE, SPHERE, CONIC, ASPHERE = 0, 1, 2, 3
IRIS_NONE, IRIS_CIRCLE, IRIS_POLYGON = 0, 1, 2
#: more constants than this (a very long lens with many aspheres) -> the generic kernel
MAX_CONSTANTS = 480
#: polygons with more blades are tested with the generic angle formula
MAX_BLADES_UNROLLED = 24


@dataclass(frozen=True)
class MediumShape:
    """Which terms of the dispersion formula a medium uses (``constant``: a fixed index).

    ``poly`` from {0, 1, 2} (p0 + p1 w^2 + p2 w^4), ``inverse`` from {3..8} (p_k w^(-2(k-2))),
    ``sellmeier`` from {0, 1, 2} (b_j w^2 / (w^2 - c_j)), as in
    :func:`lensrt.prescription.materials.index_from_packed`.
    """

    constant: bool
    poly: tuple[int, ...] = ()
    inverse: tuple[int, ...] = ()
    sellmeier: tuple[int, ...] = ()


@dataclass(frozen=True)
class LensShape:
    """What a specialised kernel is generated for (module docstring); hashable."""

    n_surfaces: int
    kinds: tuple[int, ...]
    n_asphere: tuple[int, ...]
    clips: tuple[bool, ...]
    stop: int
    iris: int
    blades: int
    obstruction: bool
    rounded: bool
    media: tuple[MediumShape, ...]
    #: refraction at surface i is the identity (the same constant index on both sides)
    same_index: tuple[bool, ...]
    #: mirrors or coordinate transforms (pack.S_GEOM): only the generic kernel traces those
    geometry: bool = False
    #: an ideal paraxial lens (pack.S_IDEAL): only the generic kernel traces it (general variant)
    ideal: bool = False
    #: a surface kind beyond the even asphere (pack.SHAPE_KIND_CODES): only the generic kernel traces those
    shapes: bool = False


class Layout:
    """Offsets of every constant in the vector (static indices for the kernel generator)."""

    def __init__(self, shape: LensShape) -> None:
        n = shape.n_surfaces
        self.size = 0
        self.c = [-1] * (n + 1)
        self.kp1 = [-1] * (n + 1)
        self.sd2 = [-1] * (n + 1)
        self.thick = [-1] * (n + 1)
        self.asph = [-1] * (n + 1)
        for i in range(n):
            kind = shape.kinds[i]
            if kind != PLANE:
                self.c[i] = self._take()
            if kind in (CONIC, ASPHERE):
                self.kp1[i] = self._take()
            if shape.clips[i]:
                self.sd2[i] = self._take()
            self.thick[i] = self._take()
            if kind == ASPHERE:
                self.asph[i] = self._take(shape.n_asphere[i])
        self.n = [-1] * (n + 1)
        self.inv_n = [-1] * (n + 1)
        #: per medium: offsets of p_k (k = 0..8), b_j, c_j (j = 0..2); -1 when absent
        self.p: list[list[int]] = []
        self.b: list[list[int]] = []
        self.cs: list[list[int]] = []
        for m, ms in enumerate(shape.media):
            p, b, cs = [-1] * 9, [-1] * 3, [-1] * 3
            if ms.constant:
                self.n[m] = self._take()
                self.inv_n[m] = self._take()
            else:
                for k in ms.poly + ms.inverse:
                    p[k] = self._take()
                for j in ms.sellmeier:
                    b[j] = self._take()
                    cs[j] = self._take()
            self.p.append(p)
            self.b.append(b)
            self.cs.append(cs)
        self.iris_limit = self.iris_limit2 = self.iris_apothem = self.iris_obs2 = self.iris_round = -1
        self.blade_cos = self.blade_sin = -1
        if shape.iris != IRIS_NONE:
            self.iris_limit = self._take()
            self.iris_limit2 = self._take()
            if shape.obstruction:
                self.iris_obs2 = self._take()
            if shape.iris == IRIS_POLYGON:
                self.iris_apothem = self._take()
                self.iris_round = self._take()
                self.blade_cos = self._take(shape.blades)
                self.blade_sin = self._take(shape.blades)
        self.size = max(self.size, 1)

    def _take(self, count: int = 1) -> int:
        at = self.size
        self.size += count
        return at


def _medium_shape(row: np.ndarray) -> MediumShape:
    if row[0] == MEDIUM_CONSTANT:
        return MediumShape(True)
    p = row[1:]
    poly = tuple(k for k in range(3) if p[k] != 0.0 or k == 0)
    inverse = tuple(k for k in range(3, 9) if p[k] != 0.0)
    sellmeier = tuple(j for j in range(3) if p[9 + j] != 0.0)
    return MediumShape(False, poly, inverse, sellmeier)


def lens_shape(surf: np.ndarray, media: np.ndarray, iris_row: np.ndarray, clip: bool = True) -> LensShape:
    """The shape of packed arrays (:func:`lensrt.trace.pack.pack_arrays`); ``clip=False`` drops apertures."""
    n = surf.shape[0] - 1
    kinds, n_asph, clips, same = [], [], [], []
    stop = int(iris_row[IRIS_STOP])
    mshapes = tuple(_medium_shape(media[m]) for m in range(n + 1))
    for i in range(n):
        na = int(surf[i, S_NASPH])
        if na > 0:
            kind = ASPHERE
        elif surf[i, S_C] == 0.0:
            kind = PLANE
        elif surf[i, S_KP1] == 1.0:
            kind = SPHERE
        else:
            kind = CONIC
        kinds.append(kind)
        n_asph.append(na)
        clips.append(bool(clip and i != stop and surf[i, S_SD2] >= 0.0))
        same.append(bool(mshapes[i].constant and mshapes[i + 1].constant and media[i, 1] == media[i + 1, 1]))
    radius = float(iris_row[IRIS_RADIUS])
    blades = int(iris_row[IRIS_BLADES])
    if not clip or radius <= 0.0:
        mode, blades, obstruction, rounded = IRIS_NONE, 0, False, False
    else:
        mode = IRIS_POLYGON if blades > 0 else IRIS_CIRCLE
        obstruction = bool(iris_row[IRIS_OBSTRUCTION] > 0.0)
        rounded = bool(mode == IRIS_POLYGON and iris_row[IRIS_ROUNDNESS] != 0.0)
        if mode == IRIS_CIRCLE:
            blades = 0
    return LensShape(n, tuple(kinds), tuple(n_asph), tuple(clips), stop, mode, blades, obstruction, rounded,
                     mshapes, tuple(same), bool(surf[0, S_GEOM] != 0.0),
                     bool((surf[:, S_IDEAL] != 0.0).any()), bool(np.any(surf[:, S_KIND] >= 3.0)))


def constants(shape: LensShape, surf: np.ndarray, media: np.ndarray, iris_row: np.ndarray) -> np.ndarray:
    """The float64 vector of constants of ``shape`` (see :class:`Layout`)."""
    lay = Layout(shape)
    v = np.zeros(lay.size)
    for i in range(shape.n_surfaces):
        if lay.c[i] >= 0:
            v[lay.c[i]] = surf[i, S_C]
        if lay.kp1[i] >= 0:
            v[lay.kp1[i]] = surf[i, S_KP1]
        if lay.sd2[i] >= 0:
            v[lay.sd2[i]] = surf[i, S_SD2]
        v[lay.thick[i]] = surf[i, S_THICK]
        if lay.asph[i] >= 0:
            na = shape.n_asphere[i]
            v[lay.asph[i]:lay.asph[i] + na] = surf[i, S_ASPH:S_ASPH + na]
    for m, ms in enumerate(shape.media):
        if ms.constant:
            v[lay.n[m]] = media[m, 1]
            v[lay.inv_n[m]] = 1.0 / media[m, 1] if media[m, 1] > 0.0 else -1.0
        else:
            p = media[m, 1:]
            for k in range(9):
                if lay.p[m][k] >= 0:
                    v[lay.p[m][k]] = p[k]
            for j in range(3):
                if lay.b[m][j] >= 0:
                    v[lay.b[m][j]] = p[9 + j]
                    v[lay.cs[m][j]] = p[12 + j]
    if shape.iris != IRIS_NONE:
        limit = float(iris_row[IRIS_RADIUS])
        v[lay.iris_limit] = limit
        v[lay.iris_limit2] = limit * limit
        if shape.obstruction:
            v[lay.iris_obs2] = float(iris_row[IRIS_OBSTRUCTION]) ** 2
        if shape.iris == IRIS_POLYGON:
            half = float(iris_row[IRIS_HALF])
            v[lay.iris_apothem] = limit * float(iris_row[IRIS_COS_HALF])
            v[lay.iris_round] = float(iris_row[IRIS_ROUNDNESS])
            # outward normals of the blades: the edge midpoints lie at rotation + (2k + 1) pi / N
            theta = float(iris_row[IRIS_ROTATION]) + (2.0 * np.arange(shape.blades) + 1.0) * half
            v[lay.blade_cos:lay.blade_cos + shape.blades] = np.cos(theta)
            v[lay.blade_sin:lay.blade_sin + shape.blades] = np.sin(theta)
    return v


@lru_cache(maxsize=256)
def specialisable(shape: LensShape) -> bool:
    """False for shapes the generator leaves to the generic kernel (too many constants or blades,
    mirrors or coordinate transforms, ideal paraxial lenses, surface kinds beyond the even asphere); memoised,
    as every trace call asks."""
    return (not shape.geometry and not shape.ideal and not shape.shapes and shape.blades <= MAX_BLADES_UNROLLED
            and Layout(shape).size <= MAX_CONSTANTS)


def describe(shape: LensShape) -> dict[str, Any]:
    """A short, JSON-friendly description of a shape (for logs and ``StreamResult.extra``)."""
    names = {PLANE: "plane", SPHERE: "sphere", CONIC: "conic", ASPHERE: "asphere"}
    return {"surfaces": shape.n_surfaces,
            "kinds": [names[k] + (f"{shape.n_asphere[i]}" if k == ASPHERE else "") for i, k in enumerate(shape.kinds)],
            "iris": ["none", "circle", f"{shape.blades}-blade"][shape.iris],
            "glass_media": sum(not m.constant for m in shape.media)}
