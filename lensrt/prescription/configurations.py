"""Lenses with several configurations: zoom positions, focus positions, or both.

A :class:`MultiConfigLens` is a base :class:`~lensrt.prescription.model.Lens`
(everything shared) plus a list of :class:`ConfigOperand` -- one value per
configuration of one quantity, the way Zemax's multi-configuration editor and
CODE V's ``ZOO`` data store them. :meth:`MultiConfigLens.configuration` applies
the operands of one configuration to the base and returns a plain ``Lens``, so
every analysis works on it unchanged.

Operand kinds (:data:`OPERAND_KINDS`; ``index`` is 0-based):

==================  ==========================================  ==================================================
kind                index                                       value
==================  ==========================================  ==================================================
thickness           surface (its thickness to the next one)     mm
object_distance     (unused, -1)                                mm (``inf`` allowed)
curvature           surface                                     1/mm
conic               surface                                     conic constant
material            surface (the medium after it)               ``Material``
semi_diameter       surface                                     mm
decenter_x, _y      surface (a basic decenter before it)        mm
stop_surface        (unused, -1)                                0-based surface index
aperture            (unused, -1)                                the lens aperture kind's value (mm, f-number, NA)
field_y, field_x    field point                                 rad or mm (the lens's field kind)
field_weight        field point                                 weight
wavelength          wavelength                                  nm
wavelength_weight   wavelength                                  weight
primary_wavelength  (unused, -1)                                0-based wavelength index
==================  ==========================================  ==================================================
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

from ..errors import PrescriptionError
from .geometry import CoordinateTransform
from .materials import Material
from .model import Aperture, Fields, Lens, Wavelengths

__all__ = ["OPERAND_KINDS", "SURFACE_KINDS", "ConfigOperand", "MultiConfigLens", "single_configuration",
           "check_surface_count"]

#: kinds whose index is a surface
SURFACE_KINDS = ("thickness", "curvature", "conic", "material", "semi_diameter", "decenter_x", "decenter_y")
OPERAND_KINDS = SURFACE_KINDS + ("object_distance", "stop_surface", "aperture", "field_y", "field_x",
                                 "field_weight", "wavelength", "wavelength_weight", "primary_wavelength")
_SYSTEM_KINDS = ("object_distance", "stop_surface", "aperture", "primary_wavelength")


@dataclass(frozen=True)
class ConfigOperand:
    """One quantity's value in every configuration (module docstring).

    ``source`` names the operand as the file wrote it (``THIC 5``, ``ZOO THI S5``)
    and ``line`` its line, for error messages.
    """

    kind: str
    index: int
    values: tuple[Any, ...]
    source: str = field(default="", compare=False)
    line: int | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.kind not in OPERAND_KINDS:
            raise PrescriptionError(f"unknown configuration operand kind {self.kind!r}",
                                    hint=f"use one of {', '.join(OPERAND_KINDS)}")
        object.__setattr__(self, "values", tuple(self.values))
        if self.kind != "material":
            for v in self.values:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(float(v)):
                    raise PrescriptionError(f"{self.label}: value {v!r} is not a number", line=self.line)

    @property
    def label(self) -> str:
        """The operand as the file wrote it, or kind and 1-based index."""
        if self.source:
            return self.source
        return self.kind if self.kind in _SYSTEM_KINDS else f"{self.kind} {self.index + 1}"


def _set_surface(surfaces: list, op: ConfigOperand, value: Any) -> None:
    if not 0 <= op.index < len(surfaces):
        raise PrescriptionError(f"configuration operand {op.label} names surface {op.index + 1}, but the lens has "
                                f"surfaces 1..{len(surfaces)}", line=op.line,
                                hint="surface numbers count from the first lens surface (the object is 0)")
    s = surfaces[op.index]
    if op.kind in ("decenter_x", "decenter_y"):
        _set_decenter(surfaces, op, float(value))
        return
    attr = {"thickness": "thickness_mm", "curvature": "curvature_per_mm", "conic": "conic",
             "material": "material", "semi_diameter": "semi_diameter_mm"}[op.kind]
    if op.kind == "material" and not isinstance(value, Material):
        raise PrescriptionError(f"{op.label}: {value!r} is not a material", line=op.line)
    changes: dict[str, Any] = {attr: value if op.kind == "material" else float(value)}
    if op.kind == "semi_diameter":
        changes["semi_diameter_auto"] = False
    surfaces[op.index] = replace(s, **changes)


def _set_decenter(surfaces: list, op: ConfigOperand, value_mm: float) -> None:
    """A basic decenter (the frame moves before the surface and stays moved) set to ``value_mm`` along x or y."""
    s = surfaces[op.index]
    if s.transform_after is not None:
        raise PrescriptionError(f"{op.label}: surface {op.index + 1} returns its frame after it; only a basic "
                                "decenter (the new frame holds for the later surfaces) can be zoomed", line=op.line)
    t = s.transform_before or CoordinateTransform()
    surfaces[op.index] = replace(s, transform_before=replace(t, **{f"{op.kind}_mm": value_mm}))


def _indexed(values: tuple, op: ConfigOperand, value: float, what: str) -> tuple:
    if not 0 <= op.index < len(values):
        raise PrescriptionError(f"configuration operand {op.label} names {what} {op.index + 1}, but the lens has "
                                f"{len(values)}", line=op.line)
    out = list(values)
    out[op.index] = float(value)
    return tuple(out)


def _apply_system(lens: Lens, changes: dict[str, Any], op: ConfigOperand, value: Any) -> None:
    """Collect the system-data change of one operand into ``changes`` (keyword arguments of Lens.replace)."""
    fields = changes.get("fields", lens.fields)
    waves = changes.get("wavelengths", lens.wavelengths)
    if op.kind == "object_distance":
        changes["object_distance_mm"] = float(value)
    elif op.kind == "aperture":
        changes["aperture"] = Aperture(lens.aperture.kind, float(value))
    elif op.kind in ("field_y", "field_x", "field_weight"):
        attr = {"field_y": "y", "field_x": "x", "field_weight": "weights"}[op.kind]
        vals = _indexed(getattr(fields, attr), op, value, "field")
        changes["fields"] = Fields(fields.kind, **{**dict(y=fields.y, x=fields.x, weights=fields.weights),
                                                   attr: vals})
    elif op.kind in ("wavelength", "wavelength_weight"):
        attr = "nm" if op.kind == "wavelength" else "weights"
        vals = _indexed(getattr(waves, attr), op, value, "wavelength")
        changes["wavelengths"] = Wavelengths(**{**dict(nm=waves.nm, weights=waves.weights,
                                                       primary=waves.primary), attr: vals})
    elif op.kind == "primary_wavelength":
        changes["wavelengths"] = Wavelengths(waves.nm, waves.weights, int(value))


@dataclass(frozen=True)
class MultiConfigLens:
    """A lens with named configurations (module docstring).

    Attributes
    ----------
    base : Lens
        Everything the configurations share; the operands overwrite the rest.
    names : tuple of str
        One name per configuration (``"1"``, ``"2"`` ... when the file gives none).
    operands : tuple of ConfigOperand
        Each with one value per configuration.
    current : int
        0-based index of the configuration a plain load gives (the file's current one).
    """

    base: Lens
    names: tuple[str, ...]
    operands: tuple[ConfigOperand, ...] = ()
    current: int = 0

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "operands", tuple(self.operands))
        if not names:
            raise PrescriptionError("a multi-configuration lens needs at least one configuration", path=self.base.path)
        if len(set(names)) != len(names):
            dup = next(n for n in names if names.count(n) > 1)
            raise PrescriptionError(f"two configurations are named {dup!r}", path=self.base.path,
                                    hint="give every configuration its own name")
        for op in self.operands:
            if len(op.values) != len(names):
                raise PrescriptionError(f"configuration operand {op.label} gives {len(op.values)} values for "
                                        f"{len(names)} configurations", path=self.base.path, line=op.line)
        if not 0 <= self.current < len(names):
            raise PrescriptionError(f"current configuration {self.current + 1} is not one of the {len(names)}",
                                    path=self.base.path)
        check_surface_count(self.base.n_surfaces, self.operands, self.base.path)

    def validate(self) -> "MultiConfigLens":
        """Build every configuration once (raises the first configuration's error); returns self."""
        self.configurations()
        return self

    @property
    def count(self) -> int:
        return len(self.names)

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def path(self) -> str | None:
        return self.base.path

    def index_of(self, key: int | str) -> int:
        """0-based index of configuration ``key``: a name, or a 1-based number (int or digits)."""
        if isinstance(key, str) and key in self.names:
            return self.names.index(key)
        try:
            number = int(key)
        except (TypeError, ValueError):
            raise PrescriptionError(f"no configuration named {key!r}", path=self.path,
                                    hint=f"configurations: {', '.join(self.names)} (or 1..{self.count})") from None
        if not 1 <= number <= self.count:
            raise PrescriptionError(f"configuration {number} does not exist: the lens has {self.count}",
                                    path=self.path, hint=f"use 1..{self.count} or a name: {', '.join(self.names)}")
        return number - 1

    def configuration(self, key: int | str | None = None) -> Lens:
        """Configuration ``key`` (name or 1-based number; default the current one) as a plain :class:`Lens`."""
        i = self.current if key is None else self.index_of(key)
        try:
            return self._build(i)
        except PrescriptionError as err:
            if self.count > 1 and not err.message.startswith("configuration"):
                err.message = f"configuration {self.names[i]!r}: {err.message}"
                err.args = (err.message,)
            if err.path is None:
                err.path = self.path
            raise

    def _build(self, i: int) -> Lens:
        lens = self.base
        surfaces = list(lens.surfaces)
        changes: dict[str, Any] = {}
        stop: int | None = None
        for op in self.operands:
            value = op.values[i]
            if op.kind in SURFACE_KINDS:
                _set_surface(surfaces, op, value)
            elif op.kind == "stop_surface":
                stop = int(value)
            else:
                _apply_system(lens, changes, op, value)
        if stop is not None:
            if not 0 <= stop < len(surfaces):
                raise PrescriptionError(f"the stop surface {stop + 1} is not one of the lens's surfaces "
                                        f"1..{len(surfaces)}")
            surfaces = [replace(s, is_stop=(k == stop)) for k, s in enumerate(surfaces)]
        notes = tuple((k, v) for k, v in lens.notes if k != "configuration") + (
            ("configuration", f"{i + 1} of {self.count}: {self.names[i]}"),)
        return lens.replace(surfaces=tuple(surfaces), notes=notes, **changes)

    def configurations(self) -> list[Lens]:
        """Every configuration as a plain :class:`Lens`, in order."""
        return [self.configuration(k + 1) for k in range(self.count)]

    def varying(self) -> list[ConfigOperand]:
        """The operands whose value is not the same in every configuration."""
        return [op for op in self.operands if len(set(map(repr, op.values))) > 1]

    def with_base(self, base: Lens) -> "MultiConfigLens":
        return replace(self, base=base)


def single_configuration(lens: Lens) -> MultiConfigLens:
    """A plain lens as a one-configuration :class:`MultiConfigLens`."""
    return MultiConfigLens(lens, (lens.meta.get("configuration_name", "1"),))


def check_surface_count(n_surfaces: int, operands: Sequence[ConfigOperand], path: str | None = None) -> None:
    """Raise for the first surface operand whose surface is not one of ``n_surfaces``."""
    for op in operands:
        if op.kind in SURFACE_KINDS and not 0 <= op.index < n_surfaces:
            raise PrescriptionError(f"configuration operand {op.label} names surface {op.index + 1}, but the lens "
                                    f"has surfaces 1..{n_surfaces}", path=path, line=op.line,
                                    hint="every configuration has the same surfaces; number them from 1")
