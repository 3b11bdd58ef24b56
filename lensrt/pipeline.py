"""Render outputs: spectral EXR, preview PNG, JSON summary, and the sensor stage + raw conversion.

Files for an output prefix ``P`` (images upright, see :class:`lensrt.render.camera.SensorGrid`):

* ``P.exr`` -- sensor-plane spectral irradiance in the spectral OpenEXR layout of Fichet et al.
  (2021) (``S0.<nm>nm`` channels, W.m^-2.nm^-1, or W.m^-2 for a line), plus ``R``, ``G``, ``B``
  (linear sRGB of the XYZ, Y in lux, for ordinary viewers) and ``Y_stderr`` (per-pixel standard
  error of Y, lux);
* ``P.png`` -- an 8-bit sRGB preview of the ideal sensor (XYZ -> sRGB, exposed so that the 99th
  percentile of Y is white; a grey image for one-wavelength renders);
* ``P.json`` -- the render summary: samples, seconds, standard errors per region, error against
  run time per pass, the plan, the camera;
* with a ``[sensor] preset``: ``P_raw.exr`` (the raw mosaic, :mod:`lensrt.io.raw`) and
  ``P_camera.png`` (raw conversion to sRGB with the ISO's SOS exposure gain, white balance for
  the scene's illuminant), exposed with the scene's ``exposure_s`` and ``iso``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .colour import Illuminant, cie_illuminant, srgb_encode, xyz_to_linear_srgb
from .errors import LensrtError

__all__ = ["write_outputs", "preview_rgb", "sensor_stage", "isp_illuminant"]


def preview_rgb(result) -> np.ndarray:
    """Display-referred sRGB (rows, cols, 3) in [0, 1] of a render's ideal-sensor image."""
    if not result.plan.spectral:
        e = result.irradiance[..., 0].astype(np.float64)
        hi = float(np.percentile(e, 99)) if e.size else 0.0
        hi = hi if hi > 0 else (float(e.max()) or 1.0)
        g = srgb_encode(e / hi)
        return np.repeat(g[..., None], 3, axis=2)
    y = result.xyz[..., 1]
    hi = float(np.percentile(y, 99)) if y.size else 0.0
    hi = hi if hi > 0 else (float(y.max()) or 1.0)
    return srgb_encode(xyz_to_linear_srgb(result.xyz / hi))


def isp_illuminant(scene) -> Illuminant:
    """The adopted white for raw conversion: the scene's uniform illumination, as the
    :class:`~lensrt.colour.Illuminant` the scene file named (CIE table, Planck, daylight or a table),
    when it is continuous; else D65."""
    s = scene.illumination
    if s is not None and s.illuminant is not None and s.illuminant.continuous:
        return s.illuminant
    return cie_illuminant("D65")


def sensor_stage(result, scene, seed: int = 0) -> tuple[Any, Any, Any]:
    """Expose the scene's sensor preset to the rendered irradiance and develop it: (sensor, raw, isp_result).

    Each rendered pixel is exposed as one photosite of the preset (its pitch, fill factor, full well
    and noise): the render is a resampled view of the sensor, and a photosite sees the irradiance
    at its place.
    """
    from .isp import Isp, IspSettings, exposure_gain_for_iso
    from .sensor import Switches, expose, sensor_from_spec
    plan = result.plan
    sen = scene.sensor
    rows, cols = result.shape
    sensor = sensor_from_spec({"preset": plan.sensor_preset, "rows": rows, "cols": cols})
    iso = float(sen.iso) if sen.iso is not None else float(sensor.base_iso)
    E = result.irradiance
    wl = result.wavelength_nm
    bw = result.band_width_nm
    if not plan.spectral:             # one wavelength: a 1 nm band holding the whole irradiance
        bw = 1.0
    switches = Switches() if sen.noise else Switches.noiseless(quantize=True)
    raw = expose(sensor, E, wl, scene.camera.exposure_s, rng=np.random.default_rng(seed), iso=iso,
                 bin_width_nm=np.full(wl.size, bw), switches=switches,
                 meta={"scene": scene.name, "render_samples_per_pixel": result.samples_per_pixel})
    isp = Isp(sensor, IspSettings(illuminant=isp_illuminant(scene), demosaic="malvar2004"))
    isp = isp.with_settings(exposure_gain=exposure_gain_for_iso(isp, iso))
    return sensor, raw, isp.develop(raw)


def write_outputs(result, scene, prefix: str | Path, *, seed: int = 0, sensor: bool = True) -> dict[str, str]:
    """Write the files of the module docstring for ``result``; returns kind -> path."""
    from .io.exr import write_spectral_exr
    from .io.png import write_png
    from .io.table import dumps_json
    prefix = Path(prefix)
    if prefix.suffix.lower() in (".exr", ".png", ".json"):
        prefix = prefix.with_suffix("")
    files: dict[str, str] = {}
    rgb_lin = xyz_to_linear_srgb(result.xyz)
    meta = {"lensrt:scene": scene.name, "lensrt:samples_per_pixel": int(result.samples_per_pixel),
            "lensrt:seconds": float(result.seconds), "lensrt:band_width_nm": float(result.band_width_nm),
            "lensrt:bin_width_nm": float(result.band_width_nm if result.plan.spectral else 1.0),
            "lensrt:orientation": "upright (row 0 = top of the scene)", "lensrt:camera": result.camera.to_dict(),
            "lensrt:xyz": "R,G,B = linear sRGB (D65) of CIE 1931 XYZ, Y = illuminance in lux"}
    extra = {"R": rgb_lin[..., 0], "G": rgb_lin[..., 1], "B": rgb_lin[..., 2],
             "Y_stderr": np.nan_to_num(result.xyz_stderr[..., 1], posinf=0.0)}
    try:
        files["exr"] = str(write_spectral_exr(prefix.with_suffix(".exr"), result.irradiance, result.wavelength_nm,
                                              units=result.unit, metadata=meta, extra_channels=extra))
        files["png"] = str(write_png(prefix.with_suffix(".png"), preview_rgb(result), 8,
                                     {"Software": "lensrt", "Comment": f"ideal-sensor preview of {scene.name}"}))
        if sensor and result.plan.sensor_stage:
            from .io.raw import write_raw_exr
            _, raw, dev = sensor_stage(result, scene, seed)
            files["raw"] = str(write_raw_exr(Path(str(prefix) + "_raw.exr"), raw))
            files["camera_png"] = str(write_png(Path(str(prefix) + "_camera.png"), dev.to_uint8(), 8,
                                                {"Software": "lensrt", "Comment": f"{scene.name} through the sensor"}))
        summary = result.summary()
        summary["files"] = dict(files)
        path = prefix.with_suffix(".json")
        path.write_text(dumps_json(summary, indent=1) + "\n", encoding="utf-8")
        files["json"] = str(path)
    except OSError as err:
        raise LensrtError(f"cannot write render output {prefix}: {err}") from None
    return files
