"""Focusing a lens for bokeh, and the Gaussian-optics blur disc a point source makes on the sensor.

See :mod:`lensrt.analysis.bokeh.entry` for the conventions: unit focusing (Field Guide p. 12) moves
the sensor plane back by the extension e in the lens frame (first vertex at z = 0 in the
focused position); distances are measured in front of the first vertex. The blur disc: the
cone from the exit pupil (diameter D_XP at z_XP) to the paraxial image z'_p of the source cuts
the sensor plane z_S in a disc of diameter ``c = D_XP |z_S - z'_p| / |z'_p - z_XP|``; with
z'_p - z_XP = f' mp b_p (b_p = 1 + |m_p| / mp, p. 31) and D_XP = mp f / N this is
``c = |z_S - z'_p| / N_w`` in air, N_w the working f-number of the source's conjugate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ...errors import LensrtError
from ...prescription.model import Lens

__all__ = ["Focus", "focus_lens", "BlurPrediction", "gaussian_blur", "stop_radius_for_f_number"]


# ---- focus -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Focus:
    """Where the sensor sits: see the module docstring.

    Attributes
    ----------
    sensor_z_mm : float
        z of the sensor plane in the lens frame (first vertex at 0, focused position).
    extension_mm : float
        e: how far the lens is moved out from its infinity-focus position (p. 12).
    distance_mm : float
        Paraxial object distance in focus, in front of the first vertex (``inf``; ``nan``
        when the sensor sits in front of the infinity focus).
    wavelength_nm : float
        Wavelength of the first-order data.
    given : str
        What set it: ``"distance"``, ``"extension"`` or ``"sensor_z"``.
    """

    sensor_z_mm: float
    extension_mm: float
    distance_mm: float
    wavelength_nm: float
    given: str

    def to_dict(self) -> dict:
        return {"sensor_z_mm": self.sensor_z_mm, "extension_mm": self.extension_mm,
                "distance_mm": None if math.isnan(self.distance_mm) else self.distance_mm,
                "wavelength_nm": self.wavelength_nm, "given": self.given}


def focus_lens(lens: Lens, distance_mm: float | None = None, *, extension_mm: float | None = None,
               sensor_z_mm: float | None = None, wavelength_nm: float | None = None) -> Focus:
    """Focus ``lens`` by unit focusing at ``distance_mm`` (in front of the first vertex; ``inf``
    allowed), or by an extension e (mm), or put the sensor at ``sensor_z_mm``. Exactly one."""
    from ...paraxial import first_order
    given = [k for k, v in (("distance", distance_mm), ("extension", extension_mm), ("sensor_z", sensor_z_mm))
             if v is not None]
    if len(given) != 1:
        raise LensrtError("focus the lens by one of: a distance, an extension or a sensor position")
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    from ...paraxial.first_order import refuse_afocal
    refuse_afocal(lens, "focusing (bokeh, renders)", wl)
    fo = first_order(lens, wl)
    z_inf = lens.image_z_mm - fo.unit_focus_extension_mm  # the sensor z of infinity focus
    ff = fo.front_focal_length_mm * fo.rear_focal_length_mm
    if distance_mm is not None:
        s = float(distance_mm)
        if math.isnan(s) or s <= 0.0:
            raise LensrtError(f"focus distance {distance_mm!r} mm must be positive (inf for infinity)")
        if not math.isinf(s) and -s >= fo.front_focal_z_mm:
            raise LensrtError(f"the focus distance {s:g} mm is at or inside the front focal point "
                              f"({-fo.front_focal_z_mm:g} mm in front of the first vertex): no real image",
                              hint="focus farther away")
        e = 0.0 if math.isinf(s) else first_order(lens, wl, s).unit_focus_extension_mm
        return Focus(z_inf + e, e, s, wl, "distance")
    if extension_mm is not None:
        e = float(extension_mm)
        if not math.isfinite(e) or e < 0.0:
            raise LensrtError(f"extension {extension_mm!r} mm must be 0 (infinity) or positive",
                              hint="a negative extension focuses beyond infinity; give --sensor-z-mm for that")
    else:
        if not math.isfinite(float(sensor_z_mm)):
            raise LensrtError(f"sensor z {sensor_z_mm!r} mm must be a finite number")
        e = float(sensor_z_mm) - z_inf
        if float(sensor_z_mm) <= lens.length_mm:
            raise LensrtError(f"the sensor at z = {sensor_z_mm:g} mm is not behind the last vertex "
                              f"(z = {lens.length_mm:g} mm)")
    # Newton: x x' = f f' with x' = e, the object at z = z_F - x
    s = math.inf if e == 0.0 else (ff / e - fo.front_focal_z_mm if e > 0.0 else math.nan)
    return Focus(z_inf + e, e, s, wl, "extension" if extension_mm is not None else "sensor_z")


@dataclass(frozen=True)
class BlurPrediction:
    """Gaussian-optics blur disc of a point source (module docstring); lengths in mm."""

    diameter_mm: float
    image_z_mm: float
    defocus_mm: float
    exit_pupil_z_mm: float
    exit_pupil_diameter_mm: float
    working_f_number: float
    pupil_magnification: float

    @property
    def diameter_from_working_f_number_mm(self) -> float:
        """|defocus| / N_w: the same disc by the working f-number of the source's conjugate (in air)."""
        return abs(self.defocus_mm) / self.working_f_number


def gaussian_blur(lens: Lens, focus: Focus, source_distance_mm: float, wavelength_nm: float | None = None,
                  stop_radius_mm: float | None = None) -> BlurPrediction:
    """Paraxial blur-disc diameter on the sensor for an axial point source at ``source_distance_mm``.

    ``stop_radius_mm`` is the iris radius the rays see (default the stop's clear semi-diameter).
    """
    from ...paraxial import first_order
    wl = focus.wavelength_nm if wavelength_nm is None else float(wavelength_nm)
    fo = first_order(lens, wl, float(source_distance_mm))
    r_stop = _stop_radius(lens, stop_radius_mm)
    k = r_stop / fo.stop_semi_diameter_mm  # the iris against the aperture the first-order data assume
    xpd = fo.exit_pupil_diameter_mm * k
    dz = focus.sensor_z_mm - fo.image_z_mm
    c = xpd * abs(dz) / abs(fo.image_z_mm - fo.exit_pupil_z_mm)
    return BlurPrediction(c, fo.image_z_mm, dz, fo.exit_pupil_z_mm, xpd, fo.working_f_number / k,
                          fo.pupil_magnification)


def _stop_radius(lens: Lens, stop_radius_mm: float | None) -> float:
    if stop_radius_mm is not None:
        return float(stop_radius_mm)
    sd = lens.surfaces[lens.stop_index].semi_diameter_mm
    if sd is None:  # pragma: no cover - load_lens fills it
        raise LensrtError("the stop has no semi-diameter")
    return float(sd)


def stop_radius_for_f_number(lens: Lens, f_number: float) -> float:
    """The real stop radius (mm) that gives the lens f-number ``f_number`` (D = f/N on axis)."""
    from ...prescription.model import Aperture
    from ...trace.aiming import pupil_geometry
    if not (math.isfinite(f_number) and f_number > 0):
        raise LensrtError(f"f-number {f_number!r} must be positive")
    return float(pupil_geometry(lens.replace(aperture=Aperture("image_fno", float(f_number)))).stop_radius_mm)
