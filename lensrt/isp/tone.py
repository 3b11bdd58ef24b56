"""Tone curves, encoding to 8/16-bit output levels, histograms (Field Guide p. 66-70).

* sRGB encoding (IEC 61966-2-1, :func:`lensrt.colour.srgb_encode`): 12.92 x for x <= 0.0031308,
  1.055 x^(1/2.4) - 0.055 above.
* A custom S-curve (:class:`SCurve`): y = A x^c / (x^c + k), the log-logistic
  (Naka-Rushton) form, fixed so that mid-grey stays mid-grey (f(m) = m) and the white input
  maps to 1; c > 1 lifts mid-tone contrast, rolls off the highlights and darkens the toe, as
  camera JPEG curves do (p. 66-69). It is applied to linear values before the sRGB encoding.
* The image dynamic range of an encoding (p. 70) is the ratio of the linear value that
  reaches the top output level to the one that reaches DOL 1: for sRGB with 8 bits,
  log2(255 * 12.92) = 11.7 stops -- computed by :func:`image_dynamic_range_stops`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..colour import srgb_decode, srgb_encode
from ..errors import LensrtError

__all__ = ["SCurve", "tone_curve", "inverse_tone_curve", "quantize",
           "image_dynamic_range_stops", "histogram"]


@dataclass(frozen=True)
class SCurve:
    """Log-logistic contrast curve y = A x^c / (x^c + k) on linear values (before sRGB encoding).

    Parameters
    ----------
    contrast : float
        Exponent c (> 0); 1 gives a gentle shoulder only, 1.2-1.6 a camera-like S-curve.
    mid_grey : float
        Linear input m kept fixed, f(m) = m (default 0.18).
    white : float
        Linear input that maps to 1 (default 1: raw clipping after exposure gain).
    """

    contrast: float = 1.4
    mid_grey: float = 0.18
    white: float = 1.0

    def __post_init__(self) -> None:
        if not (0 < self.contrast < math.inf and 0 < self.mid_grey < self.white < math.inf):
            raise LensrtError("S-curve needs contrast > 0 and 0 < mid_grey < white")

    def _coeffs(self) -> tuple[float, float]:
        c, m = self.contrast, self.mid_grey / self.white
        if abs(c - 1.0) < 1e-9:
            c = 1.0 + 1e-9
        k = m ** (c - 1) * (m - 1) / (m ** (c - 1) - 1)
        if k <= 0:
            raise LensrtError("S-curve parameters give no monotonic curve; lower the contrast or raise white")
        return k, 1.0 + k

    def __call__(self, linear: np.ndarray) -> np.ndarray:
        k, a = self._coeffs()
        x = np.clip(np.asarray(linear, dtype=np.float64) / self.white, 0.0, 1.0) ** self.contrast
        return (a * x / (x + k)).astype(np.float32)

    def inverse(self, y: np.ndarray) -> np.ndarray:
        k, a = self._coeffs()
        yy = np.clip(np.asarray(y, dtype=np.float64), 0.0, 1.0)
        return self.white * (k * yy / np.maximum(a - yy, 1e-300)) ** (1.0 / self.contrast)


def tone_curve(linear: np.ndarray, tone: str | SCurve = "srgb") -> np.ndarray:
    """Encoded output [0, 1] from linear sRGB values: ``"srgb"``, ``"linear"`` or an :class:`SCurve`."""
    if isinstance(tone, SCurve):
        return srgb_encode(tone(linear)).astype(np.float32)
    if tone == "srgb":
        return srgb_encode(linear).astype(np.float32)
    if tone == "linear":
        return np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    raise LensrtError(f"unknown tone curve {tone!r}", hint="use srgb, linear or scurve")


def inverse_tone_curve(encoded: np.ndarray, tone: str | SCurve = "srgb") -> np.ndarray:
    """Linear value that :func:`tone_curve` maps to ``encoded``."""
    if isinstance(tone, SCurve):
        return tone.inverse(srgb_decode(encoded))
    if tone == "srgb":
        return srgb_decode(encoded)
    if tone == "linear":
        return np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    raise LensrtError(f"unknown tone curve {tone!r}")


def quantize(encoded: np.ndarray, bits: int = 8) -> np.ndarray:
    """Digital output levels (DOL): round(v * (2^bits - 1)) as uint8 (8 bits) or uint16 (16 bits)."""
    if bits not in (8, 16):
        raise LensrtError(f"output bit depth {bits} must be 8 or 16")
    top = (1 << bits) - 1
    v = np.clip(np.asarray(encoded, dtype=np.float32), 0.0, 1.0) * np.float32(top) + np.float32(0.5)
    return v.astype(np.uint8 if bits == 8 else np.uint16)


def image_dynamic_range_stops(tone: str | SCurve = "srgb", bits: int = 8) -> float:
    """Image dynamic range of a tone curve (p. 70): log2 of the linear input giving the top level over
    the linear input giving DOL 1 (the smallest non-zero level)."""
    top = (1 << bits) - 1
    hi = float(inverse_tone_curve(np.array(1.0), tone))
    lo = float(inverse_tone_curve(np.array(1.0 / top), tone))
    return math.log2(hi / lo)


def histogram(values: np.ndarray, bins: int, value_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Counts and bin edges of ``values`` (any shape) over ``value_range`` (p. 69)."""
    counts, edges = np.histogram(np.asarray(values).ravel(), bins=bins, range=value_range)
    return counts, edges
