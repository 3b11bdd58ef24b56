"""Test targets as sensor-plane spectral irradiance: a uniform field and the ColorChecker chart.

Spectral reflectances and illuminants come from :mod:`lensrt.colour` (colour-science's
``SDS_COLOURCHECKERS`` and illuminants). A chart is returned as a table of spectra plus
a label image, the piecewise-uniform form :func:`lensrt.sensor.expose` takes with ``labels``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..colour import CHART, STANDARD_WAVELENGTHS_NM, Illuminant, colorchecker_names, colorchecker_reflectances
from ..errors import LensrtError
from .exposure import spectral_irradiance_from_illuminance

__all__ = ["ChartScene", "colorchecker_scene", "CHART"]


@dataclass
class ChartScene:
    """A chart on the sensor: ``spectra`` (k, n) W / (m^2 nm), ``labels`` (rows, cols) indices into it,
    ``wavelength_nm`` (n,), patch ``names`` and the inner ``boxes`` (row0, row1, col0, col1) of
    each patch, away from its edges, for measuring."""

    spectra: np.ndarray
    labels: np.ndarray
    wavelength_nm: np.ndarray
    names: list[str]
    boxes: list[tuple[int, int, int, int]]
    reflectance: np.ndarray


def colorchecker_scene(patch_px: int = 32, illuminant: str | Illuminant = "D65", white_illuminance_lux: float = 1000.0,
                       wavelength_nm: np.ndarray = STANDARD_WAVELENGTHS_NM, chart: str = CHART) -> ChartScene:
    """The 4 x 6 ColorChecker, each patch ``patch_px`` square, lit so that a perfect white reflector
    would give ``white_illuminance_lux`` on the sensor."""
    # each patch is measured inside a margin of max(2, patch_px // 4) photosites (demosaicing bleeds
    # across patch edges): 8 x 8 is the smallest patch that leaves a box to measure
    if patch_px < 8:
        raise LensrtError(f"ColorChecker patches of {patch_px} x {patch_px} photosites leave nothing to measure "
                          "inside their margins", hint="give --patch-px 8 or more")
    names, refl = list(colorchecker_names(chart)), colorchecker_reflectances(wavelength_nm, chart)
    white = spectral_irradiance_from_illuminance(white_illuminance_lux, illuminant, wavelength_nm)
    rows, cols = 4 * patch_px, 6 * patch_px
    r = np.arange(rows)[:, None] // patch_px
    c = np.arange(cols)[None, :] // patch_px
    labels = (r * 6 + c).astype(np.intp)
    m = max(2, patch_px // 4)
    boxes = [(i // 6 * patch_px + m, (i // 6 + 1) * patch_px - m, i % 6 * patch_px + m, (i % 6 + 1) * patch_px - m)
             for i in range(24)]
    return ChartScene(refl * white, labels, np.asarray(wavelength_nm, dtype=np.float64), names, boxes, refl)
