"""Studies that run other stages many times: convergence (error against run time) and sweeps.

- ``convergence/``  error against run time of PSF, MTF, relative illumination, bokeh and render quantities
- ``sweep``         a lens or setting swept over values, as a parallel Job
"""
from __future__ import annotations

from ..core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "sweep_workload": "sweep",
})
