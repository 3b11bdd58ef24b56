"""Lenses and helpers for the numerical-stability suite (tests/test_stability_*.py).

Stated tolerances live here, next to the cases that use them, so the README's
"Numerical stability" section and the tests quote one set of numbers.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from lensrt.loading import complete_lens, load_lens
from lensrt.prescription.formats import read_lens
from lensrt.prescription.materials import AIR, ConstantIndex, Material
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths

LIBRARY = Path(__file__).resolve().parent.parent / "lens_prescriptions"

#: float64 kernel against the float64 NumPy reference (mm, direction cosines): the kernels'
#: documented agreement (tests/test_trace_kernels.py), observed ~1e-13
F64_VS_REFERENCE_MM = 1e-10
#: float32 against float64, image intercepts and OPL, rays that are not flagged grazing
#: (tests/test_trace_kernels.py::FLOAT32_BOUND_MM; the README's precision table)
F32_BOUND_MM = 1e-4
#: float32 direction cosines against float64 (non-grazing rays)
F32_BOUND_DIRECTION = 1e-5
WL_D = 587.5618


def library(name: str) -> Lens:
    return load_lens(LIBRARY / f"{name}.toml")


@lru_cache(maxsize=None)
def opened_lens(name: str, f_number: float) -> Lens:
    """A library lens re-specified at image-space f-number ``f_number`` (clear apertures recomputed).

    The file's own semi-diameters (if any) are dropped, so the real marginal rays of the
    new aperture define them (``trace/apertures.py``).
    """
    from dataclasses import replace
    raw = read_lens(LIBRARY / f"{name}.toml")
    surfaces = tuple(replace(s, semi_diameter_mm=None, semi_diameter_auto=False) for s in raw.surfaces)
    lens = raw.replace(surfaces=surfaces, aperture=Aperture("image_fno", float(f_number)),
                       name=f"{raw.name} opened to f/{f_number:g}")
    return complete_lens(lens)


def system(*surfaces: Surface, epd_mm: float | None = None, object_mm: float = math.inf,
           wavelengths_nm: tuple[float, ...] = (WL_D,), field_deg: float = 0.0) -> Lens:
    """A small lens from explicit surfaces (float by stop unless an EPD is given)."""
    ap = Aperture("float_by_stop", 0.0) if epd_mm is None else Aperture("epd", epd_mm)
    return Lens(tuple(surfaces), aperture=ap, fields=Fields("angle", (0.0, math.radians(field_deg))),
                wavelengths=Wavelengths(wavelengths_nm), object_distance_mm=object_mm, name="stability case")


def plano_convex(n: float, radius_mm: float, thickness_mm: float, sd_mm: float, back_mm: float = 30.0,
                 material: Material | None = None) -> Lens:
    """Stop on a plane front, then a convex rear surface of radius ``radius_mm`` (< 0: convex to +z)."""
    glass = ConstantIndex(n) if material is None else material
    return system(Surface(thickness_mm=thickness_mm, material=glass, is_stop=True, semi_diameter_mm=sd_mm),
                  Surface(curvature_per_mm=1.0 / radius_mm, thickness_mm=back_mm, semi_diameter_mm=sd_mm))


def collimated(heights_mm: np.ndarray, z_mm: float = -1.0, angle_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of rays parallel to (0, sin a, cos a) crossing y = h at z = ``z_mm``."""
    h = np.asarray(heights_mm, dtype=np.float64)
    o = np.stack([np.zeros_like(h), h, np.full_like(h, z_mm)], axis=1)
    d = np.broadcast_to(np.array([0.0, math.sin(angle_rad), math.cos(angle_rad)]), o.shape).copy()
    return o, d


def finite(*arrays: np.ndarray) -> bool:
    return all(bool(np.all(np.isfinite(a))) for a in arrays)


__all__ = ["F64_VS_REFERENCE_MM", "F32_BOUND_MM", "F32_BOUND_DIRECTION", "WL_D", "library", "opened_lens",
           "system", "plano_convex", "collimated", "finite", "AIR"]
