"""PSFs of real rays and their transfer functions (``lensrt psf``, ``lensrt mtf``).

Files:

- ``result``      PsfResult: the PSF, its grid, estimates with standard errors; ray histograms
- ``setup``       what all PSFs of a run share (spectrum, focus plane, method, sampling, stopping)
- ``spectrum``    the spectrum a PSF integrates: file wavelengths, lines or a spectral power distribution
- ``focus``       the observation plane: image, paraxial or best focus, with an offset
- ``geometric``   one field point's geometric PSF from the stream kernel
- ``groups``      many field points' geometric PSFs in one launch
- ``bulk``        the passes over many fields' per-batch histograms at once (a map's analysis)
- ``device_sums`` the same passes as Warp kernels where the histograms are (a map's analysis on a GPU)
- ``diffraction`` the diffraction PSF from the real-ray pupil function, and the method choice
- ``auto``        many field points' ``auto`` PSFs: wavefronts traced together, geometric fields in one launch
- ``energy``      encircled/ensquared energy, centroid and moments of a sampled PSF
- ``jackknife``   jackknife standard errors of the PSF statistics, vectorised over batches
- ``otf``         MTF of a sampled PSF, diffraction limit, detector and OLPF MTFs
- ``mtf_curves``  MTF against frequency, field and focus with detector and OLPF
- ``map``         PSF maps over the field as a parallel Job
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "PsfResult": "result",
    "PsfSetup": "setup",
    "make_setup": "setup",
    "geometric_psf_at": "geometric",
    "geometric_psfs": "groups",
    "diffraction_psf_at": "diffraction",
    "PsfMap": "map",
    "psf_at": "map",
    "run_psf_map": "map",
    "diffraction_mtf": "otf",
    "encircled_energy": "energy",
})
