"""A :class:`~lensrt.prescription.model.Lens` packed into flat arrays for the Warp kernels.

One row per surface plus one for the image surface (a plane, or a sphere of curvature
``Lens.image_curvature_per_mm``: kind 1, traced by the general kernel variant only)::

    surf[i] = [c, 1 + k, sd^2 (-1: no clip), thickness to the next vertex, kind (0 plane,
               1 conic, 2 even asphere, 3.. a shape: SHAPE_KIND_CODES), number of asphere terms, a_0 .. a_9,
               geometry and aperture columns, (only with shapes:) R_n, n_terms, cx, 1 + kx, terms]

``a_j`` multiplies r^(2j+2) (``asphere[0]`` is the r^2 term, as in the model).
An ideal paraxial lens stores its power 1/f in ``S_IDEAL`` (and makes the lens one for the
general kernel variant, with its frames). A lens with mirrors, coordinate transforms, shaped surfaces or
an ideal lens (``S_GEOM`` = 1 in every row) also
carries, per surface and for the image, whether it reflects (``S_MIRROR``), the
direction light travels along its local z as it arrives (``S_SIGN``, -1 after an
odd number of mirrors) and its global frame (``S_ORIGIN``, ``S_AXES``); its
curvature and asphere terms are then stored multiplied by that sign (the surface
seen in the frame mirrored in z, as :mod:`.reference_general` meets it).
``media[m]`` holds medium m (0 = object space, m = i + 1 after surface i):
``[0, n]`` for a constant index (air included) or ``[1, p_0 .. p_14]`` with the 15
coefficients of :func:`lensrt.prescription.materials.index_from_packed`.
``iris`` is ``[stop index, radius (-1: no clip), blades, rotation rad, roundness,
obstruction radius, cos(pi / N), pi / N]``. Apertures are stored with
:data:`~lensrt.trace.status.APERTURE_TOLERANCE` applied.

Packing happens once per (lens, precision, device, iris, stop radius):
:func:`pack_lens` caches its result.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.telemetry import upload
from ..errors import LensrtError
from ..prescription.materials import DISPERSION_WIDTH
from ..prescription.model import Iris, Lens, Surface
from ..prescription.shapes import profile_of
from .status import APERTURE_TOLERANCE

__all__ = ["S_C", "S_KP1", "S_SD2", "S_THICK", "S_KIND", "S_NASPH", "S_ASPH", "MAX_ASPHERE", "SURF_COLS",
           "S_MIRROR", "S_SIGN", "S_GEOM", "S_ORIGIN", "S_AXES", "S_APER", "MAX_SURFACE_APERTURES", "APERTURE_COLS",
           "APERTURE_SHAPE_CODES", "pack_geometry", "S_IDEAL", "SHAPE_KIND_CODES", "S_X", "X_RN", "X_NT", "X_CX",
           "X_KXP1", "X_TERMS",
           "MEDIUM_CONSTANT", "MEDIUM_FORMULA", "MEDIA_COLS", "IRIS_STOP", "IRIS_RADIUS", "IRIS_BLADES",
           "IRIS_ROTATION", "IRIS_ROUNDNESS", "IRIS_OBSTRUCTION", "IRIS_COS_HALF", "IRIS_HALF", "IRIS_COLS",
           "pack_arrays", "index_table", "PackedLens", "pack_lens", "real_dtype"]

S_C, S_KP1, S_SD2, S_THICK, S_KIND, S_NASPH, S_ASPH = range(7)
MAX_ASPHERE = 10
#: geometry columns after the asphere block (module docstring): mirror flag, travel sign at the
#: surface, lens-wide geometry flag, the surface frame's origin (3) and axes (9, row-major, columns = axes)
S_MIRROR = S_ASPH + MAX_ASPHERE
S_SIGN, S_GEOM, S_ORIGIN = S_MIRROR + 1, S_MIRROR + 2, S_MIRROR + 3
S_AXES = S_ORIGIN + 3
#: up to MAX_SURFACE_APERTURES surface apertures per surface, APERTURE_COLS columns each from S_APER:
#: shape code (0 none, 1 circle, 2 annulus, 3 rectangle, 4 ellipse), a, b, decenter x, y, cos and sin
#: of the rotation, obscuration flag (sizes with APERTURE_TOLERANCE applied)
S_APER = S_AXES + 9
MAX_SURFACE_APERTURES = 2
APERTURE_COLS = 8
#: ideal paraxial lenses (Surface.ideal_focal_mm): the power 1/f at the surface (0: none); only the general
#: kernel variant looks at it (a lens with one is packed as a general lens)
S_IDEAL = S_APER + MAX_SURFACE_APERTURES * APERTURE_COLS
SURF_COLS = S_IDEAL + 1
APERTURE_SHAPE_CODES = {"circle": 1, "annulus": 2, "rectangle": 3, "ellipse": 4}
#: surface kinds beyond the even asphere (S_KIND >= 3, :mod:`lensrt.prescription.shapes`): their terms sit in
#: extra columns from S_X = SURF_COLS -- normalisation radius, number of terms, x curvature, 1 + x conic, the
#: terms (Q^bfs in the P basis, xy and Zernike as monomials in (x, y) / R_n) -- present only when the lens has
#: such a surface (the row is then wider)
SHAPE_KIND_CODES = {"odd": 3, "qbfs": 4, "qcon": 5, "biconic": 6, "toroidal": 7, "xy": 8, "zernike": 8,
                    "zernike_fringe": 8}
S_X = SURF_COLS
X_RN, X_NT, X_CX, X_KXP1, X_TERMS = range(5)
MEDIUM_CONSTANT, MEDIUM_FORMULA = 0.0, 1.0
MEDIA_COLS = 1 + DISPERSION_WIDTH
(IRIS_STOP, IRIS_RADIUS, IRIS_BLADES, IRIS_ROTATION, IRIS_ROUNDNESS, IRIS_OBSTRUCTION, IRIS_COS_HALF,
 IRIS_HALF) = range(8)
IRIS_COLS = 8

_CACHE: "OrderedDict[tuple, PackedLens]" = OrderedDict()
_CACHE_SIZE = 32


def pack_arrays(lens: Lens, iris: Iris | None = None,
                stop_radius_mm: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(surf, media, iris) float64 host arrays of ``lens`` (module docstring).

    Mirrors, coordinate transforms and surface apertures fill the geometry
    columns (:func:`pack_geometry`).
    """
    n = lens.n_surfaces
    terms = [len(profile_of(s).terms) for s in lens.surfaces if s.shape is not None]
    width = SURF_COLS if not terms else S_X + X_TERMS + max(terms)
    surf = np.zeros((n + 1, width))
    for i, s in enumerate(lens.surfaces):
        if len(s.asphere) > MAX_ASPHERE:
            raise LensrtError(f"surface {i + 1} has {len(s.asphere)} aspheric terms; the tracer takes "
                              f"at most {MAX_ASPHERE} (r^2 .. r^{2 * MAX_ASPHERE})")
        surf[i, S_C] = s.curvature_per_mm
        surf[i, S_KP1] = 1.0 + s.conic
        sd = s.semi_diameter_mm if lens.clips_semi_diameter(i) else None
        surf[i, S_SD2] = -1.0 if sd is None else (sd * (1.0 + APERTURE_TOLERANCE)) ** 2
        surf[i, S_THICK] = s.thickness_mm
        surf[i, S_KIND] = 2.0 if s.asphere else (1.0 if s.curvature_per_mm != 0.0 else 0.0)
        surf[i, S_NASPH] = len(s.asphere)
        surf[i, S_ASPH:S_ASPH + len(s.asphere)] = s.asphere
        if s.ideal_focal_mm is not None:
            surf[i, S_IDEAL] = 1.0 / s.ideal_focal_mm
        if s.shape is not None:
            _pack_shape(s, surf[i])
    surf[n, S_KP1] = 1.0
    surf[n, S_SD2] = -1.0
    if lens.image_curvature_per_mm != 0.0:  # a spherical image surface (pack_geometry marks the lens general)
        surf[n, S_C] = lens.image_curvature_per_mm
        surf[n, S_KIND] = 1.0
    pack_geometry(lens, surf)
    media = np.zeros((n + 1, MEDIA_COLS))
    for m, mat in enumerate(lens.media()):
        p = np.asarray(mat.packed(), dtype=np.float64)
        if np.all(p[1:] == 0.0):
            media[m, 0], media[m, 1] = MEDIUM_CONSTANT, math.sqrt(p[0])
        else:
            media[m, 0], media[m, 1:] = MEDIUM_FORMULA, p
    ir = lens.iris if iris is None else iris
    stop = lens.stop_index
    radius = lens.surfaces[stop].semi_diameter_mm if stop_radius_mm is None else stop_radius_mm
    iris_row = np.zeros(IRIS_COLS)
    iris_row[IRIS_STOP] = stop
    iris_row[IRIS_RADIUS] = -1.0 if radius is None else radius * (1.0 + APERTURE_TOLERANCE)
    iris_row[IRIS_BLADES] = ir.blades
    iris_row[IRIS_ROTATION] = ir.rotation_rad
    iris_row[IRIS_ROUNDNESS] = ir.roundness
    iris_row[IRIS_OBSTRUCTION] = 0.0 if radius is None else ir.obstruction_ratio * radius
    half = math.pi / ir.blades if ir.blades else 0.0
    iris_row[IRIS_COS_HALF] = math.cos(half)
    iris_row[IRIS_HALF] = half
    return surf, media, iris_row


def _pack_shape(s: Surface, row: np.ndarray) -> None:
    """A surface kind of :mod:`lensrt.prescription.shapes` into the extra columns from ``S_X``."""
    prof = profile_of(s)
    row[S_KIND] = SHAPE_KIND_CODES[prof.kind]
    row[S_X + X_RN] = prof.rn
    row[S_X + X_NT] = len(prof.terms)
    row[S_X + X_CX] = prof.cx
    row[S_X + X_KXP1] = 1.0 + prof.kx
    row[S_X + X_TERMS:S_X + X_TERMS + len(prof.terms)] = prof.terms


def pack_geometry(lens: Lens, surf: np.ndarray) -> None:
    """Fill the geometry columns of ``surf`` (and flip c and the asphere after odd mirrors) in place."""
    surf[:, S_SIGN] = 1.0
    surf[:, S_AXES:S_AXES + 9] = np.eye(3).ravel()
    if lens.is_centred and not lens.has_mirrors and not lens.has_ideal_lens and not lens.has_shapes \
            and lens.image_curvature_per_mm == 0.0:
        return  # shaped surfaces, ideal lenses and curved images are traced by the general kernel variant only
    from ..prescription.frames import surface_frames, travel_signs
    signs = travel_signs(lens)
    for i, (origin, axes) in enumerate(surface_frames(lens)):
        surf[i, S_GEOM] = 1.0
        surf[i, S_SIGN] = signs[i]
        surf[i, S_ORIGIN:S_ORIGIN + 3] = origin
        surf[i, S_AXES:S_AXES + 9] = axes.ravel()
        if i < lens.n_surfaces:
            surf[i, S_MIRROR] = 1.0 if lens.surfaces[i].mirror else 0.0
            surf[i, S_C] *= signs[i]
            surf[i, S_ASPH:S_ASPH + MAX_ASPHERE] *= signs[i]
            if surf.shape[1] > SURF_COLS:  # a shape's sag terms change sign with the frame (shapes.profile_of)
                surf[i, S_X + X_CX] *= signs[i]
                surf[i, S_X + X_TERMS:] *= signs[i]
            _pack_apertures(lens, i, surf)
        else:
            surf[i, S_C] *= signs[i]  # a curved image surface met in the frame mirrored in z


def _pack_apertures(lens: Lens, i: int, surf: np.ndarray) -> None:
    aps = lens.surfaces[i].apertures
    if len(aps) > MAX_SURFACE_APERTURES:
        raise LensrtError(f"surface {i + 1} has {len(aps)} surface apertures; the kernels take at most "
                          f"{MAX_SURFACE_APERTURES}", path=lens.path,
                          hint="use lensrt.trace.reference.trace_reference (float64, one ray at a time)")
    g = 1.0 + APERTURE_TOLERANCE
    for k, a in enumerate(aps):
        grow = 1.0 / g if a.obscuration else g  # the tolerance always favours passing
        b = a.b / grow if a.shape == "annulus" else a.b * grow
        surf[i, S_APER + k * APERTURE_COLS:S_APER + (k + 1) * APERTURE_COLS] = (
            APERTURE_SHAPE_CODES[a.shape], a.a * grow, b, a.decenter_x_mm, a.decenter_y_mm,
            math.cos(a.rotation_rad), math.sin(a.rotation_rad), 1.0 if a.obscuration else 0.0)


def index_table(lens: Lens, wavelength_nm: np.ndarray) -> np.ndarray:
    """Indices of every medium at each wavelength: (K, n_surfaces + 1), float64 reference values."""
    return np.atleast_2d(lens.indices(np.asarray(wavelength_nm, dtype=np.float64)))


def real_dtype(wp: Any, precision: str) -> Any:
    return wp.float64 if precision == "float64" else wp.float32


@dataclass(frozen=True)
class PackedLens:
    """Kernel arrays of one lens on one device in one precision."""

    lens: Lens
    precision: str
    device: str
    surf: Any
    media: Any
    iris: Any
    host_surf: np.ndarray
    host_media: np.ndarray
    host_iris: np.ndarray

    @property
    def n_surfaces(self) -> int:
        return self.lens.n_surfaces

    @property
    def general(self) -> bool:
        """Whether the kernels need the general variant (mirrors, frames, surface apertures or surface kinds of
        :mod:`lensrt.prescription.shapes`: ``S_GEOM`` set); a rotationally symmetric lens of conics and even
        aspheres runs the symmetric one, which leaves that code out."""
        return bool(self.host_surf[0, S_GEOM] != 0.0)

    @property
    def vertex_z_mm(self) -> np.ndarray:
        return self.lens.vertex_z_mm()


def pack_lens(lens: Lens, precision: str = "float64", device: str | None = None, iris: Iris | None = None,
              stop_radius_mm: float | None = None) -> PackedLens:
    """Pack ``lens`` for kernels on ``device`` (resolved; None = auto) in ``precision`` (cached)."""
    from ..device import check_precision, resolve_device, warp
    wp = warp()
    check_precision(precision)
    dev = resolve_device(device)
    key = (lens, precision, dev, iris, stop_radius_mm)
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    surf, media, iris_row = pack_arrays(lens, iris, stop_radius_mm)
    real = real_dtype(wp, precision)
    packed = PackedLens(lens, precision, dev,
                        upload(surf, real, dev), upload(media, real, dev),
                        upload(iris_row, real, dev), surf, media, iris_row)
    _CACHE[key] = packed
    if len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return packed
