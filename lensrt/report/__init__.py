"""The lens report (``lensrt report``): one HTML data sheet of a lens with the figures and data
files behind it.

:func:`build_report` runs the sections -- prescription and layout, first-order data beside real
rays, paraxial against real, spots/fans/relative illumination, PSF map, MTF, bokeh, depth of
field -- each on its own (a failing section says why and the others run on), then writes
``index.html`` (:mod:`lensrt.report.html`) and ``report.json`` into the output folder. As it
starts, :mod:`lensrt.report.kernel_plan` lists the Warp modules the sections will launch and
compiles them side by side in the background (a cold kernel cache).
"""
from __future__ import annotations

from .options import QUALITIES, Quality, ReportOptions, prepare_lens
from .run import SECTIONS, Report, build_report, section_keys

__all__ = ["build_report", "Report", "ReportOptions", "Quality", "QUALITIES", "SECTIONS", "section_keys",
           "prepare_lens"]
