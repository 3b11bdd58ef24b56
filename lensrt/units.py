"""Unit factors and physical constants: the one place where they live.

lensrt computes in millimetres (lengths), nanometres (wavelengths), radians
(angles), seconds, electrons and data numbers. Other units appear only at the
edges (files, CLI) and are converted here.
"""
from __future__ import annotations

import math

__all__ = [
    "MM_PER_UNIT", "length_to_mm", "NM_PER_UM", "UM_PER_MM", "MM_PER_M", "NM_PER_MM",
    "deg_to_rad", "rad_to_deg", "PLANCK_J_S", "LIGHT_SPEED_M_S", "FRAUNHOFER_NM",
    "PRIMARY_D_NM", "M_PER_NM", "M_PER_UM", "M2_PER_UM2", "LUMINOUS_EFFICACY_LM_PER_W",
]

#: millimetres per unit of length, for the unit names that lens files use
MM_PER_UNIT: dict[str, float] = {
    "mm": 1.0,
    "cm": 10.0,
    "m": 1000.0,
    "in": 25.4,
    "um": 1e-3,
}

NM_PER_UM = 1000.0
UM_PER_MM = 1000.0
MM_PER_M = 1000.0
NM_PER_MM = 1.0e6

#: metres per nanometre / micrometre, square metres per square micrometre (SI radiometry)
M_PER_NM = 1.0e-9
M_PER_UM = 1.0e-6
M2_PER_UM2 = 1.0e-12

#: maximum luminous efficacy K_m of photopic vision (lm/W), CIE; lux = K_m * int E_lambda V(lambda) dlambda
LUMINOUS_EFFICACY_LM_PER_W = 683.002

#: Planck constant (J s) and speed of light (m/s), CODATA exact values
PLANCK_J_S = 6.62607015e-34
LIGHT_SPEED_M_S = 299792458.0

#: Fraunhofer lines used for Abbe numbers (nm)
FRAUNHOFER_NM: dict[str, float] = {
    "F": 486.1327,
    "d": 587.5618,
    "C": 656.2725,
    "e": 546.0740,
    "g": 435.8343,
}
PRIMARY_D_NM = FRAUNHOFER_NM["d"]


def length_to_mm(value: float, unit: str) -> float:
    """Convert ``value`` given in ``unit`` (mm, cm, m, in, um) to millimetres."""
    try:
        return value * MM_PER_UNIT[unit.lower()]
    except KeyError:
        raise ValueError(f"unknown length unit {unit!r}; use one of {sorted(MM_PER_UNIT)}") from None


def deg_to_rad(angle_deg: float) -> float:
    """Degrees to radians (edges only: files and CLI use degrees)."""
    return math.radians(angle_deg)


def rad_to_deg(angle_rad: float) -> float:
    """Radians to degrees."""
    return math.degrees(angle_rad)
