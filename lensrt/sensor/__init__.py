"""Stage 6: the sensor -- spectral irradiance -> electrons -> raw DN (Field Guide p. 37-51).

Public API (what the render stage calls)::

    from lensrt.sensor import get_preset, expose, Switches
    sensor = get_preset("fullframe_24mp")            # or sensor_from_spec({...}) for a scene's [sensor]
    raw = expose(sensor, E, wavelength_nm, exposure_s, iso=400, rng=np.random.default_rng(1))

``E``: float array (rows, cols, n) of sensor-plane spectral irradiance in W / (m^2 nm), origin
top-left, wavelength axis last, ``wavelength_nm`` (n,) beside it. ``raw`` is a
:class:`RawFrame` (uint16 DN mosaic, CFA, black and white levels, metadata); develop it with
:class:`lensrt.isp.Isp`.
"""
from __future__ import annotations

from .cfa import BAYER_PHASES, CFA, XTRANS_PATTERN, parse_cfa
from .detector import (RawFrame, Switches, average_frames, dark_frame, electrons_to_raw, expose,
                       fixed_pattern_maps, mean_photoelectrons, subtract_dark)
from .model import Sensor
from .presets import PRESETS, get_preset, sensor_from_spec
from .spectral import SpectralResponse, camera_response, load_response

__all__ = ["BAYER_PHASES", "CFA", "XTRANS_PATTERN", "parse_cfa", "RawFrame", "Switches", "average_frames",
           "dark_frame", "electrons_to_raw", "expose", "fixed_pattern_maps", "mean_photoelectrons",
           "subtract_dark", "Sensor", "sensor_from_spec", "PRESETS", "get_preset", "SpectralResponse",
           "camera_response", "load_response"]
