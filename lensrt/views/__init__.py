"""What a person or another program sees of a result: tables, text, plots and result files, shared
by the command line and the report.

Files:

- ``lens``         the surface table and aperture/field descriptions of a prescription
- ``first_order``  ``lensrt info``'s data and its first-order and Seidel tables
- ``compare``      the text tables of ``lensrt compare``
- ``psf_files`` / ``bokeh_files``  result bundles (EXR + JSON + PNG)
- ``progress``     terminal progress bars
- ``plots/``       matplotlib figures (layout, compare, PSF/MTF, convergence, sensor)
"""
from __future__ import annotations

from ..core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "lens_table": "lens",
    "info_data": "first_order",
})
