"""OpenEXR files through the ``OpenEXR`` package: float / half / uint channels, layers, string metadata.

Channels are 2-D arrays (rows, cols), origin top-left. Their dtype picks the EXR pixel type:
float32 -> FLOAT, float16 -> HALF, uint32 -> UINT (float64 is stored as FLOAT, other unsigned
integers as UINT; signed integers are refused). Layers follow the EXR naming convention
``layer.channel`` (``"irradiance.550nm"``, ``"rgb.R"``). Metadata are written as string
attributes (numbers with ``repr`` so they read back exactly, lists/dicts as JSON).

Spectral images (the render stage's output, the sensor stage's input) follow the spectral
OpenEXR layout of Fichet, Pacanowski & Wilkie, "An OpenEXR Layout for Spectral Images", JCGT
10(3), 2021: one channel per wavelength named ``S0.<wavelength>nm`` with a comma as the decimal
separator (``S0.550,000000nm``: the first Stokes component, i.e. unpolarised emissive data), the
attribute ``spectralLayoutVersion = "1.0"`` and the units in ``emissiveUnits``
(``"W.m^-2.nm^-1"`` for spectral irradiance); lensrt adds ``lensrt:wavelength_nm`` (JSON list)
and ``lensrt:units`` (its own unit text). Extra non-spectral channels (an RGB preview) may sit
beside them. :func:`read_spectral_exr` also reads lensrt's earlier layout
(``<layer>.<wavelength>nm``). :func:`write_spectral_exr` / :func:`read_spectral_exr`.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import LensrtError
from .paths import output_file

__all__ = ["write_exr", "read_exr", "write_image_exr", "write_spectral_exr", "read_spectral_exr",
           "spectral_channel_name", "FICHET_UNITS"]

_STANDARD = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio",
             "screenWindowCenter", "screenWindowWidth", "type"}


def _as_pixels(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 2:
        raise LensrtError(f"EXR channel {name!r} must be 2-D (rows, cols); got shape {a.shape}")
    if a.dtype in (np.float32, np.float16, np.uint32):
        return np.ascontiguousarray(a)
    if a.dtype == np.float64:
        return np.ascontiguousarray(a, dtype=np.float32)
    if a.dtype.kind == "u" or a.dtype == np.bool_:
        return np.ascontiguousarray(a, dtype=np.uint32)
    raise LensrtError(f"EXR channel {name!r}: dtype {a.dtype} has no EXR pixel type (float32, float16, uint32)")


def _attr(value: Any) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    from .table import dumps_json
    return dumps_json(value, indent=None)


def write_exr(path: str | Path, channels: Mapping[str, np.ndarray], metadata: Mapping[str, Any] | None = None,
              compression: str = "zip") -> Path:
    """Write named 2-D channels (all one size) and string metadata to an EXR file.

    Parameters
    ----------
    channels : mapping name -> array (rows, cols)
        ``"R"``, ``"layer.R"``, ...; dtype float32 / float16 / uint32 (see module docstring).
    metadata : mapping, optional
        Attribute name -> value, stored as strings.
    compression : str
        ``zip`` (lossless, default), ``piz``, ``none``.
    """
    import OpenEXR
    if not channels:
        raise LensrtError("an EXR file needs at least one channel")
    pix = {str(k): _as_pixels(str(k), v) for k, v in channels.items()}
    shapes = {v.shape for v in pix.values()}
    if len(shapes) != 1:
        raise LensrtError(f"EXR channels differ in size: {sorted(shapes)}")
    comp = {"zip": OpenEXR.ZIP_COMPRESSION, "piz": OpenEXR.PIZ_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}
    if compression not in comp:
        raise LensrtError(f"unknown EXR compression {compression!r}", hint="use zip, piz or none")
    header: dict[str, Any] = {"compression": comp[compression], "type": OpenEXR.scanlineimage}
    for k, v in (metadata or {}).items():
        if k in _STANDARD:
            raise LensrtError(f"metadata name {k!r} is reserved by EXR")
        header[str(k)] = _attr(v)
    path = output_file(path, ".exr")
    with OpenEXR.File(header, pix) as f:
        f.write(str(path))
    return path


def read_exr(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Channels (name -> 2-D array, file pixel type) and non-standard attributes of an EXR file."""
    import OpenEXR
    path = Path(path)
    if not path.is_file():
        raise LensrtError(f"no such EXR file {path}")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            chans = {k: np.array(v.pixels) for k, v in f.channels().items()}
            header = dict(f.header())
    except Exception as err:  # noqa: BLE001 - the binding raises plain exceptions
        raise LensrtError(f"cannot read EXR: {err}", path=path) from None
    meta = {k: v for k, v in header.items() if k not in _STANDARD}
    return chans, meta


def write_image_exr(path: str | Path, image: np.ndarray, names: tuple[str, ...] = ("R", "G", "B"),
                    layer: str | None = None, metadata: Mapping[str, Any] | None = None, half: bool = False) -> Path:
    """Write an image (rows, cols, C) as C channels (optionally in ``layer``), float32 or half."""
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[..., None]
    if img.shape[-1] != len(names):
        raise LensrtError(f"image has {img.shape[-1]} channels but {len(names)} names")
    dt = np.float16 if half else (img.dtype if img.dtype in (np.uint32,) else np.float32)
    prefix = f"{layer}." if layer else ""
    return write_exr(path, {prefix + n: img[..., i].astype(dt) for i, n in enumerate(names)}, metadata)


def _wl_name(w: float) -> str:
    """Old lensrt channel suffix (read only)."""
    return f"{w:g}nm"


def spectral_channel_name(wavelength_nm: float) -> str:
    """Fichet et al. (2021) emissive channel name: ``S0.550,000000nm``."""
    return "S0." + f"{float(wavelength_nm):.6f}".replace(".", ",") + "nm"


#: Fichet et al. (2021) unit strings of lensrt's unit texts
FICHET_UNITS = {"W/(m^2 nm)": "W.m^-2.nm^-1", "W/m^2": "W.m^-2", "W/(m^2 sr nm)": "W.m^-2.sr^-1.nm^-1",
                "W/(m^2 sr)": "W.m^-2.sr^-1"}


def write_spectral_exr(path: str | Path, values: np.ndarray, wavelength_nm: np.ndarray, *, layer: str = "irradiance",
                       units: str = "W/(m^2 nm)", metadata: Mapping[str, Any] | None = None,
                       extra_channels: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write a spectral image (rows, cols, n) in the Fichet et al. (2021) layout (module docstring).

    ``layer`` names what the spectra are (``lensrt:layer``); ``extra_channels``: further 2-D
    channels (e.g. ``R``, ``G``, ``B`` for viewers that do not read spectra).
    """
    v = np.asarray(values)
    wl = np.asarray(wavelength_nm, dtype=np.float64).ravel()
    if v.ndim != 3 or v.shape[-1] != wl.size:
        raise LensrtError(f"spectral image must be (rows, cols, {wl.size}); got {v.shape}")
    names = [spectral_channel_name(w) for w in wl]
    if len(set(names)) != len(names):
        raise LensrtError("wavelengths must be distinct at 1e-6 nm")
    meta = {"spectralLayoutVersion": "1.0", "emissiveUnits": FICHET_UNITS.get(units, units),
            "lensrt:wavelength_nm": [float(w) for w in wl], "lensrt:units": units, "lensrt:layer": layer,
            **(metadata or {})}
    chans = {n: v[..., i].astype(np.float32) for i, n in enumerate(names)}
    for k, a in (extra_channels or {}).items():
        if k in chans:
            raise LensrtError(f"extra channel {k!r} clashes with a spectral channel")
        chans[str(k)] = np.asarray(a, dtype=np.float32)
    return write_exr(path, chans, meta)


def _parse_fichet(name: str) -> float | None:
    """Wavelength (nm) of a Fichet emissive channel ``S0.<number><unit>`` (nm, um, m, Hz...), else None."""
    import re
    m = re.fullmatch(r"S0\.(\d*,?\d*(?:[eE][-+]?\d+)?)(Y|Z|E|P|T|G|M|k|h|da|d|c|m|u|n|p|f|a|z|y)?(m|Hz)", name)
    if m is None:
        return None
    value = float(m.group(1).replace(",", "."))
    if m.group(2) == "n" and m.group(3) == "m":
        return value
    scale = {"": 1.0, "m": 1e-3, "u": 1e-6, "n": 1e-9, "p": 1e-12, "c": 1e-2, "d": 1e-1, "k": 1e3, "M": 1e6,
             "G": 1e9, "T": 1e12, "P": 1e15}.get(m.group(2) or "", None)
    if scale is None:
        return None
    if m.group(3) == "Hz":
        return 299792458.0 / (value * scale) * 1e9
    return value * scale * 1e9


def read_spectral_exr(path: str | Path, layer: str | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Read a spectral EXR: (values (rows, cols, n), wavelength_nm (n,) increasing, metadata).

    Fichet et al. (2021) files (``S0.*`` channels, from any writer) and lensrt's earlier layout
    (``<layer>.<wavelength>nm`` with ``lensrt:wavelength_nm``) are both read.
    """
    chans, meta = read_exr(path)
    fichet = {w: k for k in chans if (w := _parse_fichet(k)) is not None}
    if fichet:
        wl = np.array(sorted(fichet), dtype=np.float64)
        return np.stack([chans[fichet[w]] for w in wl], axis=-1).astype(np.float32), wl, meta
    try:
        wl = np.asarray(json.loads(meta["lensrt:wavelength_nm"]), dtype=np.float64)
    except (KeyError, ValueError, TypeError):
        raise LensrtError("not a spectral EXR (no S0.<wavelength>nm channels, no lensrt:wavelength_nm attribute)",
                          path=path, hint="write it with lensrt.io.exr.write_spectral_exr") from None
    layer = layer or meta.get("lensrt:layer", "irradiance")
    try:
        planes = [chans[f"{layer}.{_wl_name(w)}"] for w in wl]
    except KeyError as err:
        raise LensrtError(f"spectral EXR lacks channel {err.args[0]!r}", path=path) from None
    return np.stack(planes, axis=-1).astype(np.float32), wl, meta
