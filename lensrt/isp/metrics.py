"""Exposure metrics of a sensor + raw converter: SOS-based ISO (Field Guide p. 77) and dynamic range.

* ISO 12232 standard output sensitivity: S_SOS = 10 / H_SOS, with H_SOS the sensor-plane
  photometric exposure (lux s) of a uniform neutral that the complete pipeline renders at
  DOL 118 of 255 in sRGB (18 % grey, p. 77). Computed noise-free through the same white
  balance, colour rotation, exposure gain and tone curve the :class:`Isp` uses.
* Raw dynamic range per ISO (p. 51): :meth:`lensrt.sensor.Sensor.raw_dynamic_range_stops`.
* Image dynamic range of the tone curve (p. 70): :func:`lensrt.isp.tone.image_dynamic_range_stops`.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from ..colour import STANDARD_WAVELENGTHS_NM
from ..sensor.exposure import spectral_irradiance_from_illuminance
from .pipeline import Isp
from .tone import inverse_tone_curve

__all__ = ["sos_iso", "exposure_gain_for_iso", "SOS_DOL", "neutral_output"]

#: the 8-bit sRGB output level that 18 % grey must reach for SOS (p. 77)
SOS_DOL = 118


def neutral_output(isp: Isp, iso: float, exposure_lux_s: float) -> np.ndarray:
    """Mean linear sRGB (3,) of a uniform neutral of the ISP's illuminant at ``exposure_lux_s``, noise-free.

    Follows the ISP's steps on the mean raw values (black-subtracted, normalised, white
    balanced, clipped at 1, colour-rotated, exposure gain).
    """
    sensor = isp.sensor
    wl = STANDARD_WAVELENGTHS_NM
    E = spectral_irradiance_from_illuminance(1.0, isp.settings.illuminant, wl)  # 1 lux
    electrons = (E @ sensor.electron_weights(wl)) * exposure_lux_s  # 1 lux for exposure_lux_s seconds
    dn = np.minimum(electrons, sensor.full_well_e) / sensor.g_e_per_dn(iso)
    white = sensor.white_level_dn(iso) - sensor.bias_dn
    norm = np.minimum(dn, white) / white
    wbs = isp.settings.white_balance
    wb = np.asarray(wbs, float) / wbs[1] if isinstance(wbs, (tuple, list)) else isp.calibration.wb_multipliers
    cam = np.minimum(norm * wb, 1.0)
    return (isp.calibration.camera_to_srgb if isp.settings.colour_matrix is None
            else np.asarray(isp.settings.colour_matrix)) @ cam * isp.settings.exposure_gain


def sos_iso(isp: Isp, iso: float | None = None) -> float:
    """Standard output sensitivity S_SOS = 10 / H_SOS of the sensor + ISP at ISO setting ``iso`` (p. 77)."""
    iso = isp.sensor.base_iso if iso is None else iso
    target = float(inverse_tone_curve(np.array(SOS_DOL / 255.0), isp.settings.tone))
    h = 1e-3
    y = float(neutral_output(isp, iso, h)[1])  # green of a neutral (R = G = B after the rotation)
    if y <= 0:
        raise LensrtError("the sensor gives no signal for a neutral")
    h_sos = h * target / y
    if float(neutral_output(isp, iso, h_sos)[1]) < 0.999 * target:
        raise LensrtError("DOL 118 cannot be reached before clipping")
    return 10.0 / h_sos


def exposure_gain_for_iso(isp: Isp, iso: float) -> float:
    """Digital exposure gain that makes the pipeline's SOS equal the ISO setting (the maker's calibration)."""
    s = sos_iso(isp.with_settings(exposure_gain=1.0), iso)
    return iso / s
