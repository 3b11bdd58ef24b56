"""RGB -> spectrum by the Mallett-Yuksel (2019) basis, split into a few wavelength bands.

Mallett & Yuksel, "Spectral Primary Decomposition for Rendering with sRGB
Reflectance", EGSR 2019 (colour-science: ``colour.recovery``): a linear sRGB
colour (r, g, b) is the reflectance ``r B_r(l) + g B_g(l) + b B_b(l)``, which
reproduces (r, g, b) under CIE D65 with the CIE 1931 2-degree observer. The
scene's spectral radiance is that reflectance times D65, so every wavelength's
radiance is a *linear* function of the three input channels. A band b of the
spectrum shares one PSF (that of its centre wavelength), so the image of band b
is three blurred coefficient images c_b,c (c = r, g, b), and

* CIE XYZ of the output = sum_b W_b c_b with W_b[k, c] = integral over band b of
  cmf_k(l) D65(l) B_c(l) dl (normalised so that white has Y = 1): with sharp PSFs
  the output equals the input (:func:`round_trip_matrix` says how exactly);
* the spectral irradiance at any l in band b (the sensor stage) is
  sum_c D65(l) B_c(l) c_b,c (:func:`spectral_basis`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import LensrtError

__all__ = ["Bands", "make_bands", "spectral_basis", "round_trip_matrix", "FINE_STEP_NM"]

#: wavelength step of the fine grid on which the bands are integrated (nm)
FINE_STEP_NM = 5.0
_RANGE_NM = (380.0, 780.0)


@lru_cache(maxsize=4)
def _fine_tables(step_nm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(wavelength_nm (n,), CIE 1931 cmfs (n, 3), D65 (n,), Mallett-Yuksel basis (n, 3)) on one grid
    (colour-science's tables, through :mod:`lensrt.colour`)."""
    from ..colour import WavelengthGrid, cie_xyz_cmfs, mallett2019_basis, spectrum
    grid = WavelengthGrid(_RANGE_NM[0], _RANGE_NM[1], float(step_nm))
    wl = np.arange(_RANGE_NM[0], _RANGE_NM[1] + 0.5 * step_nm, step_nm)
    cmfs = np.asarray(cie_xyz_cmfs(grid), float).T
    d65 = np.asarray(spectrum("D65", grid), float)
    basis = np.asarray(mallett2019_basis(grid), float).T
    return wl, cmfs, d65, basis


@dataclass(frozen=True)
class Bands:
    """Wavelength bands of a simulation.

    Attributes
    ----------
    edges_nm : ndarray (K + 1,)
        Band edges (nm); band b is [edges[b], edges[b + 1]).
    centre_nm : ndarray (K,)
        The wavelength whose PSF stands for the band (nm): the band's centroid of
        D65 x (x + y + z bar), where most of the visible signal lies.
    xyz_matrix : ndarray (K, 3, 3)
        W_b: XYZ of the band from the (r, g, b) coefficients (white: Y = 1 in all).
    """

    edges_nm: np.ndarray
    centre_nm: np.ndarray
    xyz_matrix: np.ndarray

    @property
    def count(self) -> int:
        return len(self.centre_nm)

    def to_dict(self) -> dict:
        return {"edges_nm": self.edges_nm.tolist(), "centre_nm": self.centre_nm.tolist(),
                "method": "Mallett-Yuksel 2019 sRGB basis x CIE D65 (colour.recovery)"}


def make_bands(count: int = 4) -> Bands:
    """``count`` bands (1..16) of equal signal (D65 x (x + y + z bar)) over 380-780 nm."""
    if not 1 <= int(count) <= 16:
        raise LensrtError(f"{count} wavelength bands: use 1 to 16", hint="3-8 bands are usual")
    wl, cmfs, d65, basis = _fine_tables(FINE_STEP_NM)
    signal = d65 * cmfs.sum(axis=1)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (signal[1:] + signal[:-1]))])
    cdf /= cdf[-1]
    inner = np.interp(np.arange(1, count) / count, cdf, wl)
    edges = np.concatenate([[wl[0]], np.round(inner / FINE_STEP_NM) * FINE_STEP_NM, [wl[-1] + FINE_STEP_NM]])
    # per band: W_b = sum over the fine grid of cmf x D65 x basis (rectangle rule, step FINE_STEP_NM)
    idx = np.searchsorted(edges, wl, side="right") - 1
    norm = float((cmfs[:, 1] * d65 * basis.sum(axis=1)).sum())
    mats, centres = [], []
    for b in range(count):
        m = idx == b
        if not m.any():
            raise LensrtError(f"{count} bands are too many for the {FINE_STEP_NM:g} nm grid", hint="use fewer bands")
        mats.append(np.einsum("lk,l,lc->kc", cmfs[m], d65[m], basis[m]) / norm)
        centres.append(float((wl[m] * signal[m]).sum() / signal[m].sum()))
    return Bands(edges.astype(float), np.round(np.array(centres), 1), np.array(mats))


def spectral_basis(bands: Bands, wavelength_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(band index (n,), D65 x basis (n, 3)) at ``wavelength_nm``: radiance = basis @ (r, g, b) of that band.

    D65 is relative (100 at 560 nm); scale it to absolute radiance outside.
    """
    wl_f, _, d65, basis = _fine_tables(FINE_STEP_NM)
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    val = np.stack([np.interp(wl, wl_f, d65 * basis[:, c]) for c in range(3)], axis=-1)
    band = np.clip(np.searchsorted(bands.edges_nm, wl, side="right") - 1, 0, bands.count - 1)
    return band, val


def round_trip_matrix(bands: Bands) -> np.ndarray:
    """linear sRGB out = M @ (r, g, b) in for sharp PSFs: XYZ -> sRGB of sum_b W_b (the identity up to the
    basis's and the grid's accuracy)."""
    from ..colour import xyz_to_linear_srgb
    total = bands.xyz_matrix.sum(axis=0)  # (3 XYZ, 3 rgb)
    return xyz_to_linear_srgb(total.T).T
