"""The scene model: immutable records that :func:`lensrt.render.scene.load.load_scene` fills in.

Frame and units (docs/reference/scene-format.md): lengths in mm (converted from the scene
file's unit at load), the lens's optical axis is z, light travels toward +z,
the scene's origin is the vertex of the lens's first surface (in its focused
position), the scene lies at z < 0, +y is up and +x is to the right as the
photographer sees the scene (right-handed). Spectra are arrays on the scene's
wavelength grid in the units their ``unit`` names.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...colour import Illuminant, WavelengthGrid
from .textures import Texture

__all__ = ["Spectrum", "CameraSpec", "SensorSpec", "SpectralSettings", "RenderSettings", "PointLight",
           "SphereLight", "Plane", "MeshObject", "Scene"]


@dataclass(frozen=True, eq=False)
class Spectrum:
    """A spectrum on the scene grid.

    Attributes
    ----------
    values : ndarray (n,)
        Samples on the scene's grid, in ``unit``.
    unit : str
        ``"W/(m^2 sr nm)"`` (radiance), ``"W/(sr nm)"`` (intensity),
        ``"W/(m^2 nm)"`` (irradiance) or ``"1"`` (reflectance). A line
        spectrum drops the ``nm``: its value is the whole line's radiance,
        held constant over the grid.
    label : str
        What it is, for people ("D65 at 1000 cd/m^2").
    line_nm : float or None
        Wavelength of a monochromatic line; ``None`` for continuous spectra.
    illuminant : Illuminant or None
        The spectrum's shape as the scene file named it (CIE table, Planck, daylight, line, table):
        what later stages take (the ISP white-balances for it), never parsed back from ``label``.
    """

    values: np.ndarray = field(repr=False)
    unit: str
    label: str
    line_nm: float | None = None
    illuminant: Illuminant | None = field(default=None, repr=False)

    def at(self, grid: WavelengthGrid, wavelength_nm: float | np.ndarray) -> np.ndarray:
        """Value at ``wavelength_nm`` (linear between grid points; a line's value everywhere)."""
        if self.line_nm is not None:
            return np.full(np.shape(wavelength_nm), float(self.values[0]))
        return grid.interp(self.values, wavelength_nm)


@dataclass(frozen=True)
class CameraSpec:
    """The camera: lens, focus, aperture and exposure.

    ``focus_distance_mm`` runs from the first lens vertex (the scene origin)
    to the plane of focus (``inf`` = infinity); ``focus_extension_mm`` is the
    alternative: unit focusing, the whole lens moved this far from its
    infinity position (Field Guide p. 12). Exactly one is set.
    ``f_number`` = ``None`` keeps the lens's own aperture.
    ``lens_tilt_rad``, ``lens_swing_rad``, ``lens_shift_mm``: a tilt-shift camera -- the whole
    lens tilted about the sensor's x axis through its stop (> 0 turns its axis toward +y), swung
    about its own y axis (> 0 toward +x) and shifted by (x, y) mm in front of the fixed sensor
    (:mod:`lensrt.prescription.tilt_shift`; file keys ``lens_tilt_deg``, ``lens_swing_deg``,
    ``lens_shift_mm``). All zero: the plain camera.
    """

    lens: str
    lens_path: Path | None
    focus_distance_mm: float | None
    focus_extension_mm: float | None
    f_number: float | None
    exposure_s: float
    lens_tilt_rad: float = 0.0
    lens_swing_rad: float = 0.0
    lens_shift_mm: tuple[float, float] = (0.0, 0.0)

    @property
    def is_tilt_shift(self) -> bool:
        """Whether the lens is tilted, swung or shifted relative to the sensor."""
        return bool(self.lens_tilt_rad or self.lens_swing_rad or any(self.lens_shift_mm))

    @property
    def lens_source(self) -> str | Path:
        """What :func:`lensrt.loading.load_lens` takes: the file path, or the library name."""
        return self.lens_path if self.lens_path is not None else self.lens


@dataclass(frozen=True)
class SensorSpec:
    """Sensor geometry (active area, photosites) and the sensor-stage options."""

    format_name: str
    width_mm: float
    height_mm: float
    pixels_x: int
    pixels_y: int
    preset: str | None = None
    noise: bool = False
    iso: float | None = None

    @property
    def pixel_pitch_um(self) -> float:
        return 1000.0 * self.width_mm / self.pixels_x

    @property
    def diagonal_mm(self) -> float:
        return math.hypot(self.width_mm, self.height_mm)


@dataclass(frozen=True)
class SpectralSettings:
    """``mode``: auto | spectral | monochromatic; ``sampling``: auto | uniform | cie | scene | camera."""

    mode: str = "auto"
    grid: WavelengthGrid = WavelengthGrid()
    wavelength_nm: float | None = None
    sampling: str = "auto"


@dataclass(frozen=True)
class RenderSettings:
    """Monte Carlo settings; ``diffraction``: auto | on | off."""

    samples_per_pixel: int = 16
    seed: int = 0
    time_budget_s: float | None = None
    target_rel_error: float | None = None
    diffraction: str = "auto"


@dataclass(frozen=True, eq=False)
class PointLight:
    """An isotropic point source at ``position_mm`` with spectral radiant ``intensity`` (W/(sr nm))."""

    name: str
    position_mm: np.ndarray
    intensity: Spectrum


@dataclass(frozen=True, eq=False)
class SphereLight:
    """A uniformly bright (Lambertian) sphere of ``radius_mm`` with spectral ``radiance`` (W/(m^2 sr nm))."""

    name: str
    center_mm: np.ndarray
    radius_mm: float
    radiance: Spectrum


@dataclass(frozen=True, eq=False)
class Plane:
    """A rectangle: centre, size (width along ``right``, height along ``up``), unit axes.

    ``normal`` points to the front (the side that emits, and from which the
    texture reads unmirrored); ``right = up x normal``. A reflective plane
    (``emission is None``) is Lambertian on both sides with reflectance
    texture(s, t, lambda) * tint(lambda); an emissive one has radiance
    texture(s, t, lambda) * emission(lambda) on its front side only.
    """

    name: str
    center_mm: np.ndarray
    size_mm: tuple[float, float]
    normal: np.ndarray
    right: np.ndarray
    up: np.ndarray
    texture: Texture
    tint: Spectrum | None
    emission: Spectrum | None

    @property
    def emissive(self) -> bool:
        return self.emission is not None

    def corners_mm(self) -> np.ndarray:
        hw, hh = 0.5 * self.size_mm[0], 0.5 * self.size_mm[1]
        return np.array([self.center_mm + a * hw * self.right + b * hh * self.up
                         for a in (-1, 1) for b in (-1, 1)])


@dataclass(frozen=True, eq=False)
class MeshObject:
    """A triangle mesh placed in the scene (vertices in mm), Lambertian or emissive (both sides)."""

    name: str
    source: str
    vertices_mm: np.ndarray
    faces: np.ndarray
    reflectance: Spectrum | None
    emission: Spectrum | None

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])


@dataclass(frozen=True, eq=False)
class Scene:
    """A loaded scene; every length in mm, every spectrum on ``spectral.grid``."""

    name: str
    description: str
    path: Path | None
    units: str
    camera: CameraSpec
    sensor: SensorSpec
    spectral: SpectralSettings
    render: RenderSettings
    point_lights: tuple[PointLight, ...] = ()
    sphere_lights: tuple[SphereLight, ...] = ()
    planes: tuple[Plane, ...] = ()
    meshes: tuple[MeshObject, ...] = ()
    illumination: Spectrum | None = None
    background: Spectrum | None = None
    warnings: tuple[str, ...] = ()

    @property
    def grid(self) -> WavelengthGrid:
        return self.spectral.grid

    @property
    def n_triangles(self) -> int:
        return sum(m.n_triangles for m in self.meshes)

    @property
    def emissive_planes(self) -> tuple[Plane, ...]:
        return tuple(p for p in self.planes if p.emissive)

    def emission_spectra(self) -> list[Spectrum]:
        """Every emitting spectrum: lights, emissive planes and meshes, illumination, background."""
        out: list[Spectrum] = [p.intensity for p in self.point_lights]
        out += [s.radiance for s in self.sphere_lights]
        out += [p.emission for p in self.planes if p.emission is not None]
        out += [m.emission for m in self.meshes if m.emission is not None]
        out += [s for s in (self.illumination, self.background) if s is not None]
        return out

    @property
    def line_nm(self) -> float | None:
        """The wavelength of the scene's light when all of it is one monochromatic line, else ``None``."""
        lines = {s.line_nm for s in self.emission_spectra()}
        return lines.pop() if len(lines) == 1 and None not in lines else None

    def summary(self) -> str:
        """A few lines saying what is in the scene."""
        c, s = self.camera, self.sensor
        focus = (f"extension {c.focus_extension_mm:g} mm" if c.focus_extension_mm is not None else
                 "infinity" if c.focus_distance_mm is None or math.isinf(c.focus_distance_mm)
                 else f"{c.focus_distance_mm / 1000.0:g} m from the first vertex")
        lines = [f"scene {self.name!r}" + (f": {self.description}" if self.description else ""),
                 f"  camera: lens {c.lens}, focus {focus}, "
                 + (f"f/{c.f_number:g}" if c.f_number else "full aperture") + f", exposure {c.exposure_s:g} s"
                 + (f", lens tilt {math.degrees(c.lens_tilt_rad):g} deg, swing {math.degrees(c.lens_swing_rad):g} deg, "
                    f"shift ({c.lens_shift_mm[0]:g}, {c.lens_shift_mm[1]:g}) mm" if c.is_tilt_shift else ""),
                 f"  sensor: {_format_label(s)}, {s.pixels_x} x {s.pixels_y} px "
                 f"({s.pixel_pitch_um:.3g} um)" + (f", preset {s.preset}" if s.preset else "")]
        for p in self.point_lights:
            lines.append(f"  point light {p.name!r} at {_fmt_m(p.position_mm)}: {p.intensity.label}")
        for q in self.sphere_lights:
            lines.append(f"  sphere light {q.name!r} r = {q.radius_mm:g} mm at {_fmt_m(q.center_mm)}: {q.radiance.label}")
        for pl in self.planes:
            what = f"emitting {pl.emission.label}" if pl.emission is not None else \
                f"reflecting ({pl.tint.label})" if pl.tint is not None else "reflecting"
            lines.append(f"  plane {pl.name!r} {pl.size_mm[0]:g} x {pl.size_mm[1]:g} mm at {_fmt_m(pl.center_mm)}: "
                         f"{pl.texture.kind}, {what}")
        for m in self.meshes:
            what = m.emission.label if m.emission is not None else m.reflectance.label if m.reflectance else ""
            lines.append(f"  mesh {m.name!r}: {m.n_triangles} triangles from {m.source} ({what})")
        if self.illumination is not None:
            lines.append(f"  uniform illumination: {self.illumination.label}")
        if self.background is not None:
            lines.append(f"  background: {self.background.label}")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _format_label(s: SensorSpec) -> str:
    size = f"{s.width_mm:g} x {s.height_mm:g} mm"
    return size if s.format_name[:1].isdigit() and "x" in s.format_name else f"{s.format_name} {size}"


def _fmt_m(p_mm: np.ndarray) -> str:
    return "(" + ", ".join(f"{v / 1000.0:.4g}" for v in p_mm) + ") m"
