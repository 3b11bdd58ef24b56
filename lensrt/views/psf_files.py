"""PSF maps on disk: one multi-layer EXR (one layer per field point), a JSON summary, a PNG mosaic.

EXR layout (read back with :func:`lensrt.io.exr.read_exr` or :func:`read_psf_map_exr`):

* one layer per field point, named ``r<row>c<col>`` for a sensor grid (row 0 at the
  top, +y) or ``f<index>`` for a list of fields, each with the channel ``psf`` --
  the PSF in 1/mm^2, normalised to unit volume (Field Guide p. 111), float32,
  rows top-down (+y up) -- and, for Monte Carlo PSFs, ``stderr`` (its per-pixel
  standard error, batch means);
* string attributes (JSON where structured): ``lensrt:kind`` = ``psf-map``,
  ``lensrt:lens``, ``lensrt:wavelength_nm``, ``lensrt:weights``,
  ``lensrt:spectrum``, ``lensrt:grid`` ("9x9" or "list"), ``lensrt:sensor``,
  ``lensrt:layers`` (names in field order), ``lensrt:pitch_um`` (per layer),
  ``lensrt:pixel_pitch_um`` (when all layers share it), ``lensrt:rays`` (per
  layer), ``lensrt:seed`` (the job seed; each field's seed is in ``lensrt:fields``),
  ``lensrt:focus``, ``lensrt:method``, ``lensrt:units`` and ``lensrt:fields``: per
  field its sensor target, reference point (the real chief ray's landing point,
  the centre of the layer), grid origin, field (normalised and in the lens's
  units), method, rays, seconds, seed and the estimates with standard errors.

Every layer has the same size (PSFs on smaller grids are padded with zeros about their
centre); each layer's pitch and the position of its top-left pixel centre
(``grid_x0_mm``, ``grid_y0_mm``) are in the metadata.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LensrtError
from ..io.paths import output_dir

__all__ = ["layer_names", "write_psf_map_exr", "psf_map_exr_content", "read_psf_map_exr", "field_summary",
           "write_psf_outputs"]


def layer_names(pmap) -> list[str]:
    """``r<row>c<col>`` for grid fields, else ``f<index>``."""
    out = []
    for i, f in enumerate(pmap.fields):
        out.append(f"r{f.grid_index[0]}c{f.grid_index[1]}" if f.grid_index is not None else f"f{i}")
    return out


def field_summary(f, r, name: str) -> dict:
    """The per-field record of the EXR metadata and the printed table."""
    est = {k: {"value": e.to_dict()["value"], "stderr": e.to_dict()["stderr"]} for k, e in r.estimates.items()}
    return {"layer": name, "label": f.label, "hx": f.hx, "hy": f.hy, "field_xy": list(r.field_xy),
            "field_kind": r.field_kind, "target_mm": None if f.target_mm is None else list(f.target_mm),
            "reference_mm": list(r.reference_mm), "pitch_um": r.grid.pitch_um,
            "grid_x0_mm": r.grid.x0_mm, "grid_y0_mm": r.grid.y0_mm, "kind": r.kind,
            "method_reason": r.metadata.get("method_reason", ""), "rays": r.samples, "seconds": r.seconds,
            "seed": r.seed, "batches": r.batches, "energy_on_grid": r.energy_on_grid, "estimates": est}


def write_psf_map_exr(path: str | Path, pmap) -> Path:
    """Write a :class:`~lensrt.analysis.psf.map.PsfMap` as one multi-layer EXR (module docstring)."""
    from ..io.exr import write_exr
    return write_exr(path, *psf_map_exr_content(pmap))


def psf_map_exr_content(pmap) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The channels (layer.channel -> float32 image) and metadata of :func:`write_psf_map_exr`."""
    names = layer_names(pmap)
    rows = max(r.psf.shape[0] for r in pmap.results)
    cols = max(r.psf.shape[1] for r in pmap.results)
    channels: dict[str, np.ndarray] = {}
    origins = []
    for name, r in zip(names, pmap.results):
        # smaller PSFs are padded with zeros about their centre to the largest size (the origin moves)
        top, left = (rows - r.psf.shape[0]) // 2, (cols - r.psf.shape[1]) // 2
        pad = ((top, rows - r.psf.shape[0] - top), (left, cols - r.psf.shape[1] - left))
        channels[f"{name}.psf"] = np.pad(np.asarray(r.psf, dtype=np.float32), pad)
        if r.psf_stderr is not None:
            channels[f"{name}.stderr"] = np.pad(np.asarray(r.psf_stderr, dtype=np.float32), pad)
        origins.append((r.grid.x0_mm - left * r.grid.pitch_mm, r.grid.y0_mm + top * r.grid.pitch_mm))
    spec = pmap.setup.spectrum
    pitches = [r.grid.pitch_um for r in pmap.results]
    meta: dict[str, Any] = {
        "lensrt:kind": "psf-map", "lensrt:lens": pmap.setup.lens.name or "",
        "lensrt:wavelength_nm": list(spec.lines_nm), "lensrt:weights": list(spec.line_weights),
        "lensrt:spectrum": spec.to_dict(),
        "lensrt:grid": f"{pmap.grid_shape[0]}x{pmap.grid_shape[1]}" if pmap.grid_shape else "list",
        "lensrt:sensor": pmap.sensor or "", "lensrt:layers": names, "lensrt:pitch_um": pitches,
        "lensrt:rays": [r.samples for r in pmap.results], "lensrt:seed": int(pmap.seed),
        "lensrt:focus": pmap.setup.focus, "lensrt:method": pmap.setup.method,
        "lensrt:sampler": pmap.setup.sampler, "lensrt:precision": pmap.setup.precision,
        "lensrt:units": "1/mm^2, each layer normalised to unit volume (Field Guide p. 111); stderr: 1 sigma",
        "lensrt:fields": [field_summary(f, r, n) for f, r, n in zip(pmap.fields, pmap.results, names)],
    }
    for rec, (x0, y0) in zip(meta["lensrt:fields"], origins):
        rec["grid_x0_mm"], rec["grid_y0_mm"] = float(x0), float(y0)
    if len(set(pitches)) == 1:
        meta["lensrt:pixel_pitch_um"] = pitches[0]
    return channels, meta


def read_psf_map_exr(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """(layer name -> PSF (rows, cols) float32, metadata with JSON attributes decoded)."""
    from ..io.exr import read_exr
    chans, meta = read_exr(path)
    if meta.get("lensrt:kind") != "psf-map":
        raise LensrtError("not a lensrt PSF map (no lensrt:kind = psf-map attribute)", path=path)
    out = dict(meta)
    for k, v in meta.items():
        if k.startswith("lensrt:") and isinstance(v, str) and v[:1] in "[{":
            try:
                out[k] = json.loads(v)
            except ValueError:
                pass
    for k, conv in (("lensrt:seed", int), ("lensrt:pixel_pitch_um", float)):
        if k in out:
            out[k] = conv(out[k])
    psfs = {name: chans[f"{name}.psf"] for name in out["lensrt:layers"]}
    return psfs, out


def write_psf_outputs(out_dir: str | Path, pmap, stem: str = "psf", log: bool = False) -> dict[str, str]:
    """JSON summary, multi-layer EXR and PNG (mosaic, or one PSF image) of a map into ``out_dir``.

    Inside :func:`lensrt.views.plots.figure.deferred_figures` (the report) the three files are written
    by figure worker processes from the data pickled here."""
    from .plots.figure import defer
    from .plots.psf import plot_psf, plot_psf_mosaic
    from ..io.exr import write_exr
    from ..io.table import write_json
    d = output_dir(out_dir)
    paths = {"json": d / f"{stem}.json", "exr": d / f"{stem}.exr", "png": d / f"{stem}.png"}
    defer(write_json, paths["json"], pmap.to_dict())
    defer(write_exr, paths["exr"], *psf_map_exr_content(pmap))
    lens = pmap.setup.lens.name or "lens"
    if len(pmap.results) == 1:
        plot_psf(paths["png"], pmap.results[0], log=log, title=f"{lens}, {pmap.fields[0].label}")
    else:
        n = len(pmap.results)
        ncols = pmap.grid_shape[1] if pmap.grid_shape else (n if n <= 6 else None)
        plot_psf_mosaic(paths["png"], pmap.results, ncols=ncols, log=log,
                        title=f"{lens}\n{pmap.results[0].kind} PSFs" + (f" over {pmap.sensor}" if pmap.sensor else "")
                        + (", log10 of each peak" if log else ", each tile peak-normalised"))
    return {k: str(v) for k, v in paths.items()}
