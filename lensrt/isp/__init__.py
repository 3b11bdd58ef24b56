"""Stage 7: raw conversion -- a RawFrame -> linear and encoded sRGB (Field Guide p. 59-70).

Public API::

    from lensrt.isp import Isp, IspSettings
    result = Isp(sensor, IspSettings(illuminant="D65", demosaic="malvar2004")).develop(raw)
    result.linear      # (rows, cols, 3) float32 linear sRGB (D65), raw clipping at 1 x exposure_gain
    result.to_uint16() # (rows, cols, 3) uint16 sRGB-encoded
"""
from __future__ import annotations

from .colour import ColourCalibration, calibrate, white_balance_from_illuminant
from .demosaic import DEMOSAIC_METHODS, demosaic
from .metrics import exposure_gain_for_iso, sos_iso
from .pipeline import Isp, IspResult, IspSettings, output_histograms, raw_histograms
from .tone import SCurve, image_dynamic_range_stops, quantize, tone_curve
from ..colour import srgb_decode, srgb_encode  # re-exported for one release: their home is lensrt.colour

__all__ = ["ColourCalibration", "calibrate", "white_balance_from_illuminant", "DEMOSAIC_METHODS", "demosaic",
           "exposure_gain_for_iso", "sos_iso", "Isp", "IspResult", "IspSettings", "output_histograms",
           "raw_histograms", "SCurve", "image_dynamic_range_stops", "quantize", "srgb_decode", "srgb_encode",
           "tone_curve"]
