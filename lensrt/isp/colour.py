"""Colour: white balance, the camera -> XYZ characterisation matrix, the rotation to sRGB.

Field Guide p. 59-64. The camera's raw channels are white balanced (multipliers that make the
adopted white's raw response neutral, R = G = B, with G kept), then a 3x3 characterisation
matrix M maps white-balanced camera RGB to CIE XYZ relative to the adopted white (Y_white = 1).
M is fitted ISO 17321-style: the 24 ColorChecker reflectances that colour-science ships, lit
by the scene illuminant, give camera responses (from the sensor's QE curves, photon counting)
and CIE 1931 2-degree XYZ targets; M minimises the squared XYZ error subject to the white
constraint M (1, 1, 1)^T = XYZ_white (each row solved with a Lagrange multiplier), or, with
``method="de2000"``, the mean CIEDE2000 error starting from that solution. When the adopted
white is not D65 a Bradford chromatic adaptation (colour-science) takes XYZ to D65 before
XYZ -> linear sRGB. The product, the colour rotation matrix R = M_sRGB CAT M, has rows that
sum to 1 (p. 61-63): a white-balanced neutral stays neutral.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from ..sensor.exposure import STANDARD_WAVELENGTHS_NM, illuminant_spd
from ..sensor.model import Sensor
from ..sensor.targets import CHART, colorchecker_reflectances

__all__ = ["ColourCalibration", "calibrate", "camera_responses", "white_balance_from_illuminant",
           "xyz_of_reflectances", "xyz_to_linear_srgb", "linear_srgb_to_xyz", "delta_e2000_srgb",
           "CHART"]



def _cmfs(wavelength_nm: np.ndarray) -> np.ndarray:
    import colour
    c = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([np.interp(wavelength_nm, c.wavelengths, c.values[:, i], left=0, right=0) for i in range(3)], -1)


def xyz_of_reflectances(reflectance: np.ndarray, illuminant: str | float, wavelength_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """CIE 1931 XYZ (Y_white = 1) of reflectances (k, n) under ``illuminant``, and the white's XYZ."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    s = illuminant_spd(illuminant, wl)
    cmf = _cmfs(wl)
    norm = float(s @ cmf[:, 1])
    return (np.asarray(reflectance) * s) @ cmf / norm, (s @ cmf) / norm


def camera_responses(sensor: Sensor, spectra: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Mean raw responses (e- per unit exposure, arbitrary scale) of spectra (k, n): (k, 3) R, G, B.

    Photon counting: the weights carry lambda / hc and the QE of each channel (p. 40).
    """
    return np.atleast_2d(spectra) @ sensor.electron_weights(wavelength_nm)


def white_balance_from_illuminant(sensor: Sensor, illuminant: str | float) -> np.ndarray:
    """Multipliers (R, G, B), G = 1, that make the illuminant's raw response neutral (p. 62-64)."""
    wl = STANDARD_WAVELENGTHS_NM
    w = camera_responses(sensor, illuminant_spd(illuminant, wl), wl)[0]
    return w[1] / w


def _xyz_to_srgb_matrix() -> np.ndarray:
    import colour
    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB, dtype=np.float64)


def xyz_to_linear_srgb(xyz: np.ndarray) -> np.ndarray:
    """Linear sRGB (D65) from XYZ (D65-relative), no clipping."""
    return np.asarray(xyz) @ _xyz_to_srgb_matrix().T


def linear_srgb_to_xyz(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(rgb) @ np.linalg.inv(_xyz_to_srgb_matrix()).T


def delta_e2000_srgb(rgb_a: np.ndarray, rgb_b: np.ndarray) -> np.ndarray:
    """CIEDE2000 between linear sRGB colours (..., 3), both relative to the D65 white with Y = 1."""
    import colour
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    la = colour.XYZ_to_Lab(linear_srgb_to_xyz(rgb_a), white)
    lb = colour.XYZ_to_Lab(linear_srgb_to_xyz(rgb_b), white)
    return np.asarray(colour.delta_E(la, lb, method="CIE 2000"))


@dataclass(frozen=True)
class ColourCalibration:
    """White balance and colour matrices of one sensor under one adopted white.

    Attributes
    ----------
    illuminant : str or float
        Scene illuminant / adopted white the fit used.
    wb_multipliers : ndarray (3,)
        Raw white-balance multipliers, G = 1.
    camera_to_xyz : ndarray (3, 3)
        Characterisation matrix: white-balanced camera RGB -> XYZ (Y_white = 1) under the illuminant.
    camera_to_srgb : ndarray (3, 3)
        Colour rotation matrix to linear sRGB (D65), chromatic adaptation included; rows sum to 1.
    white_xyz : ndarray (3,)
        XYZ of the adopted white (Y = 1).
    fit_delta_e2000 : ndarray (24,)
        CIEDE2000 of each training patch after the fit (noise-free).
    """

    illuminant: str | float
    wb_multipliers: np.ndarray
    camera_to_xyz: np.ndarray
    camera_to_srgb: np.ndarray
    white_xyz: np.ndarray
    fit_delta_e2000: np.ndarray


def _constrained_lstsq(C: np.ndarray, X: np.ndarray, w: np.ndarray, white: np.ndarray) -> np.ndarray:
    """M minimising ||C M^T - X||^2 with M w = white (one Lagrange multiplier per row)."""
    A = C.T @ C
    Ainv = np.linalg.inv(A)
    M = np.empty((3, 3))
    for r in range(3):
        mu = Ainv @ C.T @ X[:, r]
        lam = (white[r] - w @ mu) / (w @ Ainv @ w)
        M[r] = mu + lam * (Ainv @ w)
    return M


def calibrate(sensor: Sensor, illuminant: str | float = "D65", method: str = "lstsq", chart: str = CHART) -> ColourCalibration:
    """Fit white balance and colour matrices for ``sensor`` under ``illuminant`` (see module docstring)."""
    import colour
    wl = STANDARD_WAVELENGTHS_NM
    _, refl = colorchecker_reflectances(wl, chart)
    spd = illuminant_spd(illuminant, wl)
    cam = camera_responses(sensor, refl * spd, wl)
    cam_white = camera_responses(sensor, spd, wl)[0]
    wb = cam_white[1] / cam_white
    C = cam * wb / cam_white[1]  # white-balanced, perfect white -> (1, 1, 1)
    X, white = xyz_of_reflectances(refl, illuminant, wl)
    ones = np.ones(3)
    M = _constrained_lstsq(C, X, ones, white)
    d65 = np.asarray(colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]))
    if str(illuminant).upper() == "D65":
        cat = np.eye(3)
    else:
        cat = np.asarray(colour.adaptation.matrix_chromatic_adaptation_VonKries(white, d65, "Bradford"))
    to_srgb = _xyz_to_srgb_matrix()

    def rotation(m: np.ndarray) -> np.ndarray:
        r = to_srgb @ cat @ m
        return r / r.sum(axis=1, keepdims=True)  # rows sum to 1 (p. 61-63)

    ref_srgb = xyz_to_linear_srgb(X @ cat.T)
    if method == "de2000":
        from scipy.optimize import minimize

        def unpack(p: np.ndarray) -> np.ndarray:
            m = np.empty((3, 3))
            m[:, :2] = p.reshape(3, 2)
            m[:, 2] = white - m[:, :2].sum(axis=1)  # keeps M (1,1,1) = white
            return m

        def cost(p: np.ndarray) -> float:
            return float(np.mean(delta_e2000_srgb(C @ rotation(unpack(p)).T, ref_srgb)))

        res = minimize(cost, M[:, :2].ravel(), method="Nelder-Mead",
                       options={"xatol": 1e-7, "fatol": 1e-6, "maxiter": 4000, "maxfev": 8000})
        M = unpack(res.x)
    elif method != "lstsq":
        raise LensrtError(f"unknown matrix fit {method!r}", hint="use lstsq or de2000")
    R = rotation(M)
    de = delta_e2000_srgb(C @ R.T, ref_srgb)
    return ColourCalibration(illuminant, wb, M, R, white, de)
