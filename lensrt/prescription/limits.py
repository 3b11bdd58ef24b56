"""Bounds the readers check while parsing: aspheric term orders, catalog names, the index floor.

A hand-edited aspheric index (``.zmx`` ``PARM 100000000 1e-5`` or TOML
``asphere = { A100000000 = 1e-30 }``) would otherwise allocate a coefficient tuple of that length and
hang the reader before anything is traced; an unknown name in ``catalogs = [...]`` would silently
search nothing. Both are refused here, where the line is known.
"""
from __future__ import annotations

from typing import Iterable

from ..errors import PrescriptionError, UnknownGlassError

__all__ = ["MAX_ASPHERE_POWER", "MAX_ZEMAX_PARM", "MIN_INDEX", "check_asphere_power", "check_catalog_names"]

#: the highest power of r an even-asphere term may have (Zemax EVENASPH stops at r^16, CODE V at r^20)
MAX_ASPHERE_POWER = 40
#: the highest Zemax PARM number (PARM n is the r^(2n) term of EVENASPH)
MAX_ZEMAX_PARM = MAX_ASPHERE_POWER // 2
#: the lowest refractive index accepted without an explicit opt-in (``exotic = true``)
MIN_INDEX = 1.0


def check_asphere_power(power: int, what: str) -> None:
    """Refuse an aspheric term of r^``power`` beyond :data:`MAX_ASPHERE_POWER` (``what`` names it)."""
    if power > MAX_ASPHERE_POWER:
        raise PrescriptionError(f"{what}: an aspheric term of r^{power} is beyond r^{MAX_ASPHERE_POWER}",
                                hint="even-asphere terms run A4, A6, ... (Zemax PARM 1..8); check the index")


def check_catalog_names(names: Iterable[str], known: Iterable[str]) -> None:
    """Refuse a catalog name that is not one of ``known`` (case-insensitive)."""
    known = tuple(known)
    lower = {k.lower() for k in known}
    for name in names:
        if str(name).strip().lower() not in lower:
            raise UnknownGlassError(f"unknown glass catalog {name!r} in catalogs",
                                    hint=f"use one of {', '.join(known)}")
