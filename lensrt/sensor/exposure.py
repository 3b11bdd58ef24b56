"""Photometry for exposure: illuminants, lux <-> W/(m^2 nm), the light meter, the camera equation.

* Spectral irradiance from an illuminance: E_lambda = E_v S(lambda) / (K_m int S V d lambda),
  K_m = 683 lm/W, V the CIE 1924 photopic luminous efficiency (colour-science).
* Reflected-light meter (Field Guide p. 75): N^2 / t = L S / K, with the meter calibration
  constant K = 12.5 cd s / m^2 (Canon, Nikon, Sekonic; 14 for Pentax).
* Camera equation at infinity focus: H = q L t / N^2 lux s with q = pi T cos^4(theta) / 4,
  q = 0.65 in ISO 12232 (lens transmission 0.9, on axis, vignetting and flare allowances).
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from ..units import LUMINOUS_EFFICACY_LM_PER_W

__all__ = ["illuminant_spd", "spectral_irradiance_from_illuminance", "illuminance_lux", "metered_exposure_time_s",
           "focal_plane_exposure_lux_s", "METER_CONSTANT_K", "CAMERA_EQUATION_Q", "STANDARD_WAVELENGTHS_NM"]

#: reflected-light meter calibration constant K (cd s m^-2), Canon/Nikon/Sekonic (p. 75)
METER_CONSTANT_K = 12.5
#: camera-equation factor q of ISO 12232 (p. 75): pi/4 * T(0.9) * vignetting/flare allowances
CAMERA_EQUATION_Q = 0.65
#: the 5 nm grid 380..780 nm on which colour-science's camera and ColorChecker data are given
STANDARD_WAVELENGTHS_NM = np.arange(380.0, 781.0, 5.0)


def illuminant_spd(illuminant: str | float, wavelength_nm: np.ndarray) -> np.ndarray:
    """Relative spectral power of an illuminant at ``wavelength_nm`` (arbitrary scale).

    Parameters
    ----------
    illuminant : str or float
        A CIE illuminant colour-science ships (``"D65"``, ``"D50"``, ``"A"``, ``"F2"`` ...), or a
        correlated colour temperature in kelvin (number or ``"5000K"``): the CIE daylight
        series from 4000 K up, a Planckian radiator below.
    """
    import colour
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    cct = _as_cct(illuminant)
    if cct is not None:
        if not 1000 <= cct <= 25000:
            raise LensrtError(f"colour temperature {cct:g} K is outside 1000..25000 K")
        if cct >= 4000:
            xy = colour.temperature.CCT_to_xy_CIE_D(cct * 1.4388 / 1.4380)
            sd = colour.sd_CIE_illuminant_D_series(xy)
        else:
            sd = colour.sd_blackbody(cct, colour.SpectralShape(300, 900, 1))
    else:
        if illuminant not in colour.SDS_ILLUMINANTS:
            raise LensrtError(f"unknown illuminant {illuminant!r}",
                              hint="use D65, D50, A, F2, ... or a colour temperature such as 5000K")
        sd = colour.SDS_ILLUMINANTS[illuminant]
    values = np.interp(wl, sd.wavelengths, sd.values, left=0.0, right=0.0)
    return values / values.max()


def _as_cct(illuminant: str | float) -> float | None:
    if isinstance(illuminant, (int, float)):
        return float(illuminant)
    text = str(illuminant).strip().upper()
    if text.endswith("K"):
        try:
            return float(text[:-1])
        except ValueError:
            raise LensrtError(f"cannot read colour temperature {illuminant!r}") from None
    return None


def _photopic_v(wavelength_nm: np.ndarray) -> np.ndarray:
    import colour
    v = colour.SDS_LEFS["CIE 1924 Photopic Standard Observer"]
    return np.interp(wavelength_nm, v.wavelengths, v.values, left=0.0, right=0.0)


def illuminance_lux(irradiance_w_m2_nm: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Illuminance E_v = K_m int E_lambda V d lambda (lux) of spectra on the last axis (trapezoid)."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    return LUMINOUS_EFFICACY_LM_PER_W * np.trapezoid(np.asarray(irradiance_w_m2_nm) * _photopic_v(wl), wl, axis=-1)


def spectral_irradiance_from_illuminance(illuminance_lux_value: float, illuminant: str | float,
                                         wavelength_nm: np.ndarray) -> np.ndarray:
    """Spectral irradiance (W / (m^2 nm)) of ``illuminant`` that has illuminance ``illuminance_lux_value``."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    s = illuminant_spd(illuminant, wl)
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
