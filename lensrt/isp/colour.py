"""Colour: white balance, the camera -> XYZ characterisation matrix, the rotation to sRGB.

Field Guide p. 59-64. The camera's raw channels are white balanced (multipliers that make the
adopted white's raw response neutral, R = G = B, with G kept), then a 3x3 characterisation
matrix M maps white-balanced camera RGB to CIE XYZ relative to the adopted white (Y_white = 1).
M is fitted ISO 17321-style: the 24 ColorChecker reflectances that colour-science ships, lit
by the scene illuminant, give camera responses (from the sensor's QE curves, photon counting)
and CIE 1931 2-degree XYZ targets; M minimises the squared XYZ error subject to the white
constraint M (1, 1, 1)^T = XYZ_white (each row solved with a Lagrange multiplier), or, with
``method="de2000"``, the mean CIEDE2000 error starting from that solution. A Bradford chromatic
adaptation (colour-science) takes XYZ from the adopted white to the sRGB white before XYZ -> linear
sRGB, and a diagonal absorbs the rounding of the IEC matrix, so that the adopted white lands on
(1, 1, 1) exactly. The product, the colour rotation matrix R = D M_sRGB CAT M, maps (1, 1, 1) to
(1, 1, 1) by construction -- its rows sum to 1 (p. 61-63): a white-balanced neutral stays neutral.

The white balance and the fit use the illuminant's spectrum itself (an
:class:`~lensrt.colour.Illuminant`): a 5000 K Planck radiator is balanced as one, not as CIE daylight.
Colorimetry (CMFs, sRGB, CIELAB) comes from :mod:`lensrt.colour`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..colour import (CHART, STANDARD_WAVELENGTHS_NM, Illuminant, colorchecker_reflectances, linear_srgb_to_lab,
                      parse_illuminant, reflectance_to_xyz, srgb_matrix_for_white)
from ..errors import LensrtError
from ..sensor.model import Sensor

__all__ = ["ColourCalibration", "calibrate", "camera_responses", "white_balance_from_illuminant",
           "xyz_of_reflectances", "delta_e2000_srgb", "white_preserving_lstsq", "CHART"]


def xyz_of_reflectances(reflectance: np.ndarray, illuminant: str | Illuminant,
                        wavelength_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """CIE 1931 XYZ (Y_white = 1) of reflectances (k, n) under ``illuminant``, and the white's XYZ."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    s = parse_illuminant(illuminant).values(wl)
    return (reflectance_to_xyz(reflectance, s, wl, white_y=1.0),
            reflectance_to_xyz(np.ones_like(wl), s, wl, white_y=1.0))


def camera_responses(sensor: Sensor, spectra: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Mean raw responses (e- per unit exposure, arbitrary scale) of spectra (k, n): (k, 3) R, G, B.

    Photon counting: the weights carry lambda / hc and the QE of each channel (p. 40).
    """
    return np.atleast_2d(spectra) @ sensor.electron_weights(wavelength_nm)


def white_balance_from_illuminant(sensor: Sensor, illuminant: str | Illuminant) -> np.ndarray:
    """Multipliers (R, G, B), G = 1, that make the illuminant's raw response neutral (p. 62-64).

    ``illuminant`` is the spectrum itself (an :class:`~lensrt.colour.Illuminant`, or its name in the
    one syntax): a 5000 K Planck radiator is balanced as one, not as CIE daylight.
    """
    wl = STANDARD_WAVELENGTHS_NM
    w = camera_responses(sensor, parse_illuminant(illuminant).relative(wl), wl)[0]
    return w[1] / w


def delta_e2000_srgb(rgb_a: np.ndarray, rgb_b: np.ndarray) -> np.ndarray:
    """CIEDE2000 between linear sRGB colours (..., 3), both relative to the D65 white with Y = 1."""
    import colour
    return np.asarray(colour.delta_E(linear_srgb_to_lab(rgb_a), linear_srgb_to_lab(rgb_b), method="CIE 2000"))


@dataclass(frozen=True)
class ColourCalibration:
    """White balance and colour matrices of one sensor under one adopted white.

    Attributes
    ----------
    illuminant : Illuminant
        Scene illuminant / adopted white the fit used (the spectrum itself).
    wb_multipliers : ndarray (3,)
        Raw white-balance multipliers, G = 1.
    camera_to_xyz : ndarray (3, 3)
        Characterisation matrix: white-balanced camera RGB -> XYZ (Y_white = 1) under the illuminant;
        ``camera_to_xyz @ (1, 1, 1) = white_xyz`` exactly.
    camera_to_srgb : ndarray (3, 3)
        Colour rotation matrix to linear sRGB (D65), chromatic adaptation included; rows sum to 1, so
        a white-balanced neutral stays exactly neutral.
    white_xyz : ndarray (3,)
        XYZ of the adopted white (Y = 1).
    fit_delta_e2000 : ndarray (24,)
        CIEDE2000 of each training patch after the fit (noise-free).
    """

    illuminant: Illuminant
    wb_multipliers: np.ndarray
    camera_to_xyz: np.ndarray
    camera_to_srgb: np.ndarray
    white_xyz: np.ndarray
    fit_delta_e2000: np.ndarray


def white_preserving_lstsq(C: np.ndarray, X: np.ndarray, w: np.ndarray, white: np.ndarray) -> np.ndarray:
    """M minimising ||C M^T - X||^2 subject to M w = white exactly (one Lagrange multiplier per row).

    With ``w`` the white-balanced camera white (1, 1, 1) and ``white`` its colorimetric value, the
    fitted matrix maps the white to the white, whatever the other patches pull toward.
    """
    A = C.T @ C
    Ainv = np.linalg.inv(A)
    M = np.empty((3, 3))
    for r in range(3):
        mu = Ainv @ C.T @ X[:, r]
        lam = (white[r] - w @ mu) / (w @ Ainv @ w)
        M[r] = mu + lam * (Ainv @ w)
    return M


def calibrate(sensor: Sensor, illuminant: str | Illuminant = "D65", method: str = "lstsq",
              chart: str = CHART) -> ColourCalibration:
    """Fit white balance and colour matrices for ``sensor`` under ``illuminant`` (see module docstring)."""
    ill = parse_illuminant(illuminant)
    wl = STANDARD_WAVELENGTHS_NM
    refl = colorchecker_reflectances(wl, chart)
    spd = ill.relative(wl)
    cam = camera_responses(sensor, refl * spd, wl)
    cam_white = camera_responses(sensor, spd, wl)[0]
    wb = cam_white[1] / cam_white
    C = cam * wb / cam_white[1]  # white-balanced, perfect white -> (1, 1, 1)
    X, white = xyz_of_reflectances(refl, ill, wl)
    ones = np.ones(3)
    M = white_preserving_lstsq(C, X, ones, white)
    adapt = srgb_matrix_for_white(white)   # adapt @ white = (1, 1, 1)
    ref_srgb = X @ adapt.T
    if method == "de2000":
        M = _fit_de2000(C, ref_srgb, adapt, M, white)
    elif method != "lstsq":
        raise LensrtError(f"unknown matrix fit {method!r}", hint="use lstsq or de2000")
    R = adapt @ M                          # R (1, 1, 1) = adapt @ white = (1, 1, 1): rows sum to 1 (p. 61-63)
    de = delta_e2000_srgb(C @ R.T, ref_srgb)
    return ColourCalibration(ill, wb, M, R, white, de)


def _fit_de2000(C: np.ndarray, ref_srgb: np.ndarray, adapt: np.ndarray, M0: np.ndarray,
                white: np.ndarray) -> np.ndarray:
    """The white-preserving M of least mean CIEDE2000, from ``M0`` (Nelder-Mead on six free entries)."""
    from scipy.optimize import minimize

    def unpack(p: np.ndarray) -> np.ndarray:
        m = np.empty((3, 3))
        m[:, :2] = p.reshape(3, 2)
        m[:, 2] = white - m[:, :2].sum(axis=1)  # keeps M (1,1,1) = white
        return m

    def cost(p: np.ndarray) -> float:
        return float(np.mean(delta_e2000_srgb(C @ (adapt @ unpack(p)).T, ref_srgb)))

    res = minimize(cost, M0[:, :2].ravel(), method="Nelder-Mead",
                   options={"xatol": 1e-7, "fatol": 1e-6, "maxiter": 4000, "maxfev": 8000})
    return unpack(res.x)
