"""What a lens designer reads first about a wavefront: RMS and PV wavefront error, the Strehl ratio, Zernikes.

For one field point and one wavelength (``lensrt wavefront``), from the real-ray OPD of
:mod:`lensrt.analysis.wave.wavefront`:

* **Reference sphere** (``reference``): ``"chief"`` -- centred where the real chief ray meets the observation
  plane (the OPD as traced); ``"centroid"`` -- centred on the geometric spot's centroid, i.e. the tilt of the
  area-averaged wavefront gradient removed (G-tilt: the mean transverse ray aberration is -R dW/dy / n'); and
  ``"best_fit"`` -- the sphere that minimises the RMS OPD, i.e. least-squares piston, tilt and defocus removed
  (Noll Z1-Z4; to first order that is moving the sphere's centre across and along the axis).
* **RMS and PV** over the clear pupil (cells weighted by their clear area, uniform in the exit pupil's
  direction cosines): about the mean, and with the least-squares tilt removed too. In waves at the wavelength.
* **Strehl ratio**: the peak of the diffraction PSF over the peak of the PSF of the same pupil (amplitude and
  clear aperture, vignetting included) with no OPD -- both by FFT (padding 4), the aberrated peak then refined
  by a matrix Fourier transform on a 16 x 16 grid at 1/32 of lambda N around the FFT's brightest pixel. Beside
  it the Marechal estimate exp(-(2 pi sigma)^2), sigma the RMS without tilt (good above about 0.8).
* **Zernike coefficients** of the OPD (waves) by least squares on the traced rays, pupil coordinates
  normalised to the real image-space NA (rho = 1 at the edge of the beam):
  ``noll`` -- Noll (1976) ordering and normalisation (each term unit RMS over the disc: the coefficient is the
  term's RMS contribution); ``fringe`` -- the Fringe (University of Arizona) ordering, unnormalised (each
  radial polynomial 1 at the edge: the coefficient is the term's edge amplitude). Lists start at term 1
  (piston); each fit's residual RMS is reported.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ...errors import LensrtError
from .propagation import PupilFunction, psf_fft, psf_mft
from .pupil_grid import clear_fraction, fit_zernike, noll_to_nm, pupil_coordinates, zernike
from .wavefront import RayWavefront, pupil_function_from_wavefront

__all__ = ["REFERENCES", "ZERNIKE_NORMALISATION", "WavefrontMetrics", "wavefront_metrics", "fringe_to_nm",
           "fringe_zernike", "fit_zernike_fringe", "strehl_ratio", "zernike_names", "summary_rows"]

REFERENCES = ("chief", "centroid", "best_fit")
ZERNIKE_NORMALISATION = {
    "noll": "Noll (1976): ordering and normalisation, each term unit RMS over the unit disc (coefficient = the "
            "term's RMS, waves)",
    "fringe": "Fringe (University of Arizona) ordering, unnormalised: each radial polynomial is 1 at the pupil edge "
              "(coefficient = the term's edge amplitude, waves)",
}


def fringe_to_nm(j: int) -> tuple[int, int]:
    """Fringe index j >= 1 -> (radial order n, azimuthal m); m > 0 is cos(m theta), m < 0 sin.

    j = ((n + |m|) / 2 + 1)^2 - 2 |m| (+ 1 for the sine term): 1 piston, 2-3 tilt, 4 defocus, 5-6 astigmatism,
    7-8 coma, 9 spherical, ...
    """
    if j < 1:
        raise LensrtError("Fringe Zernike indices start at 1")
    k = 0
    while (k + 1) ** 2 < j:
        k += 1
    # (n + |m|) / 2 = k; j - k^2 runs 1 .. 2k + 1 over m = k, k (sin), k - 1, k - 1 (sin), ..., 0
    r = j - k * k
    ma = k - (r - 1) // 2 if r <= 2 * k else 0
    sine = (r % 2 == 0) and ma > 0
    return 2 * k - ma, (-ma if sine else ma)


def _radial(n: int, ma: int, rho: np.ndarray) -> np.ndarray:
    out = np.zeros_like(rho)
    for k in range((n - ma) // 2 + 1):
        c = (-1) ** k * math.factorial(n - k) / (
            math.factorial(k) * math.factorial((n + ma) // 2 - k) * math.factorial((n - ma) // 2 - k))
        out = out + c * rho ** (n - 2 * k)
    return out


def fringe_zernike(j: int, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Fringe Zernike term j (unnormalised: the radial polynomial is 1 at rho = 1)."""
    n, m = fringe_to_nm(j)
    r = _radial(n, abs(m), np.asarray(rho, dtype=np.float64))
    if m == 0:
        return r
    return r * (np.cos(abs(m) * theta) if m > 0 else np.sin(abs(m) * theta))


def fit_zernike_fringe(px: np.ndarray, py: np.ndarray, values: np.ndarray, n_terms: int = 37) -> np.ndarray:
    """Least-squares Fringe-Zernike coefficients Z_1..Z_n_terms of values sampled at (px, py)."""
    px, py, v = (np.ravel(np.asarray(a, dtype=np.float64)) for a in (px, py, values))
    if px.size < n_terms:
        raise LensrtError(f"{px.size} pupil samples cannot determine {n_terms} Zernike terms")
    rho, theta = np.hypot(px, py), np.arctan2(py, px)
    a = np.stack([fringe_zernike(j, rho, theta) for j in range(1, n_terms + 1)], axis=-1)
    coef, *_ = np.linalg.lstsq(a, v, rcond=None)
    return coef


def _peak(pupil: PupilFunction) -> float:
    """The PSF's peak (1/mm^2, unit volume): FFT at padding 4, refined by an MFT around the brightest pixel."""
    from ..grid import ImageGrid
    psf, grid, _ = psf_fft(pupil, 4)
    r, c = np.unravel_index(int(np.argmax(psf)), psf.shape)
    x0, y0 = float(grid.x_mm[c]), float(grid.y_mm[r])
    lam_n_um = pupil.wavelength_mm * pupil.working_f_number * 1e3
    fine = ImageGrid.fft(16, lam_n_um / 32.0, (x0, y0))
    return max(float(psf.max()), float(psf_mft(pupil, fine, (0.0, 0.0)).max()))   # same reference point


def strehl_ratio(pupil: PupilFunction) -> float:
    """Peak of the PSF over the peak of the same pupil's PSF without OPD (module docstring)."""
    from dataclasses import replace
    perfect = replace(pupil, opd_mm=np.zeros_like(pupil.opd_mm))
    return _peak(pupil) / _peak(perfect)


@dataclass
class WavefrontMetrics:
    """RMS/PV wavefront error, Strehl ratio and Zernike coefficients of one field point at one wavelength."""

    wavelength_nm: float
    reference: str
    rms_waves: float
    pv_waves: float
    rms_waves_no_tilt: float
    pv_waves_no_tilt: float
    strehl: float
    strehl_marechal: float
    zernike_noll_waves: list[float]
    zernike_fringe_waves: list[float]
    zernike_noll_residual_rms_waves: float
    zernike_fringe_residual_rms_waves: float
    na: float
    rays: int
    opd_waves: np.ndarray = field(repr=False)     # (n, n) on the pupil grid, NaN outside the clear pupil
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"wavelength_nm": self.wavelength_nm, "reference": self.reference, "rms_waves": self.rms_waves,
                "pv_waves": self.pv_waves, "rms_waves_no_tilt": self.rms_waves_no_tilt,
                "pv_waves_no_tilt": self.pv_waves_no_tilt, "strehl": self.strehl,
                "strehl_marechal": self.strehl_marechal, "zernike_noll_waves": self.zernike_noll_waves,
                "zernike_fringe_waves": self.zernike_fringe_waves,
                "zernike_noll_residual_rms_waves": self.zernike_noll_residual_rms_waves,
                "zernike_fringe_residual_rms_waves": self.zernike_fringe_residual_rms_waves,
                "zernike_normalisation": ZERNIKE_NORMALISATION, "image_space_na": self.na, "rays": self.rays,
                **self.extra}


def _weighted_fit(basis: np.ndarray, values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    sw = np.sqrt(weights)
    coef, *_ = np.linalg.lstsq(basis * sw[:, None], values * sw, rcond=None)
    return coef


def _rms_pv(w: np.ndarray, wt: np.ndarray) -> tuple[float, float]:
    """RMS about the mean (cells weighted by clear area) and PV over the cells whose centre is clear (the
    partly clear edge cells' values are extrapolated beyond the last ray: they would inflate the PV)."""
    mean = float(np.sum(wt * w) / np.sum(wt))
    inside = wt >= 0.5
    pv = float(w[inside].max() - w[inside].min()) if inside.any() else float(w.max() - w.min())
    return float(np.sqrt(np.sum(wt * (w - mean) ** 2) / np.sum(wt))), pv


def _reference_correction(reference: str, x: np.ndarray, y: np.ndarray, w: np.ndarray, wt: np.ndarray,
                          grid_w: np.ndarray, mask: np.ndarray, scale: float):
    """``fn(px, py)``: the OPD change (waves) of moving from the chief-ray sphere to ``reference``, found on the
    clear pupil cells (x, y, w, wt; the grid ``grid_w`` with clear fractions ``mask``)."""
    if reference == "chief":
        return lambda px, py: np.zeros_like(px)
    if reference == "centroid":  # the area-averaged gradient: the geometric spot's centroid (G-tilt)
        n = grid_w.shape[0]
        step = 2.0 * scale / n
        dwr, dwc = np.gradient(np.where(mask > 0, grid_w, 0.0), step)
        inner = mask >= 1.0
        inner[1:-1, 1:-1] &= ((mask[:-2, 1:-1] >= 1) & (mask[2:, 1:-1] >= 1) & (mask[1:-1, :-2] >= 1)
                              & (mask[1:-1, 2:] >= 1))
        inner[[0, -1], :] = False
        inner[:, [0, -1]] = False
        if not inner.any():
            raise LensrtError("the clear pupil is too small to find the centroid reference")
        gxm, gym = float(np.mean(dwc[inner])), -float(np.mean(dwr[inner]))   # row 0 at +py
        return lambda px, py: -(gxm * px + gym * py)
    if reference == "best_fit":  # least-squares piston, tilt and defocus (Noll Z1-Z4)
        def basis(px, py):
            rho, th = np.hypot(px, py), np.arctan2(py, px)
            return np.stack([zernike(j, rho, th) for j in range(1, 5)], axis=-1)
        coef = _weighted_fit(basis(x, y), w, wt)
        return lambda px, py: -(basis(px, py) @ coef)
    raise LensrtError(f"unknown reference sphere {reference!r}", hint=f"use one of {', '.join(REFERENCES)}")


def wavefront_metrics(wf: RayWavefront, *, reference: str = "chief", n_terms: int = 37,
                      pupil_samples: int = 128) -> WavefrontMetrics:
    """The designer's wavefront numbers (module docstring) of one traced wavefront."""
    if reference not in REFERENCES:
        raise LensrtError(f"unknown reference sphere {reference!r}", hint=f"use one of {', '.join(REFERENCES)}")
    if not 4 <= n_terms <= 231:
        raise LensrtError(f"--zernike-terms {n_terms} must be between 4 and 231")
    pupil, _ = pupil_function_from_wavefront(wf, pupil_samples)
    n = pupil.n
    mask = clear_fraction(pupil.fine_mask, n)
    gx, gy = pupil_coordinates(n)
    scale = wf.na / wf.na_real          # rho = 1 at the real beam's edge
    clear = mask > 0
    grid_w = pupil.opd_waves
    x, y, w, wt = gx[clear] * scale, gy[clear] * scale, grid_w[clear], mask[clear]
    correction = _reference_correction(reference, x, y, w, wt, grid_w, mask, scale)
    w = w + correction(x, y)
    rms, pv = _rms_pv(w, wt)
    tilt_basis = np.stack([np.ones_like(x), x, y], axis=-1)
    w_nt = w - tilt_basis @ _weighted_fit(tilt_basis, w, wt)
    rms_nt, pv_nt = _rms_pv(w_nt, wt)
    # Strehl of the OPD as referred (a tilt moves the peak, not its height)
    opd_grid = np.zeros_like(grid_w)
    opd_grid[clear] = w
    strehl = strehl_ratio(PupilFunction.from_waves(pupil.amplitude, opd_grid, pupil.wavelength_nm,
                                                   pupil.working_f_number, chief_direction=pupil.chief_direction,
                                                   intensity=pupil.intensity, fine_mask=pupil.fine_mask))
    # Zernikes on the traced rays themselves (no gridding), OPD referred the same way
    ok = wf.valid
    lam_mm = wf.wavelength_nm * 1e-6
    rx, ry, rw = wf.px[ok] * scale, wf.py[ok] * scale, wf.opd_mm[ok] / lam_mm
    rw = rw + correction(rx, ry)
    noll = fit_zernike(rx, ry, rw, n_terms)
    rho, th = np.hypot(rx, ry), np.arctan2(ry, rx)
    noll_res = rw - np.stack([zernike(j, rho, th) for j in range(1, n_terms + 1)], axis=-1) @ noll
    fringe = fit_zernike_fringe(rx, ry, rw, n_terms)
    fringe_res = rw - np.stack([fringe_zernike(j, rho, th) for j in range(1, n_terms + 1)], axis=-1) @ fringe
    shown = np.full((n, n), np.nan)
    shown[clear] = w
    return WavefrontMetrics(wf.wavelength_nm, reference, rms, pv, rms_nt, pv_nt, strehl,
                            math.exp(-(2.0 * math.pi * rms_nt) ** 2), [float(v) for v in noll],
                            [float(v) for v in fringe], float(np.sqrt(np.mean(noll_res ** 2))),
                            float(np.sqrt(np.mean(fringe_res ** 2))), wf.na_real, int(wf.rays), shown)


def zernike_names(n_terms: int, ordering: str = "noll") -> list[str]:
    """(n, m) labels of the first ``n_terms`` terms, e.g. ``"Z4 (2,0)"``."""
    conv = noll_to_nm if ordering == "noll" else fringe_to_nm
    return [f"Z{j} {conv(j)}" for j in range(1, n_terms + 1)]


def summary_rows(metrics: Sequence[WavefrontMetrics]) -> list[list]:
    """Table rows (wavelength, reference, RMS, PV, RMS no tilt, Strehl, Marechal) for the CLI."""
    return [[m.wavelength_nm, m.reference, m.rms_waves, m.pv_waves, m.rms_waves_no_tilt, m.strehl,
             m.strehl_marechal] for m in metrics]
