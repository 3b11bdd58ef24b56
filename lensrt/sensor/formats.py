"""Named sensor formats (width x height in mm) and the ``"WxH"`` form.

The names are the ones the paraxial stage's photographic formulas use
(angle of view, crop factor); sizes are the nominal active areas.
"""
from __future__ import annotations

import re

from ..errors import LensrtError

__all__ = ["SENSOR_FORMATS_MM", "parse_sensor_format"]

#: nominal active area (width, height) in mm of common formats
SENSOR_FORMATS_MM: dict[str, tuple[float, float]] = {
    "full-frame": (36.0, 24.0),
    "aps-c": (23.6, 15.7),
    "mft": (17.3, 13.0),
    "1-inch": (13.2, 8.8),
    "2/3-inch": (8.6, 6.6),
    "1/1.7-inch": (7.6, 5.7),
    "1/2.5-inch": (5.76, 4.29),
}

_WXH = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*[xX\u00d7]\s*([0-9]*\.?[0-9]+)\s*(mm)?\s*$")


def parse_sensor_format(text: str) -> tuple[str, float, float]:
    """``(name, width_mm, height_mm)`` of a format name (``"full-frame"``) or ``"36x24"`` (mm).

    Names are case-insensitive; ``"ff"``/``"35mm"`` mean full-frame,
    ``"m43"``/``"micro-four-thirds"`` mean mft.
    """
    if not isinstance(text, str):
        raise LensrtError(f"sensor format {text!r} is not a name or a 'WxH' string")
    key = text.strip().lower().replace("_", "-").replace(" ", "-")
    key = {"ff": "full-frame", "35mm": "full-frame", "fullframe": "full-frame", "apsc": "aps-c",
           "m43": "mft", "micro-four-thirds": "mft", "four-thirds": "mft", "1in": "1-inch",
           "1\"": "1-inch"}.get(key, key)
    if key in SENSOR_FORMATS_MM:
        w, h = SENSOR_FORMATS_MM[key]
        return key, w, h
    m = _WXH.match(text)
    if m:
        w, h = float(m.group(1)), float(m.group(2))
        if w > 0 and h > 0:
            return f"{w:g}x{h:g}", w, h
    raise LensrtError(f"unknown sensor format {text!r}",
                      hint="use one of " + ", ".join(SENSOR_FORMATS_MM) + ", or 'WxH' in mm such as '36x24'")
