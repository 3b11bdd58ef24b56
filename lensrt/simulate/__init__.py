"""Image simulation: a photograph (and its depth map) through a real lens onto the sensor.

Stage: beside :mod:`lensrt.analysis` and :mod:`lensrt.render`; it uses the analysis
stage's real-ray tools (chief-ray placement, pupil boxes, the stream kernel), the
sensor and ISP stages and :mod:`lensrt.io`; only the CLI imports it.
"""
from __future__ import annotations

__all__: list[str] = []
