"""Files of a simulation, and the sensor + ISP stages for a sensor preset.

For a prefix ``P``: ``P.exr`` (linear sRGB ``R``, ``G``, ``B`` of the relative
sensor irradiance -- white on the axis in focus = 1 -- and ``Y_stderr``, the PSF
Monte Carlo standard error of Y), ``P.png`` (8-bit sRGB of the same, unscaled:
the input's exposure), ``P.json`` (the sidecar: camera, layers, PSF grid, timing,
every error estimate). With a sensor preset: ``P_raw.exr`` (the raw mosaic after
:func:`lensrt.sensor.expose`) and ``P_camera.png`` (raw conversion by
:mod:`lensrt.isp`), with ``P_raw.json`` / ``P_camera.json`` sidecars (the same
errors plus the sensor settings).

Absolute light for the sensor: the input's white (1, 1, 1) is a Lambertian
reflectance-1 surface under D65 of luminance ``white_cd_m2``; spectral radiance
L(l) = k D65(l) sum_c B_c(l) c, with k from 683 lm/W integral k D65 V dl =
``white_cd_m2``; irradiance = L x the on-axis gain (sr) x the relative image.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LensrtError
from .pipeline import Simulation
from .spectral import spectral_basis

__all__ = ["write_outputs", "spectral_irradiance", "sensor_stage", "SENSOR_WAVELENGTHS_NM"]

#: wavelengths of the irradiance handed to the sensor stage (nm; 10 nm bins)
SENSOR_WAVELENGTHS_NM = np.arange(385.0, 780.0, 10.0)


def spectral_irradiance(sim: Simulation, white_cd_m2: float) -> tuple[np.ndarray, np.ndarray]:
    """(E (H, W, n) in W / (m^2 nm), wavelength_nm (n,)) of the simulated image (module docstring)."""
    from ..colour import illuminance_lux
    wl = SENSOR_WAVELENGTHS_NM
    band, basis = spectral_basis(sim.bands, wl)  # (n,), (n, 3) D65 x B_c, relative
    white = basis.sum(axis=1)
    k = float(white_cd_m2) / float(illuminance_lux(white, wl))  # radiance scale: white -> white_cd_m2
    gain = k * sim.reference_gain_sr
    e = np.einsum("hwnc,nc->hwn", sim.coefficients[band].transpose(1, 2, 0, 3), basis) * gain
    return np.maximum(e, 0.0).astype(np.float32), wl


def sensor_stage(sim: Simulation, preset: str, iso: float | None, exposure_s: float | None,
                 white_cd_m2: float, seed: int = 0, noise: bool = True) -> tuple[Any, Any, dict]:
    """(raw frame, developed ISP result, settings): each image pixel is one photosite of the preset."""
    from ..isp import Isp, IspSettings, exposure_gain_for_iso
    from ..sensor import Switches, expose, sensor_from_spec
    from ..sensor.exposure import metered_exposure_time_s
    rows, cols = sim.camera.shape
    sensor = sensor_from_spec({"preset": preset, "rows": rows, "cols": cols})
    iso_v = float(iso) if iso is not None else float(sensor.base_iso)
    if exposure_s is None:
        n_w = float(np.sqrt(np.pi / (4.0 * sim.reference_gain_sr)))  # the working f-number of the real on-axis gain
        exposure_s = metered_exposure_time_s(0.18 * white_cd_m2, n_w, iso_v)  # metered on 18 % grey
    if not exposure_s > 0:
        raise LensrtError(f"exposure {exposure_s!r} s must be positive")
    e, wl = spectral_irradiance(sim, white_cd_m2)
    switches = Switches() if noise else Switches.noiseless(quantize=True)
    raw = expose(sensor, e, wl, float(exposure_s), rng=np.random.default_rng(seed), iso=iso_v,
                 bin_width_nm=np.full(wl.size, 10.0), switches=switches, meta={"source": "lensrt simulate"})
    isp = Isp(sensor, IspSettings(illuminant="D65", demosaic="malvar2004"))
    isp = isp.with_settings(exposure_gain=exposure_gain_for_iso(isp, iso_v))
    return raw, isp.develop(raw), {"preset": preset, "iso": iso_v, "exposure_s": float(exposure_s),
                                   "white_cd_m2": float(white_cd_m2), "noise": bool(noise)}


def _sidecar(path: Path, sim: Simulation, files: dict, extra: dict | None = None) -> str:
    from ..io.table import dumps_json
    data = sim.to_dict()
    data["files"] = dict(files)
    if extra:
        data.update(extra)
    path.write_text(dumps_json(data, indent=1) + "\n", encoding="utf-8")
    return str(path)


def write_outputs(sim: Simulation, prefix: str | Path, *, preset: str | None = None, iso: float | None = None,
                  exposure_s: float | None = None, white_cd_m2: float = 100.0, seed: int = 0,
                  noise: bool = True) -> dict[str, str]:
    """Write the files of the module docstring; returns kind -> path."""
    from ..io.exr import write_exr
    from ..io.png import write_png
    from ..colour import srgb_encode
    prefix = Path(prefix)
    if prefix.suffix.lower() in (".exr", ".png", ".json"):
        prefix = prefix.with_suffix("")
    files: dict[str, str] = {}
    meta = {"lensrt:simulate": json.dumps(sim.camera.to_dict()), "lensrt:units":
            "linear sRGB of the relative sensor irradiance (white on the axis in focus = 1)",
            "lensrt:orientation": "upright (row 0 = top of the scene)"}
    try:
        prefix.parent.mkdir(parents=True, exist_ok=True)
        ch = {"R": sim.rgb[..., 0], "G": sim.rgb[..., 1], "B": sim.rgb[..., 2], "Y_stderr": sim.y_stderr}
        files["exr"] = str(write_exr(prefix.with_suffix(".exr"), ch, meta))
        files["png"] = str(write_png(prefix.with_suffix(".png"), srgb_encode(sim.rgb), 8, {"Software": "lensrt simulate"}))
        files["json"] = _sidecar(prefix.with_suffix(".json"), sim, files)
        if preset is not None:
            from ..io.raw import write_raw_exr
            raw, dev, settings = sensor_stage(sim, preset, iso, exposure_s, white_cd_m2, seed, noise)
            raw_path = Path(str(prefix) + "_raw.exr")
            files["raw"] = str(write_raw_exr(raw_path, raw))
            files["raw_json"] = _sidecar(raw_path.with_suffix(".json"), sim, files, {"sensor": settings})
            cam_path = Path(str(prefix) + "_camera.png")
            files["camera_png"] = str(write_png(cam_path, dev.to_uint8(), 8, {"Software": "lensrt simulate"}))
            files["camera_json"] = _sidecar(cam_path.with_suffix(".json"), sim, files, {"sensor": settings})
    except OSError as err:
        raise LensrtError(f"cannot write the simulation's files at {prefix}: {err}") from None
    return files
