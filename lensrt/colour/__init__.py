"""Colour for every stage: wavelength grids, the CIE observer, illuminants, photometry, sRGB, charts.

The only package that reads colour-science's tables; it imports nothing of lensrt but
:mod:`lensrt.errors` and :mod:`lensrt.units`. One module per concept:

- wavelengths  WavelengthGrid, DEFAULT_GRID, STANDARD_WAVELENGTHS_NM; tabulated data at any wavelengths
- illuminants  the one illuminant syntax ("D65", "F2", "planck:3200K", "daylight:5000K", "lines:486.1,587.6")
               and the :class:`Illuminant` objects that stages pass to one another
- cmfs         CIE 1931 2-degree colour-matching functions and the 1924 V(lambda) on any grid
- photometry   integrals over wavelength, luminous values, spectra -> CIE XYZ
- rgb          XYZ <-> linear sRGB, the sRGB transfer curves, CIELAB of sRGB colours
- reflectance  RGB -> spectral reflectance (Mallett-Yuksel 2019 basis)
- charts       ColorChecker patch names and reflectances
- datacache    colour-science's tables on disk per colour-science version (no colour-science import)
"""
from __future__ import annotations

from .charts import CHART, chart_names, colorchecker_names, colorchecker_reflectances
from .cmfs import CIE_1931_2DEG, cie_xyz_cmfs, photopic_v
from .illuminants import (ILLUMINANT_SYNTAX, Illuminant, cie_illuminant, daylight, illuminant_names, lines,
                          parse_illuminant, planck, planck_radiance, spectrum, tabulated)
from .photometry import (illuminance_lux, integrate, luminous_value, reflectance_to_xyz, scale_to_luminous,
                         spectral_to_xyz)
from .reflectance import linear_rgb_to_reflectance, mallett2019_basis
from .rgb import (linear_srgb_to_lab, linear_srgb_to_xyz, srgb_decode, srgb_encode, srgb_encode8, srgb_matrices,
                  srgb_matrix_for_white, srgb_white_xy, xyz_to_linear_srgb)
from .wavelengths import (DEFAULT_GRID, STANDARD_WAVELENGTHS_NM, WavelengthGrid, as_wavelengths_nm, sd_at,
                          tabulated_at)

__all__ = ["CHART", "chart_names", "colorchecker_names", "colorchecker_reflectances", "CIE_1931_2DEG",
           "cie_xyz_cmfs", "photopic_v", "ILLUMINANT_SYNTAX", "Illuminant", "cie_illuminant", "daylight",
           "illuminant_names", "lines", "parse_illuminant", "planck", "planck_radiance", "spectrum", "tabulated",
           "illuminance_lux", "integrate", "luminous_value", "reflectance_to_xyz", "scale_to_luminous",
           "spectral_to_xyz", "linear_rgb_to_reflectance", "mallett2019_basis", "linear_srgb_to_lab",
           "linear_srgb_to_xyz", "srgb_decode", "srgb_encode", "srgb_encode8", "srgb_matrices", "srgb_matrix_for_white",
           "srgb_white_xy",
           "xyz_to_linear_srgb", "DEFAULT_GRID", "STANDARD_WAVELENGTHS_NM", "WavelengthGrid", "as_wavelengths_nm",
           "sd_at", "tabulated_at"]
