"""What a user asks of a loaded lens, computed from real rays (and compared with the Gaussian picture).

Wings (sub-packages), each with a face that lists its files:

- ``compare``  paraxial against real: focal lengths, best focus, field curves, distortion, real pupils,
  vignetting and relative illumination, ray fans and spot diagrams (``lensrt compare``)
- ``wave``     physical optics of the pupil: pupil grids and Zernike fits, wavefronts (OPD), FFT/MFT/Huygens
  propagation
- ``psf``      PSFs of real rays (geometric and diffraction), their statistics with standard errors, MTF,
  PSF maps over the field (``lensrt psf``, ``lensrt mtf``)
- ``bokeh``    defocused point sources through the real lens: one spot, maps over the frame, measurements
  (``lensrt bokeh``)

Shared files at this level:

- ``grid``        ImageGrid: the image-plane pixel grid a sampled PSF lives on
- ``fields``      field points for maps (named fields, sensor positions mapped through the real chief ray)
- ``raysets``     field points named by object-space value, aimed ray batches, chief and close rays
- ``pupil_rays``  deterministic ray grids over a field point's real pupil, chief rays for PSF set-up
- ``parabasal``   first-order data from real rays about the central field's chief ray (decentred lenses)
"""
from __future__ import annotations

from ..core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "ImageGrid": "grid",
    "FieldSpec": "fields",
    "lens_fields": "fields",
    "sensor_grid_fields": "fields",
    "parabasal_first_order": "parabasal",
    "ParabasalFirstOrder": "parabasal",
})
