"""Lenses with controlled properties for the bokeh tests (spherical aberration, vignetting, colour)."""
from __future__ import annotations

import math

from lensrt.prescription.materials import ConstantIndex, ModelGlass
from lensrt.prescription.model import Aperture, Fields, Iris, Lens, Surface, Wavelengths

BK7 = ModelGlass(1.5168, 64.17)
F2 = ModelGlass(1.6200, 36.37)


def singlet(f_mm: float = 50.0, f_number: float = 8.0, conic: float = 0.0, material=None, stop_gap_mm: float = 10.0,
            blades: int = 0, rotation_deg: float = 0.0, roundness: float = 0.0, flat_first: bool = True,
            vignetting_aperture: float | None = None, fields_deg=(0.0, 10.0)) -> Lens:
    """Stop, then a plano-convex singlet, focused for infinity (image at the paraxial focus).

    The stop (radius f / (2N)) is the first surface, so it is the entrance pupil. With the
    flat side first the curved rear surface has conic ``conic``: 0 gives under-corrected
    spherical aberration, -n^2 none at infinity, below -n^2 over-correction.
    ``vignetting_aperture``: a plane aperture 0.55 f behind the lens whose radius is this
    factor times the axial beam's radius there (mechanical vignetting off axis).
    """
    from lensrt.paraxial import first_order
    mat = ConstantIndex(1.5) if material is None else material
    n = float(mat.index(587.5618))
    r_stop = f_mm / (2.0 * f_number)
    c = -1.0 / ((n - 1.0) * f_mm) if flat_first else 1.0 / ((n - 1.0) * f_mm)
    sd = r_stop + (stop_gap_mm + 5.0) * math.tan(math.radians(max(fields_deg) + 5.0)) + 1.0
    if 1.0 + conic > 0:
        sd = min(sd, 0.95 / abs(c) / math.sqrt(1.0 + conic))
    t = abs(float(Surface(c, conic=conic).sag(sd))) + 2.0
    front = Surface(0.0 if flat_first else c, t, mat, sd, 0.0 if flat_first else conic)
    back = Surface(c if flat_first else 0.0, f_mm, conic=conic if flat_first else 0.0, semi_diameter_mm=sd)
    surfaces = [Surface(0.0, stop_gap_mm, is_stop=True, semi_diameter_mm=r_stop), front, back]
    lens = Lens(tuple(surfaces), Aperture("float_by_stop", 0.0), Fields("angle", tuple(math.radians(v) for v in fields_deg)),
                Wavelengths((486.1327, 587.5618, 656.2725), primary=1),
                iris=Iris(blades, math.radians(rotation_deg), roundness), name="test singlet")
    bfl = first_order(lens).bfl_mm
    if vignetting_aperture is None:
        return lens.replace_surface(2, thickness_mm=bfl)
    gap = 0.55 * f_mm
    beam = r_stop * (bfl - gap) / bfl  # the axial beam's radius there
    s = list(lens.surfaces)
    s[2] = Surface(s[2].curvature_per_mm, gap, conic=s[2].conic, semi_diameter_mm=s[2].semi_diameter_mm)
    s.append(Surface(0.0, bfl - gap, semi_diameter_mm=vignetting_aperture * beam))
    return lens.replace(surfaces=tuple(s))


def achromat(f_mm: float = 50.0, f_number: float = 4.0, stop_gap_mm: float = 10.0) -> Lens:
    """A thin-lens-designed cemented achromat (BK7 + F2 model glasses), stop first, focused at infinity."""
    from lensrt.paraxial import first_order
    n1, n2 = float(BK7.index(587.5618)), float(F2.index(587.5618))
    v1, v2 = BK7.vd, F2.vd
    p1, p2 = 1.0 / f_mm * v1 / (v1 - v2), -1.0 / f_mm * v2 / (v1 - v2)
    c1 = 1.0 / (0.6 * f_mm)  # crown front curvature, then the cemented and rear ones from the powers
    c2 = c1 - p1 / (n1 - 1.0)
    c3 = c2 - p2 / (n2 - 1.0)
    r_stop = f_mm / (2.0 * f_number)
    sd = 2.2 * r_stop
    s = (Surface(0.0, stop_gap_mm, is_stop=True, semi_diameter_mm=r_stop),
         Surface(c1, 5.0, BK7, sd), Surface(c2, 2.0, F2, sd), Surface(c3, f_mm, semi_diameter_mm=sd))
    lens = Lens(s, Aperture("float_by_stop", 0.0), Fields("angle", (0.0, math.radians(5.0))),
                Wavelengths((486.1327, 587.5618, 656.2725), primary=1), name="test achromat")
    return lens.replace_surface(3, thickness_mm=first_order(lens).bfl_mm)


