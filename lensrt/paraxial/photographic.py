"""The photographer's formulas of the Field Guide to Photographic Science (Rowlands, SPIE 2020).

Each is a plain function (vectorised where that is natural), with the unit in
its name and the page it comes from. Conventions, as in the Field Guide:

* f is the (front) effective focal length and f' the rear one (equal in air);
  N = f / D the f-number; mp = D_XP / D the pupil magnification.
* Object distances ``s`` run from the front principal plane P to the object,
  positive for a real object (so |m| = f / (s - f), p. 8).
* s_EP is the distance from P to the entrance pupil, positive toward the
  object: s_EP = (1 - 1/mp) f (p. 10; ``FirstOrder.entrance_pupil_distance_mm``).
* Depth-of-field limits and the hyperfocal distance are measured from the
  entrance pupil (the lens's centre of perspective), as H = h - s_EP + f (p. 24) is.

Photometric units: luminance L in cd/m^2, illuminance E in lux, exposure H in
lux s, time in s. Angles in radians.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError

__all__ = [
    "SensorFormat", "SENSOR_FORMATS", "FULL_FRAME_DIAGONAL_MM", "sensor_format",
    "magnification_at_distance", "bellows_factor", "working_f_number", "afov_rad",
    "unit_focus_extension_mm", "unit_focus_object_distance_mm", "focus_breathing_afov_rad",
    "focal_length_multiplier", "equivalent_focal_length_mm", "coc_diameter_mm",
    "DepthOfField", "hyperfocal_distance_mm", "depth_of_field_mm",
    "image_illuminance_lux", "exposure_lux_s", "t_number", "METER_CALIBRATION_K",
    "meter_exposure_time_s", "exposure_value", "apex_av", "apex_tv", "apex_sv", "apex_bv",
]


# ---- sensor formats (p. 19, p. 22) -------------------------------------------------------

@dataclass(frozen=True)
class SensorFormat:
    """A sensor format: size (mm) and the circle-of-confusion diameter for it (mm)."""

    name: str
    width_mm: float
    height_mm: float
    coc_mm: float

    @property
    def diagonal_mm(self) -> float:
        return math.hypot(self.width_mm, self.height_mm)

    @property
    def crop_factor(self) -> float:
        """Focal-length multiplier R = d1 / d2 against 35 mm full frame (p. 19)."""
        return focal_length_multiplier(self.diagonal_mm)


#: The Field Guide's format table (p. 19) with its CoC diameters (p. 22).
SENSOR_FORMATS: dict[str, SensorFormat] = {f.name: f for f in (
    SensorFormat("full-frame", 36.0, 24.0, 0.030),
    SensorFormat("aps-c", 23.6, 15.7, 0.020),
    SensorFormat("mft", 17.3, 13.0, 0.015),
    SensorFormat("1-inch", 13.2, 8.8, 0.011),
    SensorFormat("2/3-inch", 8.6, 6.6, 0.008),
    SensorFormat("1/1.7-inch", 7.6, 5.7, 0.006),
    SensorFormat("1/2.5-inch", 5.76, 4.29, 0.005),
)}
_ALIASES = {"ff": "full-frame", "35mm": "full-frame", "fullframe": "full-frame", "apsc": "aps-c",
            "m43": "mft", "micro4/3": "mft", "microfourthirds": "mft", "4/3": "mft", "1inch": "1-inch",
            "1in": "1-inch", '1"': "1-inch", "2/3inch": "2/3-inch", "2/3in": "2/3-inch",
            "1/1.7inch": "1/1.7-inch", "1/1.7in": "1/1.7-inch", "1/2.5inch": "1/2.5-inch",
            "1/2.5in": "1/2.5-inch"}
#: diagonal of the 36 x 24 mm format (mm): d1 of p. 19
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)


def sensor_format(spec: str) -> SensorFormat:
    """A format by name (``full-frame``, ``aps-c``, ``mft``, ``1-inch``, ``2/3-inch``,
    ``1/1.7-inch``, ``1/2.5-inch``) or size ``WxH`` in mm (e.g. ``36x24``).

    A custom size gets the CoC of p. 22's rule, scaled by diagonal from the
    full-frame 0.030 mm (:func:`coc_diameter_mm`).
    """
    key = spec.strip().lower().replace(" ", "")
    key = _ALIASES.get(key, key)
    if key in SENSOR_FORMATS:
        return SENSOR_FORMATS[key]
    m = re.fullmatch(r"(\d+(?:\.\d*)?|\.\d+)(?:mm)?[x*](\d+(?:\.\d*)?|\.\d+)(?:mm)?", key)
    if m:
        w, h = float(m.group(1)), float(m.group(2))
        if w > 0 and h > 0:
            return SensorFormat(f"{w:g}x{h:g}", w, h, coc_diameter_mm(math.hypot(w, h)))
    raise LensrtError(f"unknown sensor format {spec!r}",
                      hint=f"use one of {', '.join(SENSOR_FORMATS)} or a size WxH in mm, e.g. 36x24")


def coc_diameter_mm(sensor_diagonal_mm: float) -> float:
    """Circle-of-confusion diameter (mm) for a format of this diagonal: 0.030 mm / R (p. 22).

    The p. 22 table follows this rule (c = d / 1442) within 10 %; its own
    values are kept for the named formats.
    """
    return 0.030 * sensor_diagonal_mm / FULL_FRAME_DIAGONAL_MM


# ---- magnification, bellows factor, angle of view (p. 8, 17, 31) ------------------------

def magnification_at_distance(object_distance_mm, focal_length_mm):
    """|m| = f / (s - f) for an object at s from the front principal plane (p. 8); 0 at s = inf."""
    s = np.asarray(object_distance_mm, dtype=np.float64)
    f = np.asarray(focal_length_mm, dtype=np.float64)
    with np.errstate(divide="ignore"):
        m = np.where(np.isinf(s), 0.0, f / (s - f))
    return float(m) if m.ndim == 0 else m


def bellows_factor(magnification, pupil_magnification=1.0):
    """b = 1 + |m| / mp (p. 31)."""
    b = 1.0 + np.abs(np.asarray(magnification, dtype=np.float64)) / np.asarray(pupil_magnification)
    return float(b) if b.ndim == 0 else b


def working_f_number(f_number, magnification, pupil_magnification=1.0):
    """Nw = b N (p. 31)."""
    return np.asarray(f_number) * bellows_factor(magnification, pupil_magnification) + 0.0


def afov_rad(sensor_dimension_mm, focal_length_mm, bellows=1.0):
    """Angular field of view alpha = 2 atan(d / (2 b f)) (p. 17), rad.

    ``sensor_dimension_mm`` is the width, height or diagonal d; ``bellows`` the
    bellows factor b (1 at infinity focus).
    """
    a = 2.0 * np.arctan(np.asarray(sensor_dimension_mm, dtype=np.float64)
                        / (2.0 * np.asarray(bellows) * np.asarray(focal_length_mm)))
    return float(a) if a.ndim == 0 else a


# ---- unit focusing and focus breathing (p. 12, p. 18) -----------------------------------

def unit_focus_extension_mm(object_distance_mm, focal_length_mm, rear_focal_length_mm=None):
    """Lens extension e of a unit-focusing lens for an object at s (p. 12), mm.

    Newton's x x' = f f' with x = s - f: e = f f' / (s - f) (= f^2 / (s - f) in
    air); s from the front principal plane; e = 0 at infinity.
    """
    f = np.asarray(focal_length_mm, dtype=np.float64)
    fr = f if rear_focal_length_mm is None else np.asarray(rear_focal_length_mm, dtype=np.float64)
    s = np.asarray(object_distance_mm, dtype=np.float64)
    if np.any(s <= f):
        raise LensrtError("the object is at or inside the front focal point: no real image to focus on")
    with np.errstate(divide="ignore"):
        e = np.where(np.isinf(s), 0.0, f * fr / (s - f))
    return float(e) if e.ndim == 0 else e


def unit_focus_object_distance_mm(extension_mm, focal_length_mm, rear_focal_length_mm=None):
    """Inverse of :func:`unit_focus_extension_mm`: s = f + f f' / e (p. 12); inf at e = 0."""
    f = np.asarray(focal_length_mm, dtype=np.float64)
    fr = f if rear_focal_length_mm is None else np.asarray(rear_focal_length_mm, dtype=np.float64)
    e = np.asarray(extension_mm, dtype=np.float64)
    if np.any(e < 0):
        raise LensrtError("a negative extension focuses beyond infinity")
    with np.errstate(divide="ignore"):
        s = np.where(e == 0.0, np.inf, f + f * fr / np.where(e == 0.0, 1.0, e))
    return float(s) if s.ndim == 0 else s


def focus_breathing_afov_rad(object_distance_mm, focal_length_mm, sensor_dimension_mm, pupil_magnification=1.0):
    """AFoV of a unit-focusing lens against object distance s (p. 18), rad.

    |m| = f / (s - f), b = 1 + |m| / mp, alpha = 2 atan(d / (2 b f)): the field
    narrows as the lens focuses closer.
    """
    m = magnification_at_distance(object_distance_mm, focal_length_mm)
    return afov_rad(sensor_dimension_mm, focal_length_mm, bellows_factor(m, pupil_magnification))


# ---- equivalent focal length (p. 19) ------------------------------------------------------

def focal_length_multiplier(sensor_diagonal_mm, reference_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM):
    """R = d1 / d2: reference (35 mm full frame) diagonal over this format's (p. 19)."""
    return reference_diagonal_mm / np.asarray(sensor_diagonal_mm, dtype=np.float64) + 0.0


def equivalent_focal_length_mm(focal_length_mm, multiplier):
    """35 mm-equivalent focal length f_E = R f (p. 19), mm."""
    return np.asarray(focal_length_mm) * np.asarray(multiplier) + 0.0


# ---- depth of field (p. 23-24) ------------------------------------------------------------

@dataclass(frozen=True)
class DepthOfField:
    """Near and far limits of acceptable sharpness, measured from the entrance pupil (mm).

    ``far_mm`` and ``total_mm`` are ``inf`` at and beyond the hyperfocal distance.
    """

    near_mm: float
    far_mm: float
    total_mm: float
    hyperfocal_mm: float


def hyperfocal_distance_mm(focal_length_mm: float, f_number: float, coc_mm: float,
                           s_ep_mm: float = 0.0) -> float:
    """Hyperfocal distance H = h - s_EP + f with h = f^2 / (c N) (p. 24), from the entrance pupil, mm."""
    h = focal_length_mm ** 2 / (coc_mm * f_number)
    return h - s_ep_mm + focal_length_mm


def depth_of_field_mm(focus_distance_mm: float, focal_length_mm: float, f_number: float, coc_mm: float,
                      s_ep_mm: float = 0.0) -> DepthOfField:
    """Near/far/total depth of field with the pupil term s_EP (p. 23).

    Parameters
    ----------
    focus_distance_mm : float
        Distance u from the entrance pupil to the plane in focus (mm; ``inf`` allowed).
    focal_length_mm, f_number : float
        f and N = f / D.
    coc_mm : float
        Circle-of-confusion diameter c (mm).
    s_ep_mm : float
        s_EP = (1 - 1/mp) f, from P to the entrance pupil, + toward the object.

    Notes
    -----
    A point at u_x from the pupil sends a cone through the pupil (diameter
    D = f / N) that cuts the plane in focus in a disc of diameter
    D |u - u_x| / u_x; the lens images it with |m| = f / (s - f), s = u + s_EP.
    Setting the image disc to c gives, with h = f^2 / (c N),
    u_near = h u / (h + s - f) and u_far = h u / (h - (s - f)) (inf once
    s - f >= h, i.e. u >= H = h - s_EP + f). At u = H, u_near = H / 2.
    """
    if coc_mm <= 0 or f_number <= 0 or focal_length_mm <= 0:
        raise LensrtError("depth of field needs a positive focal length, f-number and CoC diameter")
    f = focal_length_mm
    h = f * f / (coc_mm * f_number)
    H = h - s_ep_mm + f
    u = float(focus_distance_mm)
    if math.isinf(u):
        return DepthOfField(h, math.inf, math.inf, H)
    s = u + s_ep_mm
    if s <= f:
        raise LensrtError(f"the focus distance {u:g} mm is inside the front focal point")
    near = h * u / (h + s - f)
    far = h * u / (h - (s - f)) if s - f < h else math.inf
    return DepthOfField(near, far, far - near, H)


# ---- illuminance, exposure, metering (p. 31-34, 75, 78) ----------------------------------

def image_illuminance_lux(luminance_cd_m2, working_f_number, transmittance=1.0, field_angle_rad=0.0):
    """Camera equation E = (pi/4) L T cos^4(theta) / Nw^2 (p. 31-33), lux."""
    e = (math.pi / 4.0) * np.asarray(luminance_cd_m2) * np.asarray(transmittance) \
        * np.cos(np.asarray(field_angle_rad)) ** 4 / np.asarray(working_f_number) ** 2
    return float(e) if np.ndim(e) == 0 else e


def exposure_lux_s(illuminance_lux, exposure_s):
    """Photometric exposure H = E t (p. 33), lux s."""
    return np.asarray(illuminance_lux) * np.asarray(exposure_s) + 0.0


def t_number(f_number, transmittance):
    """T-number T# = N / sqrt(T) (p. 34)."""
    return np.asarray(f_number) / np.sqrt(np.asarray(transmittance)) + 0.0


#: reflected-light meter calibration constant K = 10 / 0.65 (p. 75), cd s / m^2
METER_CALIBRATION_K = 10.0 / 0.65


def meter_exposure_time_s(mean_luminance_cd_m2, f_number, iso_speed, k: float = METER_CALIBRATION_K):
    """Reflected-light meter equation t / N^2 = K / (<L> S) (p. 75) solved for t, s.

    With q = (pi/4) T cos^4(theta) = 0.65 the metered scene average lands at
    the sensor exposure H = q K / S = 10 / S lux s (the ISO 12232 mid-tone).
    """
    return k * np.asarray(f_number) ** 2 / (np.asarray(mean_luminance_cd_m2) * np.asarray(iso_speed)) + 0.0


def exposure_value(f_number, exposure_s):
    """Exposure value EV = log2(N^2 / t) (p. 78)."""
    return np.log2(np.asarray(f_number) ** 2 / np.asarray(exposure_s)) + 0.0


def apex_av(f_number):
    """APEX aperture value Av = log2 N^2 (p. 78)."""
    return 2.0 * np.log2(np.asarray(f_number)) + 0.0


def apex_tv(exposure_s):
    """APEX time value Tv = log2(1/t) (p. 78)."""
    return -np.log2(np.asarray(exposure_s)) + 0.0


def apex_sv(iso_speed):
    """APEX speed value Sv = log2(S / 3.125) (p. 78; Sv = 5 at ISO 100)."""
    return np.log2(np.asarray(iso_speed) / 3.125) + 0.0


def apex_bv(luminance_cd_m2, k: float = METER_CALIBRATION_K):
    """APEX brightness value Bv = log2(3.125 L / K) (p. 78).

    Defined with the meter constant K so that Av + Tv = Bv + Sv = EV holds
    exactly whenever the meter equation (p. 75) does.
    """
    return np.log2(3.125 * np.asarray(luminance_cd_m2) / k) + 0.0
