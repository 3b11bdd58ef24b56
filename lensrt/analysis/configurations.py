"""Per-configuration first-order and real data of a zoom / multi-focus lens (``lensrt info --config all``)."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.configurations import MultiConfigLens

__all__ = ["CONFIG_COLUMNS", "MTF_FIELDS", "configuration_mtf", "configuration_rows", "mtf_table", "zoom_ratio"]

#: normalised field points (Hy) of the per-configuration MTF: the axis, 70 % and the full field
MTF_FIELDS = (0.0, 0.7, 1.0)

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


def configuration_mtf(family: MultiConfigLens, freqs_cpmm: Sequence[float], fields: Sequence[float] = MTF_FIELDS,
                      rays: int = 20_000, device: str | None = None, seed: int = 0,
                      precision: str = "float64") -> list[dict]:
    """Geometric sagittal/tangential MTF at ``freqs_cpmm`` (cycles/mm) per configuration and field.

    Each configuration is analysed as the plain lens it is (its own fields, aperture,
    wavelengths): the geometric PSF of ``rays`` Monte Carlo rays per normalised field
    point Hy in ``fields`` (:func:`lensrt.analysis.psf.psf_at`, the lens's spectrum),
    observed at the real best focus of the axial point
    (:func:`lensrt.analysis.psf.focus.focus_plane`), or on the file's image surface where
    that search fails (``focus`` says which). The PSF grid is chosen as in the report's
    MTF section (pitch capped so that its Nyquist frequency passes the highest frequency,
    the window sized to the traced light): where the traced light spreads too far for a
    grid that fine (e.g. the RF 15-35's stray ring of axial rays through its aspheric
    front, docs/guide/zoom.md), the frequencies it cannot resolve are NaN. One dict per
    configuration: ``name``,
    ``focus``, ``fields`` (Hy), ``freqs_cpmm``, ``sagittal``/``tangential`` and their
    standard errors (arrays field x frequency; NaN where a field fails), ``rays`` (per
    field point asked), ``samples`` and ``seconds`` (rays traced and time, all fields).
    """
    from .fields import normalised_fields
    from .psf.focus import focus_plane
    from .psf.map import psf_at
    from .psf.setup import make_setup
    freqs = tuple(float(v) for v in freqs_cpmm)
    out = []
    for i, lens in enumerate(family.configurations()):
        try:
            foc, where = focus_plane(lens, "best", device), "best"
        except LensrtError:  # the axial best-focus search fails (e.g. a very wide field): the image surface
            foc, where = focus_plane(lens, "image", device), "image"
        setup = make_setup(lens, None, foc, device, method="geometric", rays=rays, precision=precision,
                           mtf_freqs_cpmm=freqs, max_pitch_um=0.45e3 / max(freqs))
        vals = np.full((4, len(fields), len(freqs)), np.nan)
        samples, seconds = 0, 0.0
        for j, f in enumerate(normalised_fields(fields)):
            try:
                res = psf_at(setup, f, seed + j, device)
            except LensrtError:  # no light reaches the plane from this field: NaN, not a failure
                continue
            samples, seconds = samples + int(res.samples), seconds + float(res.seconds)
            for k, key in enumerate(("mtf_sagittal", "mtf_tangential")):
                e = res.estimates.get(key)
                if e is not None:
                    v, se = np.atleast_1d(e.value), np.atleast_1d(e.stderr)
                    vals[k, j, :v.size], vals[k + 2, j, :se.size] = v, se
        out.append({"name": family.names[i], "focus": where, "focus_z_mm": float(foc["z_mm"]),
                    "fields": list(fields), "freqs_cpmm": list(freqs), "rays": rays, "samples": samples,
                    "seconds": seconds,
                    "sagittal": vals[0], "tangential": vals[1], "sagittal_stderr": vals[2],
                    "tangential_stderr": vals[3], "current": i == family.current})
    return out


def mtf_table(mtf: list[dict]) -> tuple[list[list], list[str]]:
    """Rows (configuration, field, focus, then "S/T" per frequency) and headings of
    :func:`configuration_mtf`'s result."""
    freqs = mtf[0]["freqs_cpmm"] if mtf else []
    rows = []
    for m in mtf:
        s, t = np.asarray(m["sagittal"], dtype=float), np.asarray(m["tangential"], dtype=float)
        for j, hy in enumerate(m["fields"]):
            cells = [f"{s[j, k]:.3f} / {t[j, k]:.3f}" for k in range(len(freqs))]
            rows.append([m["name"] + (" *" if m["current"] else ""), f"Hy {hy:g}", m["focus"]] + cells)
    return rows, ["config", "field", "focus"] + [f"S/T {v:.3g}" for v in freqs]
