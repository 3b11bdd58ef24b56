"""Wavefront error of field points: RMS/PV, Strehl and Zernikes (:mod:`lensrt.analysis.wave.metrics`) for the
fields, wavelengths and focus of a PSF set-up (``lensrt wavefront``, and RMS WFE and Strehl against field in
the report)."""
from __future__ import annotations

import time
from typing import Sequence

from ...errors import LensrtError
from ..fields import FieldSpec
from ..wave.metrics import WavefrontMetrics, wavefront_metrics
from ..pupil_rays import chief_rays_at_many
from .diffraction import WavefrontSet, wavefront_chief_wavelengths, wavefront_sets
from .geometric import FieldGeometry, prepare_field, prepare_fields
from .setup import PsfSetup

__all__ = ["wavefront_error", "wavefront_error_table"]


def wavefront_error(setup: PsfSetup, f: FieldSpec, *, reference: str = "chief", n_terms: int = 37,
                    device: str | None = None, geom: FieldGeometry | None = None, chief=None,
                    wset: WavefrontSet | None = None) -> list[WavefrontMetrics]:
    """The wavefront metrics of field ``f`` at each wavelength of the set-up's spectrum (its lines), at the
    set-up's focus plane; the ray grid adapted to the interpolation goal as for diffraction PSFs.
    ``geom``, ``chief``: the field's :func:`~lensrt.analysis.psf.geometric.prepare_fields` geometry and
    :func:`~lensrt.analysis.pupil_rays.chief_rays_at_many` entry, ``wset`` its traced wavefronts, when already
    found."""
    t0 = time.perf_counter()
    if wset is None:
        geom = prepare_field(setup, f, device) if geom is None else geom
        wset = WavefrontSet(setup, geom, device, chief)
    out = []
    for wf in wset.wavefronts:
        m = wavefront_metrics(wf, reference=reference, n_terms=n_terms, pupil_samples=int(setup.pupil_samples))
        m.extra.update({"field": f.to_dict(), "focus": setup.focus["focus"], "plane_z_mm": setup.plane_z_mm,
                        "reference_sphere": wset.sphere.to_dict(), "ray_grid": wset.ray_grid,
                        "ray_interp_error_waves": wset.interp_error_waves})
        out.append(m)
    for m in out:
        m.extra["seconds"] = time.perf_counter() - t0
    return out


def wavefront_error_table(setup: PsfSetup, fields: Sequence[FieldSpec], *, reference: str = "chief",
                          device: str | None = None) -> list[dict]:
    """RMS WFE (no tilt) and Strehl against field at the primary wavelength: one dict per field that could be
    traced (a field that cannot is listed with its reason)."""
    rows = []
    fields = list(fields)
    try:  # the pupil boxes and chief rays of every field in one batched search, the wavefronts' chief rays in another
        geoms = prepare_fields(setup, fields, device)
        chiefs = chief_rays_at_many(setup.lens, [g.fp for g in geoms], wavefront_chief_wavelengths(setup),
                                    setup.plane_z_mm, device)
    except LensrtError:  # some field cannot be traced: each field on its own, to say which
        geoms, chiefs = [None] * len(fields), [None] * len(fields)
    # every field's wavefront in a few batched rounds (two launches a round of the ray-grid adaptation)
    known = bool(fields) and geoms[0] is not None
    wsets = wavefront_sets(setup, geoms, device, chiefs) if known else [None] * len(fields)
    for f, geom, chief, wset in zip(fields, geoms, chiefs, wsets):
        try:
            if isinstance(wset, LensrtError):
                raise wset
            ms = wavefront_error(setup, f, reference=reference, n_terms=4, device=device, geom=geom, chief=chief,
                                 wset=wset)
        except LensrtError as err:
            rows.append({"field": f.label, "error": str(err)})
            continue
        m = min(ms, key=lambda x: abs(x.wavelength_nm - setup.spectrum.primary_nm))
        rows.append({"field": f.label, "hy": f.hy, "wavelength_nm": m.wavelength_nm, "rms_waves": m.rms_waves,
                     "rms_waves_no_tilt": m.rms_waves_no_tilt, "pv_waves": m.pv_waves, "strehl": m.strehl,
                     "strehl_marechal": m.strehl_marechal})
    return rows
