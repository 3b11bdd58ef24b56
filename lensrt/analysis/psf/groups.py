"""Geometric PSFs of many field points at once: batched set-up, one stream launch, per-field analysis.

:func:`geometric_psfs` is :func:`lensrt.analysis.psf.geometric.geometric_psf_at` for a group of
fields, with the same results bit for bit:

1. set-up for all fields together -- the pupil boxes in one batched search, the real
   chief rays in one batched Newton solve, the pilot grids that size each PSF grid in
   one trace per wavelength (:func:`~lensrt.analysis.psf.geometric.prepare_fields`,
   :func:`~lensrt.analysis.psf.geometric.psf_windows`);
2. one stream launch for every field of the group with the same grid size (each
   field a source on its own histogram layer, with its own bin size, per-batch
   histograms). Each field's rays are seeded by the field's own seed and index 0
   (``StreamSource.seed``/``rng_index``), as the one-field launch seeds them, and
   the stream's sums do not depend on what else shares the launch
   (:mod:`lensrt.trace.kernels`): the histograms, counts and moment sums are those
   of the field traced alone;
3. the analysis: the passes over every field's per-batch histograms at once
   (:func:`~lensrt.analysis.psf.bulk.field_sums`), then each field's
   :func:`~lensrt.analysis.psf.geometric.finish_geometric` on those sums (vectorised over
   batches, :mod:`lensrt.analysis.psf.jackknife`).

So a PSF map is the same whether its fields run one at a time, in one group, or in
groups spread over devices and machines (:mod:`lensrt.analysis.psf.map`). Progressive
runs (a target error or time budget) stop per field, so they take the one-field path.
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Sequence

import numpy as np

from ..fields import FieldSpec
from ..grid import ImageGrid
from .result import PsfResult
from .setup import PsfSetup

__all__ = ["geometric_psfs", "GROUP_HIST_BYTES", "ANALYSIS_THREADS"]

#: per-batch histograms of one launch at most (bytes, int64 on the device): larger groups are split
GROUP_HIST_BYTES = 1 << 30
#: host threads analysing the fields of a group side by side
ANALYSIS_THREADS = 8


def geometric_psfs(setup: PsfSetup, fields: Sequence[FieldSpec], seeds: Sequence[int], device: str | None = None,
                   reason: str | Sequence[str] = "asked for", geoms: Sequence | None = None) -> list[PsfResult]:
    """Geometric PSFs of ``fields`` with ``seeds`` (one each), as many one-field runs would give them
    (module docstring). ``reason``: the method's reason, one for all or one per field; ``geoms``: the
    fields' :func:`~lensrt.analysis.psf.geometric.prepare_fields` geometries when already found."""
    from ...device import resolve_device
    from ...trace.stream import Grid, StreamSource, stream
    from .bulk import FIELDS_PER_PASS, analysis_on_device, field_sums, shape_only
    from .geometric import StreamTotals, finish_geometric, geometric_psf_at, prepare_fields, psf_windows, round_seed
    fields = list(fields)
    reasons = [reason] * len(fields) if isinstance(reason, str) else list(reason)
    if setup.progressive:
        return [geometric_psf_at(setup, f, int(s), device, None if geoms is None else geoms[k], reason=reasons[k])
                for k, (f, s) in enumerate(zip(fields, seeds))]
    t0 = time.perf_counter()
    dev = resolve_device(device)
    geoms = prepare_fields(setup, fields, dev) if geoms is None else list(geoms)
    windows = psf_windows(setup, geoms, dev)
    setup_each = (time.perf_counter() - t0) / max(len(fields), 1)
    spectrum = setup.spectrum.trace_spectrum()
    B = int(setup.batches)
    n_rays = max(B, (int(setup.rays) // B) * B)
    results: list[PsfResult | None] = [None] * len(fields)
    on_device = analysis_on_device(dev)
    for pixels in sorted({w[1] for w in windows}):
        members = [k for k, w in enumerate(windows) if w[1] == pixels]
        per_field = 8 * B * pixels * pixels
        size = max(1, GROUP_HIST_BYTES // per_field)
        for g0 in range(0, len(members), size):
            part = members[g0:g0 + size]
            sources, grids = [], []
            for j, k in enumerate(part):
                pitch_um = windows[k][0]
                grid = ImageGrid.centred((pixels, pixels), pitch_um, geoms[k].reference_mm)
                grids.append(grid)
                sources.append(StreamSource(geoms[k].fp, geoms[k].box, setup.plane_z_mm, geoms[k].reference_mm, j,
                                            "lambertian", seed=round_seed(int(seeds[k]), 0), rng_index=0,
                                            pixel_mm=grid.pitch_mm))
            res = stream(setup.lens, sources, Grid(pixels, pixels, grids[0].pitch_mm), n_rays, spectrum=spectrum,
                         sampler=setup.sampler, batches=B, precision=setup.precision, device=dev,
                         batch_histograms="device" if on_device else True)
            share = 1.0 / len(part)
            t_an = time.perf_counter()
            extra = {"group_fields": len(part), "group_trace_seconds": float(res.seconds),
                     "group_kernel_seconds": float(res.extra.get("kernel_seconds", res.seconds)),
                     "analysis_device": dev if on_device else "host"}
            dsums = _device_sums(res, part, grids, geoms, setup, dev) if on_device else None

            def analyse(js: range, res=res, part=part, grids=grids, extra=extra, dsums=dsums) -> None:
                # a run of fields: their totals (histograms stacked; a run's stack, not the group's, so
                # that its memory is reused and stays in cache), the passes over all of them at once
                # (bulk.field_sums; made on the device for the whole group when dsums), then each field's
                # estimates from those sums
                if dsums is not None:
                    tots = [StreamTotals(shape_only(B, pixels, pixels), np.zeros((B, 6)), np.zeros(B)) for _ in js]
                    for i, j in enumerate(js):
                        tots[i].add(res, j, share)
                    sums = dsums[js.start:js.stop]
                else:
                    stack = np.zeros((len(js), B, pixels, pixels))
                    tots = [StreamTotals(stack[i], np.zeros((B, 6)), np.zeros(B)) for i in range(len(js))]
                    for i, j in enumerate(js):
                        tots[i].add(res, j, share)
                    sums = field_sums(stack, np.stack([t.off_grid for t in tots]), grids[js.start:js.stop],
                                      [geoms[part[j]].reference_mm for j in js], setup)
                for i, j in enumerate(js):
                    k = part[j]
                    results[k] = finish_geometric(setup, fields[k], int(seeds[k]), geoms[k], grids[j], windows[k][2],
                                                  tots[i], None, setup_each + tots[i].trace_seconds, reasons[k],
                                                  dict(extra), sums[i])

            # runs of fields analysed side by side (NumPy releases the GIL in its loops); each field's
            # numbers do not depend on the threads or on the other fields of its run. With the device's sums
            # what is left is small arrays and Python (B values per field), which holds the GIL: threads
            # only contend for it there (twice the host seconds of one thread, measured on the CPU)
            runs = [range(a, min(a + FIELDS_PER_PASS, len(part))) for a in range(0, len(part), FIELDS_PER_PASS)]
            workers = 1 if dsums is not None else min(ANALYSIS_THREADS, len(runs), os.cpu_count() or 1)
            if workers > 1:
                with ThreadPoolExecutor(workers) as pool:
                    list(pool.map(analyse, runs))
            else:
                for js in runs:
                    analyse(js)
            # wall-clock times of the group (the per-field times above overlap in threads)
            group = {"group_id": f"{int(seeds[part[0]])}:{len(part)}",
                     "group_setup_seconds": setup_each * len(part),
                     "group_analysis_seconds": time.perf_counter() - t_an}
            for k in part:
                results[k].metadata.update(group)
    return [r for r in results if r is not None]


def _device_sums(res, part: list[int], grids: list[ImageGrid], geoms: Sequence, setup: PsfSetup, dev: str) -> list:
    """The group's :class:`~lensrt.analysis.psf.bulk.FieldSums`, made where its histograms are
    (:func:`~lensrt.analysis.psf.device_sums.device_field_sums`)."""
    from .device_sums import DeviceHistograms, device_field_sums
    d = res.extra["device_histograms"]
    layers, hb, chan, ny, nx = d["shape"]
    dh = DeviceHistograms(d["array"], res.extra["layers_of_sources"], hb, chan, ny, nx, d["unit"], dev)
    off = np.stack([res.off_grid_weight(j) for j in range(len(part))])
    return device_field_sums(dh, range(len(part)), off, grids, [geoms[k].reference_mm for k in part], setup)
