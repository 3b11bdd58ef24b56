"""Physical optics of the pupil: the wavefront of real rays and its propagation to a PSF.

Files:

- ``pupil_grid``   pupil coordinates, aperture shapes (circular, iris, vignetted), Zernike polynomials and fits,
  scattered real-ray data resampled onto a pupil grid
- ``point_location`` which triangle of the rays' triangulation holds each query point (a bucket grid)
- ``ray_mesh``     triangles of rays traced on a regular grid (two a cell) and linear interpolation on them
- ``wavefront``    reference spheres, OPD of real rays, the pupil function of a field point
- ``propagation``  pupil function -> PSF by FFT, matrix Fourier transform or Huygens sum; through-focus PSFs
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "PupilFunction": "propagation",
    "psf_fft": "propagation",
    "psf_mft": "propagation",
    "psf_huygens": "propagation",
    "trace_wavefronts": "wavefront",
    "reference_sphere": "wavefront",
    "fit_zernike": "pupil_grid",
    "zernike": "pupil_grid",
})
