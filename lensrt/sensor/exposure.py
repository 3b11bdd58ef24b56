"""Photometry for exposure: lux <-> W/(m^2 nm), the light meter, the camera equation.

* Spectral irradiance from an illuminance: E_lambda = E_v S(lambda) / (K_m int S V d lambda),
  K_m = 683 lm/W, V the CIE 1924 photopic luminous efficiency; S an illuminant of
  :mod:`lensrt.colour` (``illuminance_lux`` and ``STANDARD_WAVELENGTHS_NM`` are re-exported from there).
* Reflected-light meter (Field Guide p. 75): N^2 / t = L S / K, with the meter calibration
  constant K = 12.5 cd s / m^2 (Canon, Nikon, Sekonic; 14 for Pentax).
* Camera equation at infinity focus: H = q L t / N^2 lux s with q = pi T cos^4(theta) / 4,
  q = 0.65 in ISO 12232 (lens transmission 0.9, on axis, vignetting and flare allowances).
"""
from __future__ import annotations

import numpy as np

from ..colour import STANDARD_WAVELENGTHS_NM, Illuminant, illuminance_lux, parse_illuminant
from ..errors import LensrtError

__all__ = ["spectral_irradiance_from_illuminance", "illuminance_lux", "metered_exposure_time_s",
           "focal_plane_exposure_lux_s", "METER_CONSTANT_K", "CAMERA_EQUATION_Q", "STANDARD_WAVELENGTHS_NM"]

#: reflected-light meter calibration constant K (cd s m^-2), Canon/Nikon/Sekonic (p. 75)
METER_CONSTANT_K = 12.5
#: camera-equation factor q of ISO 12232 (p. 75): pi/4 * T(0.9) * vignetting/flare allowances
CAMERA_EQUATION_Q = 0.65


def spectral_irradiance_from_illuminance(illuminance_lux_value: float, illuminant: str | Illuminant,
                                         wavelength_nm: np.ndarray) -> np.ndarray:
    """Spectral irradiance (W / (m^2 nm)) of ``illuminant`` (an :class:`~lensrt.colour.Illuminant` or its
    name, ``"D65"``, ``"planck:3200K"``, ...) that has illuminance ``illuminance_lux_value``."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    s = parse_illuminant(illuminant).relative(wl)
    lux_per_unit = float(illuminance_lux(s, wl))
    if lux_per_unit <= 0:
        raise LensrtError("the wavelength range holds no visible light")
    return s * (illuminance_lux_value / lux_per_unit)


def metered_exposure_time_s(luminance_cd_m2: float, f_number: float, iso: float,
                            meter_constant: float = METER_CONSTANT_K) -> float:
    """Exposure time a reflected-light meter sets: t = K N^2 / (L S) (p. 75)."""
    if luminance_cd_m2 <= 0 or f_number <= 0 or iso <= 0:
        raise LensrtError("luminance, f-number and ISO must be > 0")
    return meter_constant * f_number ** 2 / (luminance_cd_m2 * iso)


def focal_plane_exposure_lux_s(luminance_cd_m2: float, f_number: float, exposure_s: float,
                               q: float = CAMERA_EQUATION_Q) -> float:
    """Photometric exposure at the sensor H = q L t / N^2 (lux s), camera equation at infinity focus."""
    return q * luminance_cd_m2 * exposure_s / f_number ** 2
