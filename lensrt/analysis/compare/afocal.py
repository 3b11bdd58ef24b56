"""Spots in angle space: what real rays say about an afocal lens (a telescope, a beam expander).

An afocal lens images an object at infinity to infinity: each field point leaves the lens as a bundle
of (ideally) parallel rays, so its "spot" is a spread of **directions**. For every field point this
module traces a real-aimed pupil grid (float64, the lens's clipping) and reports

* the real chief ray's exit angle beside the paraxial one, atan(M tan theta) with M the angular
  magnification of :func:`lensrt.paraxial.first_order` (angle fields only);
* the angular spot: the angles between each ray's exit direction and the real chief ray's,
  their RMS and largest value (mrad) -- the angular blur an eye or a camera focused at infinity
  behind the lens would see (zero for a perfect afocal system, e.g. two ideal lenses).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ...errors import LensrtError
from ...paraxial import first_order
from ...prescription.model import Lens
from ...trace import make_rays, trace

__all__ = ["AngularSpot", "angular_spots"]


@dataclass(frozen=True)
class AngularSpot:
    """One field point's exit directions (angles in degrees and mrad; see the module docstring)."""

    field_deg: float | None  # object-space field angle (None for object-height fields)
    field_height_mm: float | None  # object height (None for angle fields)
    paraxial_exit_deg: float | None  # atan(M tan theta), angle fields only
    chief_exit_deg: float  # real chief ray's angle to the axis in the meridional (y) plane, signed
    rms_mrad: float  # RMS angle between the rays and the real chief ray
    max_mrad: float  # largest such angle
    rays: int  # rays that passed

    def to_dict(self) -> dict:
        return asdict(self)


def angular_spots(lens: Lens, wavelength_nm: float | None = None, grid: int = 21,
                  device: str | None = None) -> list[AngularSpot]:
    """Angular spots of an afocal ``lens`` at each of its field points (module docstring).

    Parameters
    ----------
    lens : Lens
        An afocal lens (``first_order(lens).afocal``).
    wavelength_nm : float, optional
        Wavelength (nm); default the primary.
    grid : int
        Pupil samples across the diameter (rays inside the unit circle are traced).
    device : str, optional
        Warp device; default CUDA when present.
    """
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fo = first_order(lens, wl)
    if not fo.afocal:
        raise LensrtError("angular spots are for afocal lenses; this one has a focal length",
                          hint="lensrt compare gives spots on its image plane")
    if math.isfinite(lens.object_distance_mm):
        raise LensrtError(f"angular spots need an object at infinity; this afocal lens's object is "
                          f"{lens.object_distance_mm:g} mm in front (its image is then at a finite distance, which "
                          "lensrt's afocal first-order data do not give)", hint="set the object distance to infinity")
    g = np.linspace(-1.0, 1.0, max(int(grid), 3))
    px, py = (a.ravel() for a in np.meshgrid(g, g))
    inside = px * px + py * py <= 1.0
    px, py = px[inside], py[inside]
    top = lens.fields.max_radial
    out = []
    for x, y in zip(lens.fields.x, lens.fields.y):
        radial = math.hypot(x, y)
        hy = radial / top if top > 0.0 else 0.0
        chief = trace(lens, make_rays(lens, 0.0, hy, 0.0, 0.0, wl, aim="real", device=device), "float64", device,
                      clip=False)
        if not chief.ok[0]:
            raise LensrtError(f"the real chief ray of field {radial:g} does not pass the lens",
                              hint="check the field points and the aperture")
        c = chief.direction[0]
        res = trace(lens, make_rays(lens, 0.0, hy, px, py, wl, aim="real", device=device), "float64", device)
        d = res.direction[res.ok]
        if not len(d):
            raise LensrtError(f"no ray of field {radial:g} passes the lens", hint="check the apertures")
        cross = np.linalg.norm(np.cross(d, c), axis=1)
        ang = np.arctan2(cross, d @ c) * 1e3
        is_angle = lens.fields.kind == "angle"
        par = math.degrees(math.atan(fo.angular_magnification * math.tan(radial))) if is_angle else None
        out.append(AngularSpot(
            math.degrees(radial) if is_angle else None, None if is_angle else radial, par,
            math.degrees(math.atan2(c[1], c[2])), float(np.sqrt(np.mean(ang ** 2))), float(ang.max()),
            int(len(ang))))
    return out
