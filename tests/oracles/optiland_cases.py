"""optiland (a test-only oracle) set up from a lensrt Lens: the same surfaces and refractive indices."""
from __future__ import annotations

import math

from lensrt.paraxial import first_order
from lensrt.prescription.model import Lens

__all__ = ["optiland_optic"]


def optiland_optic(lens: Lens, wavelength_nm: float):
    import optiland.backend as be
    from optiland import optic
    from optiland.materials import IdealMaterial
    n = lens.indices(wavelength_nm)
    op = optic.Optic()
    op.surfaces.add(index=0, radius=be.inf, thickness=be.inf)
    for i, s in enumerate(lens.surfaces):
        mat = "air" if n[i + 1] == 1.0 else IdealMaterial(float(n[i + 1]))
        op.surfaces.add(index=i + 1, radius=s.radius_mm, thickness=s.thickness_mm, material=mat,
                        is_stop=s.is_stop, conic=s.conic)
    op.surfaces.add(index=lens.n_surfaces + 1)
    op.set_aperture(aperture_type="EPD", value=first_order(lens).entrance_pupil_diameter_mm)
    op.fields.set_type(field_type="angle")
    for f in lens.fields.y:
        op.fields.add(y=math.degrees(f))
    op.wavelengths.add(value=wavelength_nm / 1000.0, is_primary=True)
    return op
