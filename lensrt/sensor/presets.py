"""Three real-looking sensors: full frame, APS-C and a phone.

These are *representative* sensors, not any one manufacturer's datasheet: the numbers are
rounded typical values of each class as published in photon-transfer measurements of
consumer cameras (full-well capacity, read noise at base ISO and at high ISO, QE, ISO-less
gain: e.g. the sensorgen.info / photonstophotos.net style tables, and the Field Guide's own
examples on p. 42-51) and in sensor vendors' product briefs for 1.4 um phone sensors. Each
parameter carries a ``sources`` note saying which kind of number it is. Two things are
modelling choices rather than measurements and are said so:

* colour-science ships only two camera spectral-sensitivity sets (Nikon D5100, NPL; Sigma
  SD Merrill, a stacked Foveon sensor). All three presets use the Nikon D5100 curves (which
  already include that camera's IR-cut filter and CFA), scaled by per-channel peak QE; the
  phone sensor's real curves differ.
* the bias (black level) offsets are chosen so that dark noise is never clipped at 0.
"""
from __future__ import annotations

from dataclasses import fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..errors import LensrtError
from .cfa import CFA, parse_cfa
from .model import Sensor
from .spectral import CAMERA_DATASETS, SpectralResponse, camera_response, load_response

__all__ = ["PRESETS", "get_preset", "preset_names", "sensor_from_spec"]

_COMMON_SOURCES = {
    "response": "colour-science MSDS_CAMERA_SENSITIVITIES['Nikon 5100 (NPL)'] (relative, includes the IR-cut "
                "filter and CFA); the only Bayer camera set colour-science ships",
    "seed": "arbitrary; fixes the DSNU/PRNU/dark-current maps",
}


def _fullframe() -> Sensor:
    return Sensor(
        name="fullframe_24mp", description="24 MP 36x24 mm CMOS, class of 2014-2018 24 MP full-frame cameras",
        rows=4000, cols=6000, pixel_pitch_um=6.0, fill_factor=0.9,
        response=camera_response("nikon_d5100"), peak_qe=(0.45, 0.55, 0.45), cfa=parse_cfa("RGGB"),
        full_well_e=80000.0, dark_current_e_per_s=0.5, dark_current_nonuniformity=0.4,
        read_noise_upstream_e=1.8, read_noise_downstream_e=5.5, dsnu_e=1.0, prnu=0.006,
        conversion_gain_uv_per_e=12.5, adc_gain_dn_per_mv=16.0, base_iso=100, iso_less_iso=800,
        max_iso=51200, adc_bits=14, bias_dn=512, seed=1,
        sources={**_COMMON_SOURCES,
                 "pixel_pitch_um": "36 mm / 6000 photosites", "fill_factor": "effective FF with gapless microlenses, typical",
                 "peak_qe": "typical PTC-measured peak QE ~50 % (green) for this class, times 1/FF",
                 "full_well_e": "typical published saturation for ~6 um photosites (75-90 ke-)",
                 "read_noise_upstream_e": "typical high-ISO read noise of this class (~2 e-)",
                 "read_noise_downstream_e": "chosen so base-ISO read noise is ~6 e-, typical of this class",
                 "dark_current_e_per_s": "typical room-temperature dark current of large-pixel CMOS (0.1-1 e-/s)",
                 "dsnu_e": "typical DSNU of modern CMOS (~1 e-)", "prnu": "typical PRNU 0.5-1 %",
                 "conversion_gain_uv_per_e": "typical CG of 6 um pixels (10-20 uV/e-)",
                 "adc_gain_dn_per_mv": "chosen with CG for g = 5 e-/DN at base ISO (full well ~ ADC range)",
                 "base_iso": "nominal", "iso_less_iso": "typical ISO-less point of this class (ISO 400-800)",
                 "adc_bits": "14-bit raw, typical", "bias_dn": "512 DN, as several makers use in 14-bit raw"})


def _apsc() -> Sensor:
    return Sensor(
        name="apsc_16mp", description="16 MP APS-C CMOS (23.6x15.6 mm), Nikon D5100 class",
        rows=3264, cols=4928, pixel_pitch_um=4.78, fill_factor=0.9,
        response=camera_response("nikon_d5100"), peak_qe=(0.40, 0.48, 0.40), cfa=parse_cfa("RGGB"),
        full_well_e=45000.0, dark_current_e_per_s=0.5, dark_current_nonuniformity=0.4,
        read_noise_upstream_e=1.6, read_noise_downstream_e=2.5, dsnu_e=0.8, prnu=0.007,
        conversion_gain_uv_per_e=25.0, adc_gain_dn_per_mv=14.0, base_iso=100, iso_less_iso=400,
        max_iso=25600, adc_bits=14, bias_dn=256, seed=2,
        sources={**_COMMON_SOURCES,
                 "pixel_pitch_um": "4928 x 3264 photosites on 23.6 x 15.6 mm", "fill_factor": "effective, typical",
                 "peak_qe": "typical PTC-measured peak QE ~43 % (green) for this class, times 1/FF",
                 "full_well_e": "typical published saturation for ~4.8 um photosites (~45 ke-)",
                 "read_noise_upstream_e": "typical high-ISO read noise of this class (~1.5 e-)",
                 "read_noise_downstream_e": "chosen so base-ISO read noise is ~3 e-, typical of this near-ISO-less class",
                 "dark_current_e_per_s": "typical room-temperature dark current (0.1-1 e-/s)",
                 "dsnu_e": "typical", "prnu": "typical 0.5-1 %",
                 "conversion_gain_uv_per_e": "typical CG of ~5 um pixels", "adc_gain_dn_per_mv": "chosen for g ~ 2.9 e-/DN",
                 "base_iso": "nominal", "iso_less_iso": "typical for this sensor class (ISO 200-400)",
                 "adc_bits": "14-bit raw", "bias_dn": "model choice (the camera clips at 0, lensrt keeps the noise)"})


def _phone() -> Sensor:
    return Sensor(
        name="phone_12mp", description="12 MP 1/2.55-inch BSI CMOS, 1.4 um photosites (phone main camera class)",
        rows=3024, cols=4032, pixel_pitch_um=1.4, fill_factor=1.0,
        response=camera_response("nikon_d5100"), peak_qe=(0.60, 0.72, 0.62), cfa=parse_cfa("RGGB"),
        full_well_e=6000.0, dark_current_e_per_s=5.0, dark_current_nonuniformity=0.5,
        read_noise_upstream_e=1.2, read_noise_downstream_e=2.0, dsnu_e=0.5, prnu=0.01,
        conversion_gain_uv_per_e=80.0, adc_gain_dn_per_mv=2.0, base_iso=50, iso_less_iso=400,
        max_iso=6400, adc_bits=10, bias_dn=64, seed=3,
        sources={**_COMMON_SOURCES,
                 "response": _COMMON_SOURCES["response"] + " -- a stand-in: phone CFAs differ",
                 "pixel_pitch_um": "1.4 um, common 12 MP phone main sensors", "fill_factor": "BSI with microlenses, ~1",
                 "peak_qe": "typical BSI peak QE 65-75 % (vendor briefs)",
                 "full_well_e": "typical 1.4 um BSI full well (4.5-6.5 ke-)",
                 "read_noise_upstream_e": "typical 1-1.5 e- at high gain", "read_noise_downstream_e": "~2 e- at base, typical",
                 "dark_current_e_per_s": "typical at 50-60 C die temperature (a few e-/s)",
                 "dsnu_e": "typical", "prnu": "typical ~1 %",
                 "conversion_gain_uv_per_e": "typical CG of small pixels (50-100 uV/e-)",
                 "adc_gain_dn_per_mv": "chosen for g ~ 6.25 e-/DN (full well ~ 10-bit range)",
                 "base_iso": "nominal ISO 50 of such phone sensors", "iso_less_iso": "typical",
                 "adc_bits": "10-bit RAW10 (MIPI)", "bias_dn": "64 DN, the usual RAW10 black level"})


_FACTORIES = {"fullframe_24mp": _fullframe, "apsc_16mp": _apsc, "phone_12mp": _phone}
#: preset names, in table order
PRESETS = tuple(_FACTORIES)


def preset_names() -> tuple[str, ...]:
    return PRESETS


@lru_cache(maxsize=None)
def get_preset(name: str) -> Sensor:
    """The preset sensor called ``name`` (see :data:`PRESETS`)."""
    key = name.strip().lower().replace("-", "_")
    if key not in _FACTORIES:
        raise LensrtError(f"unknown sensor preset {name!r}", hint=f"use one of {', '.join(PRESETS)}")
    return _FACTORIES[key]()


_SPEC_KEYS = {f.name for f in fields(Sensor)} - {"sources"}


def sensor_from_spec(spec: dict[str, Any] | None = None, *, path: str | None = None) -> Sensor:
    """A sensor from a preset name plus overrides, as a scene file's ``[sensor]`` table gives it.

    Parameters
    ----------
    spec : dict
        ``{"preset": "fullframe_24mp", ...overrides}``; keys are :class:`Sensor` field names.
        ``cfa`` is a pattern string, ``response`` a camera dataset name
        (``nikon_d5100``) or a CSV/JSON path, ``peak_qe`` a list of three numbers. ``iso`` is
        not a sensor property and is refused here (it belongs to the exposure).
    path : str, optional
        File the spec came from, for error messages.
    """
    spec = dict(spec or {})
    base = get_preset(spec.pop("preset", "fullframe_24mp"))
    unknown = set(spec) - _SPEC_KEYS
    if unknown:
        raise LensrtError(f"unknown sensor key(s) {sorted(unknown)}", path=path,
                          hint=f"known keys: preset, {', '.join(sorted(_SPEC_KEYS))}")
    if "cfa" in spec and not isinstance(spec["cfa"], CFA):
        spec["cfa"] = parse_cfa(str(spec["cfa"]))
    if "response" in spec and not isinstance(spec["response"], SpectralResponse):
        r = str(spec["response"])
        spec["response"] = camera_response(r) if r in CAMERA_DATASETS else load_response(
            Path(path).parent / r if path and not Path(r).is_absolute() else r)
    if "peak_qe" in spec:
        pq = spec["peak_qe"]
        spec["peak_qe"] = tuple(float(v) for v in (pq if isinstance(pq, (list, tuple)) else [pq] * 3))
    try:
        return replace(base, **spec, sources={**base.sources, **{k: "user" for k in spec}})
    except TypeError as err:
        raise LensrtError(f"bad sensor value: {err}", path=path,
                          hint="numeric keys take numbers, e.g. full_well_e=45000") from None
