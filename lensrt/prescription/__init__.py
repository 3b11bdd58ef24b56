"""Stage 1: what the lens is -- the model, materials and file formats."""
from __future__ import annotations

from .materials import AIR, Air, CatalogGlass, ConstantIndex, Material, ModelGlass, find_glass, parse_material
from .model import Aperture, Fields, Iris, Lens, Surface, Wavelengths

__all__ = [
    "AIR", "Air", "CatalogGlass", "ConstantIndex", "Material", "ModelGlass", "find_glass", "parse_material",
    "Aperture", "Fields", "Iris", "Lens", "Surface", "Wavelengths",
]
