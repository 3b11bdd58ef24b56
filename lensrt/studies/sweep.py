"""Sweeps over lens variants (focus distance x f-number) as a parallel job: one table row per variant.

Each variant is the loaded lens with its object distance set to the focus
distance and its aperture set to an f-number (``image_fno``: D = f/N). The
quantities are first-order (Gaussian) ones from :mod:`lensrt.paraxial` and the
Field Guide's photographic formulas; real-ray quantities (RMS spot, MTF) can
be added to :data:`QUANTITIES` once the tracer is in. The clear apertures of
the file are not checked against a faster f-number: these are paraxial numbers.

Distances: ``focus_distance_mm`` runs from the object (focus) plane to the
first vertex, like ``lensrt info --object-distance-mm``, and so do the
depth-of-field limits and the hyperfocal distance in a row: the Field Guide
measures them from the entrance pupil (p. 23-24), and a row converts them with
the entrance pupil's z (distance from the vertex = distance from the pupil - z_EP).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, Sequence

from ..errors import LensrtError
from ..parallel.work import Job, WorkItem, make_items

__all__ = ["Variant", "SweepSetup", "QUANTITIES", "DEFAULT_QUANTITIES", "variant_lens", "variant_row",
           "sweep_job", "sweep_item", "sweep_workload"]

#: name -> (unit, description); every row holds all of them
QUANTITIES: dict[str, tuple[str, str]] = {
    "efl_mm": ("mm", "effective focal length f_E = 1/Phi"),
    "f_number": ("", "f-number N = f/D (p. 30)"),
    "entrance_pupil_diameter_mm": ("mm", "entrance-pupil diameter D"),
    "magnification": ("", "paraxial lateral magnification m (negative: inverted)"),
    "image_distance_mm": ("mm", "last vertex to the paraxial image of the focus plane"),
    "extension_mm": ("mm", "unit-focus extension e = x' (p. 12)"),
    "working_f_number": ("", "working f-number Nw = (1 + |m|/mp) N (p. 31)"),
    "hyperfocal_mm": ("mm", "hyperfocal distance H (p. 24), in front of the first vertex"),
    "dof_near_mm": ("mm", "near limit of depth of field (p. 23), in front of the first vertex"),
    "dof_far_mm": ("mm", "far limit of depth of field, in front of the first vertex (inf beyond H)"),
    "dof_total_mm": ("mm", "total depth of field, far - near"),
    "afov_diagonal_deg": ("deg", "diagonal angle of view with the bellows factor (p. 17)"),
    "airy_diameter_um": ("um", "Airy disc diameter to the first zero 2.44 lambda Nw (p. 111)"),
}
DEFAULT_QUANTITIES = ("f_number", "working_f_number", "magnification", "extension_mm", "hyperfocal_mm",
                      "dof_near_mm", "dof_far_mm", "dof_total_mm", "airy_diameter_um")


@dataclass(frozen=True)
class Variant:
    """One lens variant: focus distance (object plane to first vertex, mm; inf allowed) and f-number."""

    focus_distance_mm: float
    f_number: float | None = None  # None: the lens file's own aperture


@dataclass(frozen=True)
class SweepSetup:
    """What every variant shares: the lens, the wavelength, and the sensor for DoF and AFoV."""

    lens: Any
    wavelength_nm: float | None = None
    sensor: str = "full-frame"
    coc_mm: float | None = None


def variant_lens(lens: Any, variant: Variant) -> Any:
    """The lens focused at ``variant.focus_distance_mm`` with aperture f/``variant.f_number``."""
    from ..prescription.model import Aperture
    changes: dict[str, Any] = {"object_distance_mm": float(variant.focus_distance_mm)}
    if variant.f_number is not None:
        changes["aperture"] = Aperture("image_fno", float(variant.f_number))
    return lens.replace(**changes)


def variant_row(setup: SweepSetup, variant: Variant) -> dict[str, Any]:
    """Every quantity of :data:`QUANTITIES` for one variant, plus the variant's own keys."""
    from ..paraxial import first_order
    from ..paraxial import photographic as ph
    lens = variant_lens(setup.lens, variant)
    try:
        fo = first_order(lens, setup.wavelength_nm)
        if fo.object_z_mm is not None and fo.object_z_mm >= fo.front_focal_z_mm:
            raise LensrtError(f"the focus plane lies at or behind the front focal point F "
                              f"({-fo.front_focal_z_mm:g} mm in front of the first vertex): no real image",
                              hint="sweep focus distances farther than F")
        fmt = ph.sensor_format(setup.sensor)
        c = fmt.coc_mm if setup.coc_mm is None else float(setup.coc_mm)
        focus_u = (math.inf if fo.object_distance_mm is None
                   else fo.object_distance_mm + fo.entrance_pupil_z_mm)
        dof = ph.depth_of_field_mm(focus_u, fo.front_focal_length_mm, fo.f_number, c,
                                   fo.entrance_pupil_distance_mm)
    except LensrtError as err:
        raise LensrtError(f"variant focus {variant.focus_distance_mm:g} mm, f/{variant.f_number}: {err.message}",
                          hint=err.hint) from None
    z_ep = fo.entrance_pupil_z_mm  # from the entrance pupil to "in front of the first vertex": - z_EP
    row = {
        "focus_distance_mm": float(variant.focus_distance_mm),
        "f_number_requested": variant.f_number,
        "efl_mm": fo.efl_mm,
        "f_number": fo.f_number,
        "entrance_pupil_diameter_mm": fo.entrance_pupil_diameter_mm,
        "magnification": fo.magnification,
        "image_distance_mm": fo.image_distance_mm,
        "extension_mm": fo.unit_focus_extension_mm,
        "working_f_number": fo.working_f_number,
        "hyperfocal_mm": dof.hyperfocal_mm - z_ep,
        "dof_near_mm": dof.near_mm - z_ep,
        "dof_far_mm": dof.far_mm - z_ep,
        "dof_total_mm": dof.total_mm,
        "afov_diagonal_deg": math.degrees(ph.afov_rad(fmt.diagonal_mm, fo.efl_mm, fo.bellows_factor)),
        # 2.44 lambda Nw, lambda in nm -> um
        "airy_diameter_um": 2.44 * fo.wavelength_nm * 1e-3 * fo.working_f_number,
    }
    return {k: (v if v is None else float(v)) for k, v in row.items()}


def sweep_item(item: WorkItem, setup: SweepSetup, device: str) -> dict[str, Any]:
    """``run`` of the sweep job: the row of one variant (host only; ``device`` is not used)."""
    return variant_row(setup, item.params)


def _rows(results: list) -> list:
    return results


def _check_axes(focus_distances_mm: Sequence[float], f_numbers: Sequence[float | None]) -> None:
    if not focus_distances_mm or not f_numbers:
        raise LensrtError("a sweep needs at least one focus distance and one f-number")
    for d in focus_distances_mm:
        if math.isnan(d) or d <= 0:
            raise LensrtError(f"focus distance {d:g} mm must be positive (inf for infinity)")
    for n in f_numbers:
        if n is not None and not (math.isfinite(n) and n >= 0.5):
            raise LensrtError(f"f-number {n:g} must be a finite number >= 0.5")


def sweep_job(setup: SweepSetup, focus_distances_mm: Sequence[float],
              f_numbers: Sequence[float | None] = (None,), seed: int = 0) -> Job:
    """A host-only job with one item per (focus distance, f-number), focus-major order."""
    _check_axes(focus_distances_mm, f_numbers)
    variants = [Variant(float(d), None if n is None else float(n))
                for d, n in itertools.product(focus_distances_mm, f_numbers)]
    return Job(make_items(variants, seed), sweep_item, _rows, context=setup, name="sweep", uses_device=False)


def sweep_workload(size: str, seed: int) -> Job:
    """Benchmark factory: a focus x f-number grid (``n_focus``, ``n_fnumber``) on a library ``lens``."""
    import numpy as np

    from ..loading import load_lens
    from ..parallel.workloads import parse_size
    lens = "codev_dblgauss_100mm_f2"
    p = parse_size(size, {"tiny": {"n_focus": 8, "n_fnumber": 4, "lens": lens},
                          "small": {"n_focus": 50, "n_fnumber": 20, "lens": lens},
                          "large": {"n_focus": 400, "n_fnumber": 50, "lens": lens}})
    focus = list(np.geomspace(300.0, 1e5, p["n_focus"]))
    fnum = list(np.geomspace(2.0, 22.0, p["n_fnumber"]))
    return sweep_job(SweepSetup(load_lens(p["lens"])), focus, fnum, seed)
