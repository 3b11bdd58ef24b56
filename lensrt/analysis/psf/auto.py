"""``auto`` PSFs of many field points at once: every field's wavefront traced together, then the fields
that ``auto`` makes geometric in one stream launch.

:func:`auto_psfs` is :func:`lensrt.analysis.psf.map.psf_at` with ``method="auto"`` for a group of fields,
with the same results bit for bit: the wavefronts of all fields in a few batched rounds
(:func:`~lensrt.analysis.psf.diffraction.wavefront_sets`: two launches a round of the ray-grid adaptation),
the choice of :func:`~lensrt.analysis.psf.diffraction.choose_method` per field, then the geometric fields as
one group (:func:`~lensrt.analysis.psf.groups.geometric_psfs`: each field's rays seeded by its own seed, its
sums those of the field traced alone) and the diffraction fields one by one on the host. A geometric field's
metadata gains the group's keys (``group_fields``, ``group_id``, ...).
"""
from __future__ import annotations

import time
from typing import Sequence

from ...errors import LensrtError
from ..fields import FieldSpec
from .result import PsfResult
from .setup import PsfSetup

__all__ = ["auto_psfs"]


def auto_psfs(setup: PsfSetup, fields: Sequence[FieldSpec], seeds: Sequence[int], device: str | None,
              geoms: Sequence, chiefs: Sequence) -> list[PsfResult]:
    """The ``auto`` PSFs of ``fields`` (seeds one each) from their
    :func:`~lensrt.analysis.psf.geometric.prepare_fields` geometries and
    :func:`~lensrt.analysis.pupil_rays.chief_rays_at_many` entries (module docstring). A field whose
    wavefront cannot be traced raises its error, the first such field in field order."""
    from .diffraction import choose_method, diffraction_psf_at, wavefront_sets
    from .groups import geometric_psfs
    fields = list(fields)
    t0 = time.perf_counter()
    wsets = wavefront_sets(setup, list(geoms), device, list(chiefs))
    for w in wsets:
        if isinstance(w, LensrtError):
            raise w
    choices = [choose_method(setup, w) for w in wsets]
    auto_each = (time.perf_counter() - t0) / max(len(fields), 1)
    results: list[PsfResult | None] = [None] * len(fields)
    geo = [k for k, (method, _) in enumerate(choices) if method == "geometric"]
    if geo:
        got = geometric_psfs(setup, [fields[k] for k in geo], [int(seeds[k]) for k in geo], device,
                             reason=[choices[k][1] for k in geo], geoms=[geoms[k] for k in geo])
        for k, res in zip(geo, got):
            res.metadata["auto_seconds"] = auto_each
            results[k] = res
    for k, (method, reason) in enumerate(choices):
        if method != "geometric":
            results[k] = diffraction_psf_at(setup, fields[k], device, geoms[k], wsets[k], method, reason)
    return [r for r in results if r is not None]
