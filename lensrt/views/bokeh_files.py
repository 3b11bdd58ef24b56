"""Bokeh images on disk: an sRGB PNG for people, a linear XYZ EXR with metadata, a JSON summary.

Colour (colour-science via :mod:`lensrt.colour`): the image's CIE 1931
XYZ (Y = sensor illuminance in lux) is scaled by an exposure, turned into
linear sRGB by the IEC 61966-2-1 matrix (D65 white, no adaptation: a D65 source
is neutral), clipped to [0, 1] (out-of-gamut colours lose their negative
components) and encoded with the sRGB transfer function. The automatic
exposure puts the 99.5th percentile of the lit pixels' Y at white.

EXR layers: ``XYZ.X``, ``XYZ.Y``, ``XYZ.Z`` (lux, float32) and
``noise.Y_rel_stderr`` (per-pixel relative standard error of Y); the picture is
upright (the sensor image turned by 180 degrees). Attributes (strings; numbers
as repr, structures as JSON): ``lensrt:kind`` = ``bokeh``, lens, focus, light,
iris, rays, seed, seconds, noise, sources, frame.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from ..colour import srgb_encode8, xyz_to_linear_srgb

__all__ = ["xyz_to_srgb8", "auto_exposure", "write_bokeh_files", "read_bokeh_exr"]


def auto_exposure(y: np.ndarray, percentile: float = 99.5) -> float:
    """Multiplier that puts the ``percentile`` of the positive values of ``y`` at 1 (1 if none)."""
    lit = np.asarray(y)[np.asarray(y) > 0]
    if lit.size == 0:
        return 1.0
    top = float(np.percentile(lit, percentile))
    return 1.0 / top if top > 0 else 1.0


def xyz_to_srgb8(xyz: np.ndarray, exposure: float | None = None) -> tuple[np.ndarray, float]:
    """(rows, cols, 3) XYZ -> (uint8 sRGB image, the exposure multiplier used)."""
    k = auto_exposure(xyz[..., 1]) if exposure is None else float(exposure)
    rgb = xyz_to_linear_srgb(np.asarray(xyz, dtype=np.float64) * k)
    return srgb_encode8(rgb), k


def _meta(image: Any, exposure: float) -> dict[str, Any]:
    d = image.to_dict()
    s = d["settings"]
    return {"lensrt:kind": "bokeh", "lensrt:lens": s["lens"] or "", "lensrt:focus": s["focus"],
            "lensrt:light": s["light"], "lensrt:iris": s["iris"], "lensrt:intensity_cd": s["intensity_cd"],
            "lensrt:rays": int(d["rays"]), "lensrt:rays_per_source": s["rays_per_source"],
            "lensrt:seed": int(d["seed"]), "lensrt:seconds": float(d["seconds"]), "lensrt:noise": d["noise"],
            "lensrt:sampler": s["sampler"], "lensrt:precision": s["precision"], "lensrt:frame": d["frame"],
            "lensrt:units": s["units"], "lensrt:png_exposure": exposure,
            "lensrt:sources": [{k: r.get(k) for k in ("kind", "depth_mm", "object_mm", "target_mm", "field_deg",
                                                       "transmission", "centroid_mm", "rms_radius_mm", "noise",
                                                       "rays") if k in r} for r in d["sources"]]}


def write_bokeh_files(image: Any, out_dir: str | Path, name: str = "bokeh", exposure: float | None = None,
                      json_summary: bool = True) -> dict[str, Path]:
    """Write ``<name>.png`` (sRGB, 8 bit), ``<name>.exr`` (linear XYZ + noise) and ``<name>.json``.

    ``image`` is a :class:`lensrt.analysis.bokeh.entry.BokehImage`. Returns the paths by kind. Inside
    :func:`lensrt.views.plots.figure.deferred_figures` (the report) the files are written by figure
    worker processes from the arrays made here.
    """
    from ..io.exr import write_exr
    from ..io.paths import output_file
    from ..io.png import write_png
    from ..io.table import write_json
    from .plots.figure import defer
    out = Path(out_dir)
    pic = image.picture()
    rgb8, k = xyz_to_srgb8(pic, exposure)
    meta = _meta(image, k)
    text = {"Software": "lensrt bokeh", "lensrt:lens": str(meta["lensrt:lens"]),
            "lensrt:focus": json.dumps(meta["lensrt:focus"]), "lensrt:rays": str(meta["lensrt:rays"]),
            "lensrt:seconds": f"{meta['lensrt:seconds']:.4g}", "lensrt:noise": json.dumps(meta["lensrt:noise"]),
            "lensrt:seed": str(meta["lensrt:seed"]), "lensrt:exposure": repr(k),
            "lensrt:orientation": "upright (sensor image turned by 180 deg)"}
    paths = {"png": output_file(out / f"{name}.png", ".png")}
    defer(write_png, paths["png"], rgb8, 8, text)
    rel = image.picture_rel_stderr().astype(np.float32)
    chans = {"XYZ.X": pic[..., 0].astype(np.float32), "XYZ.Y": pic[..., 1].astype(np.float32),
             "XYZ.Z": pic[..., 2].astype(np.float32), "noise.Y_rel_stderr": rel}
    paths["exr"] = output_file(out / f"{name}.exr", ".exr")
    defer(write_exr, paths["exr"], chans, meta)
    if json_summary:
        p = out / f"{name}.json"
        d = image.to_dict()
        d["files"] = {"png": str(paths["png"]), "exr": str(paths["exr"])}
        d["png_exposure"] = k
        defer(write_json, p, d)
        paths["json"] = p
    return paths


def read_bokeh_exr(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """(XYZ (rows, cols, 3), relative stderr of Y (rows, cols), metadata with JSON values decoded)."""
    from ..io.exr import read_exr
    chans, meta = read_exr(path)
    xyz = np.stack([chans["XYZ.X"], chans["XYZ.Y"], chans["XYZ.Z"]], axis=-1)
    out = {}
    for key, v in meta.items():
        try:
            out[key] = json.loads(v) if isinstance(v, str) else v
        except ValueError:
            out[key] = v
    return xyz, chans["noise.Y_rel_stderr"], out
