"""Error against run time: every Monte Carlo quantity measured at growing sample counts, samplers and
precisions, against a reference (``lensrt converge``, ``lensrt psf --converge``).

Files:

- ``study``       converge(): the runs, references, log-log slopes
- ``quantities``  the quantities studied: PSF RMS radius, MTF, relative illumination, bokeh region
- ``render``      the render's error against run time
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "converge": "study",
    "Reference": "study",
    "converge_psf": "quantities",
})
