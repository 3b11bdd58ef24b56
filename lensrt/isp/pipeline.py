"""Raw conversion in the Field Guide's order (p. 65).

1. black level (bias) or dark-frame subtraction, normalisation to raw clipping = 1 (p. 47, 49);
2. white balance multipliers on the mosaic (from an illuminant or CCT, a grey patch, or given;
   p. 62-64), then clipping at 1 so that clipped highlights stay white (as dcraw does);
3. demosaicing (:mod:`lensrt.isp.demosaic`);
4. colour rotation to linear sRGB (camera -> XYZ fitted on the ColorChecker, chromatic
   adaptation to D65, XYZ -> sRGB; rows sum to 1; p. 59-63), times a digital exposure gain;
5. tone curve / encoding (sRGB or an S-curve; p. 66-69) and quantisation to 8 or 16 bits.

Usage::

    isp = Isp(sensor, IspSettings(illuminant="D65", demosaic="malvar2004"))
    out = isp.develop(raw)            # IspResult: out.linear (rows, cols, 3), out.encoded, out.to_uint16()
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..colour import Illuminant
from ..errors import LensrtError
from ..sensor.detector import RawFrame, subtract_dark
from ..sensor.model import Sensor
from .colour import ColourCalibration, calibrate
from .demosaic import demosaic
from .tone import SCurve, histogram, quantize, tone_curve

__all__ = ["IspSettings", "Isp", "IspResult", "raw_histograms", "output_histograms"]


@dataclass(frozen=True)
class IspSettings:
    """How to develop a raw frame.

    Attributes
    ----------
    illuminant : str or Illuminant
        Scene illuminant / adopted white: the spectrum itself (a :class:`lensrt.colour.Illuminant`, as
        the render stage passes it) or its name in the one syntax (``"D65"``, ``"A"``, ``"F2"``,
        ``"planck:3200K"``, ``"daylight:5000K"``): the colour matrix is fitted under it and, with
        ``white_balance="illuminant"``, the multipliers come from it.
    white_balance : str or tuple
        ``"illuminant"``, ``"grey"`` (multipliers from the mean raw of ``grey_region``) or three
        multipliers (R, G, B).
    grey_region : (row0, row1, col0, col1), optional
        Half-open pixel box of a neutral patch for ``white_balance="grey"``.
    demosaic : str
        ``bilinear``, ``malvar2004``, ``menon2007`` (Bayer) or ``normalized`` (any CFA).
    matrix_method : str
        ``lstsq`` (white-preserving least squares in XYZ) or ``de2000``.
    colour_matrix : 3x3, optional
        A given camera -> linear sRGB rotation (rows should sum to 1) instead of the fitted one.
    tone : str or SCurve
        ``srgb``, ``linear`` or an :class:`~lensrt.isp.tone.SCurve`.
    exposure_gain : float
        Digital gain on linear values (1: raw clipping -> linear 1.0).
    """

    illuminant: str | Illuminant = "D65"
    white_balance: str | tuple[float, float, float] = "illuminant"
    grey_region: tuple[int, int, int, int] | None = None
    demosaic: str = "bilinear"
    matrix_method: str = "lstsq"
    colour_matrix: Any = None
    tone: str | SCurve = "srgb"
    exposure_gain: float = 1.0


@dataclass
class IspResult:
    """A developed image. ``linear``: linear sRGB (rows, cols, 3) float32, not clipped; ``encoded``:
    tone-mapped [0, 1] float32; ``wb_multipliers``, ``camera_to_srgb``: what was applied;
    ``seconds``: time per step."""

    linear: np.ndarray
    encoded: np.ndarray
    wb_multipliers: np.ndarray
    camera_to_srgb: np.ndarray
    seconds: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def to_uint8(self) -> np.ndarray:
        return quantize(self.encoded, 8)

    def to_uint16(self) -> np.ndarray:
        return quantize(self.encoded, 16)


class Isp:
    """A raw converter for one sensor (the colour calibration is fitted once and reused)."""

    def __init__(self, sensor: Sensor, settings: IspSettings = IspSettings()) -> None:
        self.sensor = sensor
        self.settings = settings
        self._cal: ColourCalibration | None = None
        if not (settings.exposure_gain > 0):
            raise LensrtError("exposure gain must be > 0")

    @property
    def calibration(self) -> ColourCalibration:
        if self._cal is None:
            self._cal = calibrate(self.sensor, self.settings.illuminant, self.settings.matrix_method)
        return self._cal

    def with_settings(self, **changes: Any) -> "Isp":
        isp = Isp(self.sensor, replace(self.settings, **changes))
        if changes.keys() <= {"exposure_gain", "tone", "demosaic", "white_balance", "grey_region"}:
            isp._cal = self._cal
        return isp

    def wb_multipliers(self, normalized_mosaic: np.ndarray, raw: RawFrame) -> np.ndarray:
        s = self.settings
        if isinstance(s.white_balance, (tuple, list, np.ndarray)):
            m = np.asarray(s.white_balance, dtype=np.float64)
            if m.shape != (3,) or np.any(m <= 0):
                raise LensrtError("white balance multipliers must be three numbers > 0")
            return m / m[1]
        if s.white_balance == "illuminant":
            return self.calibration.wb_multipliers
        if s.white_balance == "grey":
            if s.grey_region is None:
                raise LensrtError("grey-patch white balance needs a region (row0, row1, col0, col1)")
            r0, r1, c0, c1 = s.grey_region
            patch = normalized_mosaic[r0:r1, c0:c1]
            cmap = raw.cfa.channel_map(*raw.dn.shape)[r0:r1, c0:c1]
            means = np.array([patch[cmap == c].mean() if np.any(cmap == c) else np.nan for c in range(3)])
            if not np.all(np.isfinite(means)) or np.any(means <= 0):
                raise LensrtError(f"grey region {s.grey_region} holds no usable signal in every channel")
            return means[1] / means
        raise LensrtError(f"unknown white balance {s.white_balance!r}", hint="use illuminant, grey or three numbers")

    def develop(self, raw: RawFrame, dark: RawFrame | None = None) -> IspResult:
        """Develop ``raw`` (optionally subtracting a master ``dark`` frame) into linear and encoded sRGB."""
        s = self.settings
        sec: dict[str, float] = {}
        t0 = time.perf_counter()
        if dark is not None:
            raw = subtract_dark(raw, dark)
        mosaic = raw.normalized()  # 1. black level, raw clip -> 1
        sec["black_level"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        wb = self.wb_multipliers(mosaic, raw)  # 2. white balance on the mosaic
        gains = wb.astype(np.float32)[raw.cfa.channel_map(*mosaic.shape)]
        mosaic *= gains
        np.clip(mosaic, None, 1.0, out=mosaic)
        sec["white_balance"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        rgb = demosaic(mosaic, raw.cfa, s.demosaic)  # 3.
        sec["demosaic"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        R = np.asarray(s.colour_matrix if s.colour_matrix is not None else self.calibration.camera_to_srgb, dtype=np.float64)
        if R.shape != (3, 3):
            raise LensrtError("colour matrix must be 3x3")
        M = (R * s.exposure_gain).astype(np.float32)  # 4. colour rotation and exposure gain
        linear = (rgb.reshape(-1, 3) @ M.T).reshape(rgb.shape)
        sec["colour"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        encoded = tone_curve(linear, s.tone)  # 5.
        sec["tone"] = time.perf_counter() - t0
        return IspResult(linear=linear, encoded=encoded, wb_multipliers=wb, camera_to_srgb=R, seconds=sec,
                         meta={"illuminant": _illuminant_name(s.illuminant), "demosaic": s.demosaic,
                               "tone": s.tone if isinstance(s.tone, str) else f"scurve(contrast={s.tone.contrast})",
                               "exposure_gain": s.exposure_gain})


def _illuminant_name(illuminant: str | Illuminant) -> str:
    return illuminant.name if isinstance(illuminant, Illuminant) else str(illuminant)


def raw_histograms(raw: RawFrame, bins: int = 256) -> dict[str, Any]:
    """Histograms of the raw values of each CFA channel over 0 .. white level (p. 69)."""
    cmap = raw.cfa.channel_map(*raw.dn.shape)
    out: dict[str, Any] = {"range_dn": (0.0, float(raw.white_level_dn) + 1)}
    for c, name in enumerate("RGB"):
        out[name], out["edges"] = histogram(raw.dn[cmap == c], bins, out["range_dn"])
    return out


def output_histograms(image: np.ndarray, bins: int = 256) -> dict[str, Any]:
    """Histograms of output levels (uint8 or uint16 image, (rows, cols, 3)) per channel (p. 69)."""
    top = 255 if image.dtype == np.uint8 else 65535
    out: dict[str, Any] = {"range_dol": (0.0, top + 1.0)}
    for c, name in enumerate("RGB"):
        out[name], out["edges"] = histogram(image[..., c], bins, out["range_dol"])
    return out
