"""lensrt: a GPU-parallel, spectral, Monte Carlo raytracer for real camera lenses.

The public face: the entry points of every stage, imported on first use (``import lensrt`` stays cheap, so
``lensrt --help`` starts without NumPy or Warp):

- ``load_lens``, ``Lens``                 a prescription from a file (TOML, Zemax, CODE V, pbrt) or the library
- ``trace``, ``RayBatch``, ``stream``     real rays through the lens (Warp kernels; store and stream modes)
- ``compare_lens``                        the Gaussian picture beside real rays
- ``run_psf_map``, ``psf_at``, ``mtf_curves``   PSFs and MTFs of real rays
- ``bokeh_spot``, ``bokeh_map``           defocused point sources through the lens
- ``load_scene``, ``render``              a scene onto the sensor plane
- ``expose``, ``Isp``                     the sensor and the raw conversion
- ``LensrtError``, ``PrescriptionError``  the one error type a user sees
"""
from __future__ import annotations

from .core.lazy import lazy_face

__version__ = "0.1.0"

__getattr__, _names = lazy_face(__name__, {
    "LensrtError": "errors",
    "PrescriptionError": "errors",
    "load_lens": "loading",
    "Lens": "prescription.model",
    "trace": "trace.api",
    "RayBatch": "trace.api",
    "stream": "trace.stream",
    "compare_lens": "analysis.compare.comparison",
    "run_psf_map": "analysis.psf.map",
    "psf_at": "analysis.psf.map",
    "mtf_curves": "analysis.psf.mtf_curves",
    "bokeh_spot": "analysis.bokeh.entry",
    "bokeh_map": "analysis.bokeh.entry",
    "load_scene": "render.scene.load",
    "render": "render.integrator",
    "expose": "sensor.detector",
    "Isp": "isp.pipeline",
})
__all__ = ["__version__"] + _names
