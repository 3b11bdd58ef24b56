"""Raw frames as EXR: the DN mosaic in one UINT channel plus the metadata needed to develop it.

Channel ``raw`` holds the mosaic (UINT for quantised frames, FLOAT for averaged or
dark-subtracted ones). String attributes: ``lensrt:cfa`` (name), ``lensrt:cfa_pattern`` (rows
of R/G/B letters separated by ``/``, from the top-left photosite), ``lensrt:black_level_dn``,
``lensrt:white_level_dn``, ``lensrt:exposure_s``, ``lensrt:iso``, ``lensrt:g_e_per_dn``,
``lensrt:n_frames`` and ``lensrt:meta`` (JSON).

DNG (optional, through pidng) is in :mod:`lensrt.io.dng`.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import LensrtError
from ..sensor.cfa import parse_cfa
from ..sensor.detector import RawFrame
from .exr import read_exr, write_exr

__all__ = ["write_raw_exr", "read_raw_exr"]


def write_raw_exr(path: str | Path, raw: RawFrame) -> Path:
    """Write ``raw`` to an EXR file (see module docstring)."""
    dn = raw.dn.astype(np.uint32) if raw.dn.dtype.kind == "u" else raw.dn.astype(np.float32)
    meta = {"lensrt:cfa": raw.cfa.name, "lensrt:cfa_pattern": raw.cfa.pattern, "lensrt:black_level_dn": raw.black_level_dn,
            "lensrt:white_level_dn": raw.white_level_dn, "lensrt:exposure_s": raw.exposure_s, "lensrt:iso": raw.iso,
            "lensrt:g_e_per_dn": raw.g_e_per_dn, "lensrt:n_frames": raw.n_frames, "lensrt:meta": raw.meta}
    return write_exr(path, {"raw": dn}, meta)


def read_raw_exr(path: str | Path) -> RawFrame:
    """Read a raw EXR written by :func:`write_raw_exr`."""
    chans, meta = read_exr(path)
    if "raw" not in chans or "lensrt:cfa_pattern" not in meta:
        raise LensrtError("not a lensrt raw EXR (needs channel 'raw' and lensrt:cfa_pattern)", path=path)
    try:
        cfa = parse_cfa(meta["lensrt:cfa"] if meta["lensrt:cfa"] in ("XTRANS",) else meta["lensrt:cfa_pattern"])
        dn = chans["raw"]
        dn = dn.astype(np.uint16) if dn.dtype == np.uint32 and dn.max(initial=0) < 65536 else dn.astype(np.float32)
        return RawFrame(dn=dn, cfa=cfa, black_level_dn=float(meta["lensrt:black_level_dn"]),
                        white_level_dn=float(meta["lensrt:white_level_dn"]), exposure_s=float(meta["lensrt:exposure_s"]),
                        iso=float(meta["lensrt:iso"]), g_e_per_dn=float(meta["lensrt:g_e_per_dn"]),
                        n_frames=int(meta.get("lensrt:n_frames", 1)), meta=json.loads(meta.get("lensrt:meta", "{}")))
    except (KeyError, ValueError) as err:
        raise LensrtError(f"raw EXR metadata is incomplete: {err}", path=path) from None
