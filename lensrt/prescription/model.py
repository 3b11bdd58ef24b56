"""The lens model: immutable, sequential, refractive or reflective.

Conventions (``CONVENTIONS.md``): lengths in mm, angles in radians, light
travels toward +z, the first surface's vertex is at z = 0, radius R > 0 when the
centre of curvature lies on the +z side; curvature c = 1/R is stored (a plane
is c = 0). ``Surface.thickness_mm`` runs from this vertex to the next one; the
last surface's thickness runs to the image surface. Each surface's material is
the medium *after* it.

Sag of a conic + even asphere (r in mm)::

    z(r) = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2)) + sum_i a_i r^(2i+2),   a = Surface.asphere

so ``asphere[0]`` is the r^2 term (Zemax EVENASPH PARM 1), ``asphere[1]`` the
r^4 term (Zemax PARM 2, CODE V ``A``), and so on. Other surface kinds (odd and
Q-type aspheres, biconic, toroidal) carry a :class:`~.shapes.SurfaceShape`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Iterable, Sequence

import numpy as np

from ..errors import PrescriptionError
from .focusing import UNIT_FOCUS, FocusMechanism
from .geometry import CoordinateTransform, SurfaceAperture
from .materials import AIR, Material
from .shapes import SurfaceShape, profile_of, sag_grad, vertex_expansion

__all__ = [
    "APERTURE_KINDS", "FIELD_KINDS", "APERTURE_RULES", "Aperture", "Iris", "Fields", "Wavelengths", "Surface", "Lens",
    "LoadWarning",
]

#: epd: entrance-pupil diameter (mm); image_fno: image-space f-number at infinite
#: conjugates (f / D); object_na: object-space numerical aperture; float_by_stop:
#: the stop's clear semi-diameter sets the beam (value unused).
APERTURE_KINDS = ("epd", "image_fno", "object_na", "float_by_stop")
#: angle: field angle in object space (rad); object_height: mm in the object plane;
#: paraxial_image_height / real_image_height: mm on the image surface.
FIELD_KINDS = ("angle", "object_height", "paraxial_image_height", "real_image_height")
#: which semi-diameters vignette. every_surface: every element's clear semi-diameter (given or
#: computed) clips, as pbrt's lens tables mean it (the photographic reading, lensrt's default);
#: opticstudio: OpticStudio's rule -- an automatic semi-diameter does not vignette, a user-defined
#: one (``Surface.semi_diameter_fixed``: ``DIAM v 1``, a floating aperture) does. Surface apertures
#: (``Surface.apertures``) and the stop clip under both rules.
APERTURE_RULES = ("every_surface", "opticstudio")


def _finite(value: float, what: str, surface: int | None = None) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PrescriptionError(f"{what} {value!r} is not a number", surface=surface) from None
    if not math.isfinite(v):
        raise PrescriptionError(f"{what} is {value!r}", surface=surface,
                                hint="give a finite number")
    return v


@dataclass(frozen=True)
class Aperture:
    """How the beam is sized: ``kind`` in :data:`APERTURE_KINDS` and its ``value``."""

    kind: str = "epd"
    value: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in APERTURE_KINDS:
            raise PrescriptionError(f"unknown aperture type {self.kind!r}",
                                    hint=f"use one of {', '.join(APERTURE_KINDS)}")
        v = _finite(self.value, f"aperture value ({self.kind})")
        if self.kind == "float_by_stop":
            return
        if v <= 0.0:
            raise PrescriptionError(f"aperture {self.kind} = {v:g} must be positive")
        if self.kind == "image_fno" and v < 0.5:
            raise PrescriptionError(f"f-number {v:g} is below 0.5, the limit for a lens in air",
                                    hint="check the FNO/FNUM value")
        if self.kind == "object_na" and v >= 1.0:
            raise PrescriptionError(f"object-space NA {v:g} must be below 1 in air")


@dataclass(frozen=True)
class Iris:
    """The aperture stop's shape.

    ``blades`` = 0 is a circle; N >= 3 a regular N-gon of straight blades
    inscribed in the stop circle, rotated by ``rotation_rad`` (a vertex at
    angle ``rotation_rad`` from +x). ``roundness`` in [0, 1] blends the straight
    blade toward the circle (0 = straight, 1 = circular). ``obstruction_ratio``
    is a central obstruction's radius as a fraction of the stop radius.
    """

    blades: int = 0
    rotation_rad: float = 0.0
    roundness: float = 0.0
    obstruction_ratio: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.blades, (int, np.integer)) or isinstance(self.blades, bool) \
                or self.blades < 0 or self.blades in (1, 2) or self.blades > 64:
            raise PrescriptionError(f"iris blade count {self.blades!r} is not 0 (circular) or 3..64")
        _finite(self.rotation_rad, "iris rotation")
        if not 0.0 <= _finite(self.roundness, "iris roundness") <= 1.0:
            raise PrescriptionError(f"iris roundness {self.roundness:g} must be within [0, 1]")
        if not 0.0 <= _finite(self.obstruction_ratio, "obstruction ratio") < 1.0:
            raise PrescriptionError(f"obstruction ratio {self.obstruction_ratio:g} must be within [0, 1)")


@dataclass(frozen=True)
class Fields:
    """Field points: ``kind`` in :data:`FIELD_KINDS`, x/y values (rad or mm) and weights."""

    kind: str = "angle"
    y: tuple[float, ...] = (0.0,)
    x: tuple[float, ...] = ()
    weights: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in FIELD_KINDS:
            raise PrescriptionError(f"unknown field type {self.kind!r}",
                                    hint=f"use one of {', '.join(FIELD_KINDS)}")
        y = tuple(_finite(v, "field value") for v in self.y)
        if not y:
            raise PrescriptionError("the lens has no field points")
        x = tuple(_finite(v, "field value") for v in self.x) if self.x else (0.0,) * len(y)
        w = tuple(_finite(v, "field weight") for v in self.weights) if self.weights else (1.0,) * len(y)
        if len(x) != len(y) or len(w) != len(y):
            raise PrescriptionError(f"{len(y)} field points but {len(x)} x values and {len(w)} weights")
        if any(v < 0 for v in w):
            raise PrescriptionError("field weights must not be negative")
        if self.kind == "angle" and any(math.hypot(a, b) >= math.pi / 2 * 1.2 for a, b in zip(x, y)):
            raise PrescriptionError("a field angle is beyond 108 degrees",
                                    hint="field angles are half-angles from the axis")
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "weights", w)

    @property
    def count(self) -> int:
        return len(self.y)

    @property
    def max_radial(self) -> float:
        """Largest radial field value (rad or mm): the normalisation of (Hx, Hy)."""
        return max(math.hypot(a, b) for a, b in zip(self.x, self.y))


@dataclass(frozen=True)
class Wavelengths:
    """Wavelengths (nm) with weights; ``primary`` is a 0-based index into ``nm``."""

    nm: tuple[float, ...] = (587.5618,)
    weights: tuple[float, ...] = ()
    primary: int = 0

    def __post_init__(self) -> None:
        nm = tuple(_finite(v, "wavelength") for v in self.nm)
        if not nm:
            raise PrescriptionError("the lens has no wavelengths")
        if any(not 200.0 <= v <= 20000.0 for v in nm):
            raise PrescriptionError(f"wavelengths {nm} nm are outside 200..20000 nm",
                                    hint="wavelengths are in nm (Zemax files use micrometres)")
        w = tuple(_finite(v, "wavelength weight") for v in self.weights) if self.weights else (1.0,) * len(nm)
        if len(w) != len(nm) or any(v < 0 for v in w):
            raise PrescriptionError("wavelength weights must be one non-negative number per wavelength")
        if not any(v > 0 for v in w):
            raise PrescriptionError("wavelength weights are all zero", hint="give at least one positive weight")
        if not 0 <= int(self.primary) < len(nm):
            raise PrescriptionError(f"primary wavelength index {self.primary} is not one of the {len(nm)} wavelengths")
        object.__setattr__(self, "nm", nm)
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "primary", int(self.primary))

    @property
    def primary_nm(self) -> float:
        return self.nm[self.primary]


@dataclass(frozen=True)
class Surface:
    """One refracting or reflecting surface and the gap after it (see the module docstring).

    Geometry beyond the rotationally symmetric lens (:mod:`.geometry`):
    ``mirror`` reflects instead of refracting (its ``material`` is the medium
    the reflected light travels in: the one before it; thicknesses after an
    odd number of mirrors are negative, as in Zemax and CODE V);
    ``transform_before`` moves the local frame before the surface is placed
    and ``transform_after`` after it, before the thickness is measured along
    the new z (None: identity); ``apertures`` are clear apertures and
    obscurations that always clip; ``semi_diameter_fixed`` marks a
    user-defined semi-diameter (OpticStudio's ``DIAM v 1``), the one kind that
    vignettes under the ``opticstudio`` aperture rule.

    ``ideal_focal_mm`` makes the surface an ideal paraxial lens (OpticStudio's
    ``TYPE PARAXIAL``, PARM 1): a plane of power Phi = 1 / f, perfect at every
    conjugate (:func:`lensrt.trace.ray_surface.ideal_lens`); ``ideal_opd_mode``
    is OpticStudio's PARM 2, kept for the record (the trace uses only the
    direction change; ``docs/guide/first-order.md`` says what the optical path
    lengths through it mean).
    """

    curvature_per_mm: float = 0.0
    thickness_mm: float = 0.0
    material: Material = AIR
    semi_diameter_mm: float | None = None
    conic: float = 0.0
    asphere: tuple[float, ...] = ()
    is_stop: bool = False
    label: str = ""
    #: True when the clear semi-diameter was computed (not given by the file)
    semi_diameter_auto: bool = False
    mirror: bool = False
    transform_before: CoordinateTransform | None = None
    transform_after: CoordinateTransform | None = None
    apertures: tuple[SurfaceAperture, ...] = ()
    semi_diameter_fixed: bool = False
    ideal_focal_mm: float | None = None
    ideal_opd_mode: int = 0
    #: a surface kind beyond the conic + even asphere (odd, Q-type, biconic, toroidal: :mod:`.shapes`); None:
    #: the conic + even asphere of the module docstring
    shape: SurfaceShape | None = None
    #: line of the source file this surface came from (not part of equality)
    line: int | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        self._check_geometry()
        object.__setattr__(self, "curvature_per_mm", _finite(self.curvature_per_mm, "curvature"))
        object.__setattr__(self, "thickness_mm", _finite(self.thickness_mm, "thickness"))
        object.__setattr__(self, "conic", _finite(self.conic, "conic constant"))
        asph = tuple(_finite(a, "aspheric coefficient") for a in self.asphere)
        while asph and asph[-1] == 0.0:
            asph = asph[:-1]
        object.__setattr__(self, "asphere", asph)
        self._check_shape()
        if not isinstance(self.material, Material):
            raise PrescriptionError(f"material {self.material!r} is not a Material")
        if self.semi_diameter_mm is not None:
            sd = _finite(self.semi_diameter_mm, "semi-diameter")
            if sd <= 0.0:
                raise PrescriptionError(f"semi-diameter {sd:g} mm must be positive")
            limit = self.max_semi_diameter_mm
            if sd > limit * (1.0 + 1e-9):
                raise PrescriptionError(
                    f"semi-diameter {sd:g} mm exceeds the surface's largest possible radius {limit:g} mm "
                    f"(|R| = {abs(self.radius_mm):g} mm, conic {self.conic:g})",
                    hint="a semi-diameter must not exceed |R| (the surface would not exist there)")
            object.__setattr__(self, "semi_diameter_mm", sd)

    def _check_ideal(self) -> None:
        if self.ideal_focal_mm is None:
            return
        f = _finite(self.ideal_focal_mm, "ideal lens focal length")
        if f == 0.0:
            raise PrescriptionError("an ideal paraxial lens with focal length 0", line=self.line,
                                    hint="give a non-zero focal length (PARM 1 of TYPE PARAXIAL)")
        if self.curvature_per_mm != 0.0 or self.conic != 0.0 or any(a != 0.0 for a in self.asphere) \
                or self.mirror or self.shape is not None:
            raise PrescriptionError("an ideal paraxial lens is a plane: it has no curvature, conic, asphere or "
                                    "mirror", line=self.line, hint="leave those out of a TYPE PARAXIAL surface")
        if self.ideal_opd_mode not in (0, 1, 2, 3):
            raise PrescriptionError(f"ideal lens OPD mode {self.ideal_opd_mode!r} is not 0, 1, 2 or 3", line=self.line)
        object.__setattr__(self, "ideal_focal_mm", f)
        object.__setattr__(self, "ideal_opd_mode", int(self.ideal_opd_mode))

    @property
    def is_ideal(self) -> bool:
        """An ideal paraxial lens (``ideal_focal_mm`` set)."""
        return self.ideal_focal_mm is not None

    def _check_shape(self) -> None:
        sh = self.shape
        if sh is None:
            return
        if not isinstance(sh, SurfaceShape):
            raise PrescriptionError(f"surface shape {sh!r} is not a SurfaceShape", line=self.line)
        if self.asphere and sh.kind not in ("toroidal", "xy", "zernike", "zernike_fringe"):
            raise PrescriptionError(f"even asphere terms on a {sh.kind} surface", line=self.line,
                                    hint="give every polynomial term in the shape's coefficients")

    def _check_geometry(self) -> None:
        self._check_ideal()
        object.__setattr__(self, "mirror", bool(self.mirror))
        object.__setattr__(self, "semi_diameter_fixed", bool(self.semi_diameter_fixed))
        for name in ("transform_before", "transform_after"):
            t = getattr(self, name)
            if t is not None and not isinstance(t, CoordinateTransform):
                raise PrescriptionError(f"{name} {t!r} is not a CoordinateTransform")
            if t is not None and t.is_identity:
                object.__setattr__(self, name, None)  # identity is stored as None: equal lenses compare equal
        aps = tuple(self.apertures)
        if any(not isinstance(a, SurfaceAperture) for a in aps):
            raise PrescriptionError("surface apertures must be SurfaceAperture values")
        object.__setattr__(self, "apertures", aps)

    @property
    def is_centred(self) -> bool:
        """No transform and no aperture beyond the circular semi-diameter (mirrors allowed)."""
        return self.transform_before is None and self.transform_after is None and not self.apertures

    @property
    def is_rotational(self) -> bool:
        """The sag depends on r only (False for biconic and toroidal surfaces)."""
        return self.shape is None or self.shape.rotational

    @property
    def paraxial_curvature_per_mm(self) -> float:
        """Curvature of the osculating sphere at the vertex (the y-section's for biconic and toroidal
        surfaces): c plus twice the r^2 coefficient of every term (:func:`.shapes.vertex_expansion`)."""
        if self.shape is None:
            return self.curvature_per_mm + (2.0 * self.asphere[0] if self.asphere else 0.0)
        return 2.0 * vertex_expansion(profile_of(self))[0]

    @property
    def radius_mm(self) -> float:
        """Radius of curvature (``inf`` for a plane)."""
        return math.inf if self.curvature_per_mm == 0.0 else 1.0 / self.curvature_per_mm

    @property
    def is_plane(self) -> bool:
        return self.curvature_per_mm == 0.0 and not self.asphere and self.shape is None

    @property
    def max_semi_diameter_mm(self) -> float:
        """Largest r where the conic sag is defined: 1 / (|c| sqrt(1 + k)) when (1 + k) c^2 > 0."""
        q = (1.0 + self.conic) * self.curvature_per_mm ** 2
        limit = math.inf if q <= 0.0 else 1.0 / math.sqrt(q)
        if self.shape is not None and self.shape.kind == "biconic":
            qx = (1.0 + self.shape.conic_x) * self.shape.curvature_x_per_mm ** 2
            limit = min(limit, math.inf if qx <= 0.0 else 1.0 / math.sqrt(qx))
        return limit

    def sag(self, r_mm: float | np.ndarray) -> np.ndarray | float:
        """Surface sag z(r) in mm (float64, vectorised), in the cancellation-free form.

        A surface with a :attr:`shape` gives its sag along +y (x = 0): the y-section of biconic and
        toroidal surfaces; NaN where the surface does not exist.
        """
        if self.shape is not None:
            prof = profile_of(self)
            r = np.asarray(r_mm, dtype=np.float64)
            out = np.array([(lambda v: math.nan if v is None else v[0])(sag_grad(prof, 0.0, float(v)))
                            for v in r.ravel()]).reshape(r.shape)
            return float(out) if np.ndim(out) == 0 else out
        r2 = np.asarray(r_mm, dtype=np.float64) ** 2
        c, k = self.curvature_per_mm, self.conic
        z = c * r2 / (1.0 + np.sqrt(np.maximum(1.0 - (1.0 + k) * c * c * r2, 0.0)))
        power = r2
        for a in self.asphere:
            z = z + a * power
            power = power * r2
        return float(z) if np.ndim(z) == 0 else z


@dataclass(frozen=True)
class LoadWarning:
    """An approximation a reader made, for programs to check (``lensrt info --json``'s ``warnings``).

    ``code`` is one of ``glass_other_catalog``, ``glass_alias``, ``glass_substituted``,
    ``glass_model``, ``glass_line_disagrees``, ``glass_private``, ``keyword_ignored``,
    ``keyword_unknown``, ``assumed_default``, ``first_order_y_section`` (a surface that is not rotationally
    symmetric: paraxial data are its y-section's), ``dummy_crossing``, ``glass_uncertain_name``,
    ``surface_numbering``, ...; ``surface`` the 0-based lens surface
    (``None`` for system data); ``line`` the file line.
    """

    code: str
    text: str
    surface: int | None = None
    line: int | None = None

    def to_dict(self) -> dict[str, object]:
        return {"code": self.code, "surface": self.surface, "line": self.line, "text": self.text}


@dataclass(frozen=True)
class Lens:
    """A complete prescription: surfaces plus the system data (aperture, fields, ...)."""

    surfaces: tuple[Surface, ...]
    aperture: Aperture = Aperture("float_by_stop", 0.0)
    fields: Fields = Fields()
    wavelengths: Wavelengths = Wavelengths()
    object_distance_mm: float = math.inf
    object_material: Material = AIR
    iris: Iris = Iris()
    name: str = ""
    source: str = ""
    #: free-form metadata as (key, value) pairs, e.g. ("clear_apertures", "paraxial")
    notes: tuple[tuple[str, str], ...] = ()
    #: which semi-diameters vignette (:data:`APERTURE_RULES`)
    aperture_rule: str = "every_surface"
    #: the image surface's change of frame after the last thickness (CODE V's SI decenter); None: identity
    image_transform: CoordinateTransform | None = None
    #: approximations the reader made (glass substitutions, ignored keywords, assumed defaults)
    warnings: tuple[LoadWarning, ...] = field(default=(), compare=False)
    #: file the lens was read from (not part of equality)
    path: str | None = field(default=None, compare=False)
    #: how the lens focuses (:mod:`lensrt.prescription.focusing`); unit focusing by default
    focus: FocusMechanism = UNIT_FOCUS
    #: curvature (1/mm) of a spherical image surface (a curved sensor, the retina; Zemax image CURV, CODE V SI);
    #: 0: the usual plane. Real rays end on it; paraxial (y-nu) data do not depend on it
    image_curvature_per_mm: float = 0.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.image_curvature_per_mm):
            raise PrescriptionError(f"image surface curvature {self.image_curvature_per_mm!r} is not finite",
                                    hint="give the image radius in mm, or 0 / inf for a plane")
        if self.image_transform is not None and self.image_transform.is_identity:
            object.__setattr__(self, "image_transform", None)
        if self.aperture_rule not in APERTURE_RULES:
            raise PrescriptionError(f"unknown aperture rule {self.aperture_rule!r}",
                                    hint=f"use one of {', '.join(APERTURE_RULES)}")
        surfaces = tuple(self.surfaces)
        object.__setattr__(self, "surfaces", surfaces)
        if not surfaces:
            raise PrescriptionError("the lens has no surfaces")
        stops = [i for i, s in enumerate(surfaces) if s.is_stop]
        if not stops:
            raise PrescriptionError("the lens has no aperture stop",
                                    hint="flag one surface as the stop (STO / STOP / stop = true)")
        if len(stops) > 1:
            raise PrescriptionError(f"the lens has {len(stops)} aperture stops (surfaces "
                                    f"{', '.join(str(i + 1) for i in stops)})",
                                    surface=stops[1], hint="flag exactly one surface as the stop")
        d = float(self.object_distance_mm)
        if math.isnan(d) or d <= 0.0:
            raise PrescriptionError(f"object distance {self.object_distance_mm!r} mm must be positive "
                                    "(use inf for an object at infinity)")
        object.__setattr__(self, "object_distance_mm", d)
        if math.isinf(d) and self.fields.kind == "object_height":
            raise PrescriptionError("fields are object heights but the object is at infinity",
                                    hint="use field angles, or give a finite object distance")
        if math.isinf(d) and self.aperture.kind == "object_na":
            raise PrescriptionError("aperture is an object-space NA but the object is at infinity",
                                    hint="use an entrance-pupil diameter or an f-number")
        if self.aperture.kind == "float_by_stop" and surfaces[stops[0]].semi_diameter_mm is None:
            raise PrescriptionError("the aperture floats by stop size but the stop has no semi-diameter",
                                    surface=stops[0], hint="give the stop's semi-diameter")
        object.__setattr__(self, "notes", tuple((str(k), str(v)) for k, v in self.notes))
        self.focus.check_against(len(surfaces))
        self._check_mirrors(surfaces)

    def _check_mirrors(self, surfaces: tuple[Surface, ...]) -> None:
        before = self.object_material
        mirrors = 0
        for i, s in enumerate(surfaces):
            if s.is_ideal and mirrors % 2:
                raise PrescriptionError(f"surface {i + 1} is an ideal paraxial lens after an odd number of mirrors",
                                        surface=i, line=s.line,
                                        hint="lensrt models ideal lenses in light travelling toward +z only")
            mirrors += bool(s.mirror)
            if s.mirror and s.material != before:
                raise PrescriptionError(
                    f"mirror surface {i + 1} has material {s.material.describe()} but the light before it "
                    f"travels in {before.describe()}", surface=i, line=s.line,
                    hint="a mirror's material is the medium the reflected light travels in: the one before it")
            before = s.material

    # ---- geometry kind ---------------------------------------------------
    @property
    def has_mirrors(self) -> bool:
        return any(s.mirror for s in self.surfaces)

    @property
    def has_ideal_lens(self) -> bool:
        """At least one surface is an ideal paraxial lens (``Surface.ideal_focal_mm``)."""
        return any(s.is_ideal for s in self.surfaces)

    @property
    def is_centred(self) -> bool:
        """Rotationally symmetric about one axis: no transforms, only circular apertures (mirrors allowed)."""
        return self.image_transform is None and all(s.is_centred for s in self.surfaces)

    @property
    def is_rotational(self) -> bool:
        """Centred and every surface's sag a function of r only (no biconic or toroidal surface)."""
        return self.is_centred and all(s.is_rotational for s in self.surfaces)

    @property
    def has_shapes(self) -> bool:
        """A surface kind beyond the conic + even asphere (only the generic trace kernel traces those)."""
        return any(s.shape is not None for s in self.surfaces)

    @property
    def is_plain(self) -> bool:
        """The classic lens of the Warp kernels: centred, refractive, every semi-diameter clipping."""
        return self.is_centred and not self.has_mirrors and self.aperture_rule == "every_surface"

    def clips_semi_diameter(self, index: int) -> bool:
        """True when surface ``index``'s circular semi-diameter vignettes under :attr:`aperture_rule`."""
        s = self.surfaces[index]
        if s.semi_diameter_mm is None:
            return False
        if self.aperture_rule == "every_surface" or index == self.stop_index:
            return True
        return s.semi_diameter_fixed

    # ---- structure -------------------------------------------------------
    @property
    def n_surfaces(self) -> int:
        return len(self.surfaces)

    @property
    def stop_index(self) -> int:
        """0-based index of the aperture stop surface."""
        return next(i for i, s in enumerate(self.surfaces) if s.is_stop)

    @property
    def meta(self) -> dict[str, str]:
        return dict(self.notes)

    def with_note(self, key: str, value: str) -> "Lens":
        """A copy with metadata ``key`` set to ``value``."""
        notes = tuple((k, v) for k, v in self.notes if k != key) + ((key, value),)
        return replace(self, notes=notes)

    def replace(self, **changes: object) -> "Lens":
        """A copy with fields changed (``dataclasses.replace``); keeps ``path``."""
        new = replace(self, **changes)
        object.__setattr__(new, "path", self.path)
        return new

    def replace_surface(self, index: int, **changes: object) -> "Lens":
        surfaces = list(self.surfaces)
        surfaces[index] = replace(surfaces[index], **changes)
        return self.replace(surfaces=tuple(surfaces))

    # ---- geometry --------------------------------------------------------
    def vertex_z_mm(self) -> np.ndarray:
        """z of every surface vertex (first = 0) followed by the image surface's z."""
        t = np.array([s.thickness_mm for s in self.surfaces], dtype=np.float64)
        return np.concatenate([[0.0], np.cumsum(t)])

    @property
    def image_z_mm(self) -> float:
        """z of the image surface: the last vertex plus the last thickness."""
        return float(sum(s.thickness_mm for s in self.surfaces))

    @property
    def length_mm(self) -> float:
        """First to last vertex (CODE V's overall length, OAL)."""
        return float(sum(s.thickness_mm for s in self.surfaces[:-1]))

    # ---- media -----------------------------------------------------------
    def media(self) -> tuple[Material, ...]:
        """Object medium then the medium after each surface (n_surfaces + 1 entries)."""
        return (self.object_material,) + tuple(s.material for s in self.surfaces)

    def indices(self, wavelength_nm: float | Sequence[float] | np.ndarray) -> np.ndarray:
        """Refractive indices of :meth:`media` at ``wavelength_nm``; shape (..., n_surfaces + 1)."""
        w = np.asarray(wavelength_nm, dtype=np.float64)
        cols = [np.broadcast_to(np.asarray(m.index(w), dtype=np.float64), w.shape) for m in self.media()]
        return np.stack(cols, axis=-1)

    def check_wavelengths(self, wavelength_nm: float | Sequence[float] | np.ndarray) -> list[str]:
        """Warn where a glass's dispersion formula would be extrapolated at ``wavelength_nm``.

        Each catalog glass carries the wavelength range its vendor measured; outside it
        the formula is extrapolated (and can be far off, or not real: a power series
        goes negative in the infrared). Issues one
        :class:`~lensrt.prescription.materials.ExtrapolationWarning` per such glass and
        returns the messages (empty when every wavelength is covered).
        """
        from .materials import check_wavelength_range
        waves = np.unique(np.ravel(np.asarray(wavelength_nm, dtype=np.float64)))
        return check_wavelength_range(self.media(), waves)

    def glass_materials(self) -> list[Material]:
        return [m for m in self.media() if not m.is_air]

    def summary(self) -> str:
        return f"{self.name or 'lens'}: {self.n_surfaces} surfaces, stop at surface {self.stop_index + 1}"


def surfaces_from_rows(rows: Iterable[dict]) -> tuple[Surface, ...]:
    """Build surfaces from dicts of :class:`Surface` fields (convenience for tests)."""
    return tuple(Surface(**row) for row in rows)
