"""Paraxial against real: the Gaussian picture of a lens beside real ray traces (``lensrt compare``).

Files:

- ``comparison``  compare_lens: every table of ``lensrt compare`` in one Comparison; lateral colour
- ``focus``       real focal lengths, longitudinal aberration, best focus, axial colour, field curvature
- ``distortion``  distortion curves (paraxial and CODE V definitions) and grid distortion
- ``pupils``      real entrance/exit pupils and the pupil outline seen from a field point
- ``vignetting``  unvignetted fraction and relative illumination against cos^4
- ``aberrations`` ray fans, spot diagrams, OPD to the reference sphere
- ``afocal``      spots in angle space of an afocal lens (exit angles against the angular magnification)
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "Comparison": "comparison",
    "compare_lens": "comparison",
    "best_focus": "focus",
    "real_focal_length": "focus",
    "real_focal_lengths": "focus",
    "distortion_curve": "distortion",
    "real_pupils": "pupils",
    "pupil_outline": "pupils",
    "vignetting": "vignetting",
    "relative_illumination_at": "vignetting",
    "ray_fan": "aberrations",
    "spot_diagrams": "aberrations",
    "AngularSpot": "afocal",
    "angular_spots": "afocal",
})
