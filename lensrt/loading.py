"""Load a lens ready for use: read the file, check the aperture, compute missing clear apertures, check geometry.

Every path into a usable :class:`Lens` (the TOML, Zemax, CODE V and pbrt readers, and a ``Lens``
built in Python and passed to :func:`load_lens`) goes through :func:`complete_lens`, so the physical
checks run once, here and in the model's own ``__post_init__`` checks (docs/guide/validation.md).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .errors import located
from .prescription.formats import read_lens
from .prescription.model import Lens
from .prescription.validate import check_geometry
from .paraxial.aperture_check import check_aperture
from .paraxial.crossing import check_axial_beam_crossing
from .library import resolve_lens_path

__all__ = ["load_lens", "complete_lens"]


def complete_lens(lens: Lens) -> Lens:
    """Fill clear semi-diameters the file did not give, then check the geometry.

    Missing semi-diameters are computed as OpticStudio's automatic mode does:
    the largest height at which the real chief and marginal rays of the
    aperture and field specification cross each surface
    (:func:`lensrt.trace.apertures.compute_clear_apertures`, float64 reference
    tracer on the host -- no kernel is compiled), with the paraxial estimate as
    the fallback where real rays fail; the method used is recorded in
    ``lens.meta["clear_apertures"]``. The lens's wavelengths are checked against its
    glasses' measured ranges (:meth:`Lens.check_wavelengths`: an ExtrapolationWarning each).
    """
    with located(lens.path):
        check_aperture(lens)  # an f-number below 0.5 (epd = 1e9): before any ray is traced
        if any(s.semi_diameter_mm is None for s in lens.surfaces):
            from .trace.apertures import compute_clear_apertures
            lens = compute_clear_apertures(lens)
        check_geometry(lens)
        check_axial_beam_crossing(lens)
    lens.check_wavelengths(lens.wavelengths.nm)  # warns where a glass's formula is extrapolated
    return lens


def load_lens(source: str | Path | Lens | None = None, **options: Any) -> Lens:
    """A complete :class:`Lens` from a file path, a library name, or ``None`` (the default lens).

    ``options`` go to the format reader (see :func:`lensrt.prescription.formats.read_lens`).
    """
    if isinstance(source, Lens):
        return complete_lens(source)
    path = resolve_lens_path(source)
    return complete_lens(read_lens(path, **options))
