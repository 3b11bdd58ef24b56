"""Photometry and colorimetry of spectra: integrals over wavelength, luminous values, CIE XYZ.

Radiometry (Field Guide p. 39-40): a luminance L_v (cd/m^2) and a spectral radiance L_e(lambda)
(W / (m^2 sr nm)) are tied by ``L_v = K_m * int L_e(lambda) V(lambda) dlambda`` with K_m = 683 lm/W
(:data:`lensrt.units.LUMINOUS_EFFICACY_LM_PER_W`); the same holds for illuminance (lux) and spectral
irradiance (W / (m^2 nm)), and for luminous intensity (cd) and spectral radiant intensity (W / (sr nm)).
Integrals on a :class:`~lensrt.colour.wavelengths.WavelengthGrid` are its trapezoid rule; on any other
set of wavelengths, the trapezoid rule over them.
"""
from __future__ import annotations

import numpy as np

from ..errors import LensrtError
from ..units import LUMINOUS_EFFICACY_LM_PER_W
from .cmfs import cie_xyz_cmfs, photopic_v
from .wavelengths import WavelengthGrid

__all__ = ["integrate", "luminous_value", "scale_to_luminous", "spectral_to_xyz", "reflectance_to_xyz",
           "illuminance_lux"]


def integrate(values: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Trapezoid integral over wavelength (last axis) of grid-sampled ``values``; result times nm."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape[-1] != grid.n:
        raise ValueError(f"spectrum has {v.shape[-1]} samples, the grid {grid.n}")
    return v @ grid.weights_nm


def luminous_value(values: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Photometric value K_m int S V dlambda of a radiometric spectrum S on ``grid``.

    Spectral radiance W/(m^2 sr nm) -> cd/m^2; irradiance W/(m^2 nm) -> lux;
    radiant intensity W/(sr nm) -> cd; spectral flux W/nm -> lm.
    """
    return LUMINOUS_EFFICACY_LM_PER_W * integrate(np.asarray(values) * photopic_v(grid), grid)


def illuminance_lux(irradiance_w_m2_nm: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Illuminance E_v = K_m int E_lambda V dlambda (lux) of spectra on the last axis, trapezoid over
    ``wavelength_nm`` (any increasing wavelengths, nm)."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    return LUMINOUS_EFFICACY_LM_PER_W * np.trapezoid(np.asarray(irradiance_w_m2_nm) * photopic_v(wl), wl, axis=-1)


def scale_to_luminous(relative: np.ndarray, target: float, grid: WavelengthGrid, what: str = "spectrum") -> np.ndarray:
    """Scale a relative spectrum so that its photometric value (see :func:`luminous_value`) is ``target``."""
    lv = float(luminous_value(relative, grid))
    if not lv > 0.0:
        raise LensrtError(f"{what} has no power where the eye sees (K_m int S V dlambda = 0), "
                          "so a luminous value cannot set its scale",
                          hint="use radiance_scale (W / (m^2 sr nm) per unit of the spectrum) instead")
    return np.asarray(relative, dtype=np.float64) * (float(target) / lv)


def spectral_to_xyz(values: np.ndarray, grid: WavelengthGrid, absolute: bool = True) -> np.ndarray:
    """CIE 1931 XYZ of spectra on ``grid`` (wavelength axis last).

    ``absolute``: X, Y, Z = K_m int S (x, y, z) dlambda, so Y is the luminance
    (cd/m^2) of a radiance, the illuminance (lux) of an irradiance. Otherwise
    the plain integrals int S (x, y, z) dlambda.
    """
    k = LUMINOUS_EFFICACY_LM_PER_W if absolute else 1.0
    cmfs = cie_xyz_cmfs(grid) * grid.weights_nm
    return k * np.asarray(values, dtype=np.float64) @ cmfs.T


def reflectance_to_xyz(reflectance: np.ndarray, illuminant_values: np.ndarray,
                       grid: WavelengthGrid | np.ndarray, white_y: float = 100.0) -> np.ndarray:
    """XYZ of reflectances (..., n) under an illuminant, scaled so the perfect white has Y = ``white_y``
    (100 in CIE 15; 1 for the ISP's relative colorimetry). ``grid``: a grid (its trapezoid rule) or
    the wavelengths (nm) of the samples, assumed evenly spaced (the spacing cancels)."""
    illum = np.asarray(illuminant_values, dtype=np.float64)
    if isinstance(grid, WavelengthGrid):
        cmfs = cie_xyz_cmfs(grid) * grid.weights_nm
    else:
        cmfs = cie_xyz_cmfs(np.asarray(grid, dtype=np.float64))
    xyz = (np.asarray(reflectance, dtype=np.float64) * illum) @ cmfs.T
    return white_y * xyz / float(illum @ cmfs[1])
