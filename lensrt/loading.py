"""Load a lens ready for use: read the file, check the aperture, compute missing clear apertures, check geometry.

Every path into a usable :class:`Lens` (the TOML, Zemax, CODE V and pbrt readers, and a ``Lens``
built in Python and passed to :func:`load_lens`) goes through :func:`complete_lens`, so the physical
checks run once, here and in the model's own ``__post_init__`` checks (docs/guide/validation.md).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .errors import PrescriptionError, located
from .prescription.configurations import MultiConfigLens, single_configuration
from .prescription.formats import read_any
from .prescription.model import Lens
from .prescription.validate import check_geometry
from .paraxial.aperture_check import check_aperture, paraxial_image_distance_mm
from .paraxial.crossing import axial_beam_heights, check_axial_beam_crossing
from .prescription.formats import emit_load_warnings
from .library import resolve_lens_path

__all__ = ["load_lens", "complete_lens", "load_configurations"]


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
        lens = _checked_geometry(lens)
        check_axial_beam_crossing(lens)
    lens.check_wavelengths(lens.wavelengths.nm)  # warns where a glass's formula is extrapolated
    return lens


def _checked_geometry(lens: Lens) -> Lens:
    """:func:`check_geometry` with the axial beam's heights and the paraxial image distance (a virtual image may
    lie in front of the last surface); its edge warnings are emitted and kept."""
    try:
        heights = axial_beam_heights(lens)
    except PrescriptionError:
        heights = None  # no first-order data (afocal, ...): every crossing at the semi-diameters is an error
    if heights is not None and not np.isfinite(heights).all():
        heights = None
    found = check_geometry(lens, beam_heights_mm=heights, image_distance_mm=paraxial_image_distance_mm(lens))
    if not found:
        return lens
    emit_load_warnings(lens.path, found)
    return lens.replace(warnings=tuple(lens.warnings) + tuple(found))


def load_lens(source: str | Path | Lens | None = None, config: int | str | None = None, **options: Any) -> Lens:
    """A complete :class:`Lens` from a file path, a library name, or ``None`` (the default lens).

    ``config`` picks a configuration of a multi-configuration file (a name or a
    1-based number; default the file's current one). ``options`` go to the format
    reader (see :func:`lensrt.prescription.formats.read_lens`).
    """
    if isinstance(source, Lens):
        return complete_lens(source)
    family = load_configurations(source, **options)
    return family.configuration(config) if config is not None or family.count > 1 else family.base


def load_configurations(source: str | Path | Lens | MultiConfigLens | None = None,
                        **options: Any) -> MultiConfigLens:
    """Every configuration of a lens file, complete (a plain lens file gives one).

    Clear semi-diameters the file does not give are computed in every
    configuration and the largest is kept for all of them (a zoom's elements
    have one size), except the aperture stop's: it is an iris, which opens to
    the radius each configuration's aperture (f-number, EPD, NA) implies, so it
    becomes a per-configuration semi-diameter (otherwise a constant-f-number
    zoom would pass a wider beam than its f-number wherever its stop beam is
    smaller than the largest one). The geometry of every configuration is then
    checked.
    """
    if isinstance(source, MultiConfigLens):
        found: Lens | MultiConfigLens = source
    elif isinstance(source, Lens):
        found = source
    else:
        found = read_any(resolve_lens_path(source), **options)
    if isinstance(found, Lens):
        return single_configuration(complete_lens(found))
    return _complete_family(found)


def _stop_follows_aperture(family: MultiConfigLens, done: list[Lens]) -> MultiConfigLens:
    """The stop's computed semi-diameter per configuration (an operand), where the file gives none for it
    and every configuration has the same stop surface (see :func:`load_configurations`)."""
    from dataclasses import replace
    from .prescription.configurations import ConfigOperand
    k = done[0].stop_index
    given = family.base.surfaces[k].semi_diameter_mm is not None and not family.base.surfaces[k].semi_diameter_auto
    if given or any(c.stop_index != k for c in done) or \
            any(op.kind == "semi_diameter" and op.index == k for op in family.operands):
        return family
    radii = tuple(float(c.surfaces[k].semi_diameter_mm) for c in done)
    if len(set(radii)) == 1:
        return family
    op = ConfigOperand("semi_diameter", k, radii, source=f"stop S{k + 1} (the aperture's radius)")
    return replace(family, operands=family.operands + (op,))


def _complete_family(family: MultiConfigLens) -> MultiConfigLens:
    from dataclasses import replace
    done = [complete_lens(c) for c in family.configurations()]
    base = family.base
    surfaces = list(base.surfaces)
    for i, s in enumerate(surfaces):
        if s.semi_diameter_mm is None:
            sd = max(c.surfaces[i].semi_diameter_mm or 0.0 for c in done)
            surfaces[i] = replace(s, semi_diameter_mm=sd, semi_diameter_auto=True)
    notes = tuple((k, v) for k, v in done[family.current].notes if k != "configuration")
    completed = family.with_base(base.replace(surfaces=tuple(surfaces), notes=notes))
    completed = _stop_follows_aperture(completed, done)
    with located(base.path):
        for lens in completed.configurations():
            _checked_geometry(lens)
    return completed
