"""Per-configuration first-order and real data of a zoom / multi-focus lens (``lensrt info --config all``)."""
from __future__ import annotations

import math

import numpy as np

from ..errors import LensrtError
from ..prescription.configurations import MultiConfigLens

__all__ = ["CONFIG_COLUMNS", "configuration_rows", "zoom_ratio"]

#: (key, header) of each column of :func:`configuration_rows`
CONFIG_COLUMNS = (
    ("name", "config"), ("efl_mm", "EFL mm"), ("f_number", "f/#"), ("working_f_number", "Nw"),
    ("entrance_pupil_z_mm", "EP z"), ("entrance_pupil_diameter_mm", "EP diam"), ("exit_pupil_z_mm", "XP z"),
    ("exit_pupil_diameter_mm", "XP diam"), ("full_field_deg", "full field deg"),
    ("paraxial_image_height_mm", "image h mm"), ("distortion_percent", "dist %"),
    ("object_distance_mm", "object mm"),
)


def configuration_rows(family: MultiConfigLens, wavelength_nm: float | None = None) -> list[dict]:
    """One dict per configuration: first-order data, the full field and the real distortion at it.

    ``full_field_deg`` is twice the largest field angle (the lens's fields; for
    height fields, twice the paraxial chief-ray slope); ``distortion_percent`` the
    real chief ray's distortion at the largest field (paraxial definition,
    :mod:`lensrt.analysis.distortion`), NaN where the chief ray fails.
    """
    from ..paraxial import first_order
    from .compare.distortion import distortion_curve
    rows = []
    for i, lens in enumerate(family.configurations()):
        fo = first_order(lens, wavelength_nm)
        try:
            dist = float(distortion_curve(lens, [1.0], wavelength_nm).distortion_percent[0])
        except LensrtError:  # a chief ray that cannot be aimed: no value, not a failure
            dist = math.nan
        rows.append({
            "name": family.names[i], "efl_mm": fo.efl_mm, "f_number": fo.f_number,
            "working_f_number": fo.working_f_number, "entrance_pupil_z_mm": fo.entrance_pupil_z_mm,
            "entrance_pupil_diameter_mm": fo.entrance_pupil_diameter_mm, "exit_pupil_z_mm": fo.exit_pupil_z_mm,
            "exit_pupil_diameter_mm": fo.exit_pupil_diameter_mm, "full_field_deg": 2.0 * fo.half_field_deg,
            "paraxial_image_height_mm": fo.paraxial_image_height_mm, "distortion_percent": dist,
            "object_distance_mm": lens.object_distance_mm, "current": i == family.current,
        })
    return rows


def zoom_ratio(rows: list[dict]) -> float:
    """Longest over shortest EFL of the configurations."""
    efl = np.array([abs(r["efl_mm"]) for r in rows])
    return float(efl.max() / efl.min())
