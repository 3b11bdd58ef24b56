"""Matplotlib figures of results (Agg, written to files).

Files:

- ``figure``       one Agg figure/save helper for every plot module; figures and files made by worker processes
- ``figure_worker`` the worker process that runs figure and file jobs (plot data or a pickled figure)
- ``layout``       the lens layout drawing (meridional section) with rays
- ``analysis``     compare figures: field curves, distortion, fans, spots, pupils, relative illumination
- ``psf``          PSF maps, MTF curves, convergence of the PSF
- ``convergence``  error-against-run-time figures
- ``sensor``       sensor characterisation figures
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
})
