"""Modulation transfer: MTF from sampled PSFs, diffraction limit, detector aperture, OLPF, system MTF.

The Field Guide (p. 108-118) treats the camera as a linear shift-invariant
system piece by piece: the system PSF is the lens PSF convolved with the
detector aperture and the optical low-pass filter, so the system OTF is the
product of theirs. The MTF is the modulus of the OTF normalised to 1 at zero
frequency. Spatial frequencies are in cycles/mm (= lp/mm).

Sagittal and tangential
-----------------------
For an image point at (x, y) on the sensor, the *tangential* (meridional)
direction is the radial one, from the axis through the point (angle
atan2(y, x)); the *sagittal* direction is perpendicular to it. The
tangential MTF is the MTF for frequencies along the radial direction (bars
lying along the circumference); the sagittal MTF for frequencies along the
circumference (bars pointing at the axis). On axis the tangential direction
is taken as +y (Zemax's convention for a y field).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...stats import Estimate, jackknife
from ...units import NM_PER_MM, UM_PER_MM
from ..grid import ImageGrid

__all__ = ["FULL_FRAME_DIAGONAL_MM", "AIRY_FIRST_ZERO", "nyquist_cpmm", "diffraction_cutoff_cpmm",
           "diffraction_mtf", "polychromatic_diffraction_mtf", "airy_psf", "airy_first_zero_mm",
           "airy_encircled_energy", "detector_mtf", "olpf_mtf", "system_mtf", "mtf_2d", "otf_along",
           "mtf_along", "tangential_angle_rad", "sagittal_tangential", "mtf_vs_field",
           "reference_frequencies_cpmm", "through_focus_mtf", "mtf_estimate", "usable_freqs", "mtf_directions"]

#: diagonal of the 36 x 24 mm full-frame format (mm)
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: first zero of the Airy pattern in units of lambda N (j_1,1 / pi)
AIRY_FIRST_ZERO = 3.8317059702075125 / math.pi


def nyquist_cpmm(pixel_pitch_um: float) -> float:
    """Sensor Nyquist frequency 1 / (2 pitch) (cycles/mm)."""
    return UM_PER_MM / (2.0 * pixel_pitch_um)


def diffraction_cutoff_cpmm(wavelength_nm: float, working_f_number: float) -> float:
    """Incoherent cutoff 1 / (lambda N_w) of a circular pupil (cycles/mm), p. 112."""
    return NM_PER_MM / (wavelength_nm * working_f_number)


def diffraction_mtf(freq_cpmm: np.ndarray | float, wavelength_nm: float, working_f_number: float) -> np.ndarray:
    """Diffraction-limited MTF of a clear circular pupil (p. 112).

    MTF = (2/pi) (arccos s - s sqrt(1 - s^2)), s = freq / cutoff, 0 beyond the cutoff.
    """
    s = np.clip(np.abs(np.asarray(freq_cpmm, dtype=np.float64)) / diffraction_cutoff_cpmm(
        wavelength_nm, working_f_number), 0.0, 1.0)
    return 2.0 / np.pi * (np.arccos(s) - s * np.sqrt(1.0 - s * s))


def polychromatic_diffraction_mtf(freq_cpmm: np.ndarray | float, wavelengths_nm: Sequence[float],
                                  weights: Sequence[float], working_f_number: float) -> np.ndarray:
    """MTF of the weighted sum of unit-volume diffraction PSFs: sum w_i MTF_i / sum w_i."""
    w = np.asarray(weights, dtype=np.float64)
    return sum(wi * diffraction_mtf(freq_cpmm, wl, working_f_number)
               for wl, wi in zip(wavelengths_nm, w)) / w.sum()


def airy_first_zero_mm(wavelength_nm: float, working_f_number: float) -> float:
    """Radius of the Airy pattern's first dark ring, 1.22 lambda N (mm), p. 111."""
    return AIRY_FIRST_ZERO * wavelength_nm / NM_PER_MM * working_f_number


def airy_psf(r_mm: np.ndarray | float, wavelength_nm: float, working_f_number: float) -> np.ndarray:
    """Airy pattern normalised to unit volume (1/mm^2), p. 111.

    E(r) = pi / (4 lambda^2 N^2) [2 J1(v) / v]^2 with v = pi r / (lambda N).
    """
    from scipy.special import j1

    lam_n = wavelength_nm / NM_PER_MM * working_f_number
    v = np.pi * np.abs(np.asarray(r_mm, dtype=np.float64)) / lam_n
    safe = np.where(v == 0, 1.0, v)
    amp = np.where(v == 0, 1.0, 2.0 * j1(safe) / safe)
    return np.pi / (4.0 * lam_n * lam_n) * amp * amp


def airy_encircled_energy(r_mm: np.ndarray | float, wavelength_nm: float, working_f_number: float) -> np.ndarray:
    """Fraction of the Airy pattern's energy within radius r: 1 - J0(v)^2 - J1(v)^2 (Rayleigh)."""
    from scipy.special import j0, j1

    v = np.pi * np.abs(np.asarray(r_mm, dtype=np.float64)) / (wavelength_nm / NM_PER_MM * working_f_number)
    return 1.0 - j0(v) ** 2 - j1(v) ** 2


def detector_mtf(freq_x_cpmm: np.ndarray | float, freq_y_cpmm: np.ndarray | float, aperture_x_um: float,
                 aperture_y_um: float | None = None) -> np.ndarray:
    """MTF of a rectangular pixel aperture |sinc(dx mu_x) sinc(dy mu_y)|, p. 115 (zero at 1/dx).

    ``aperture_*_um`` is the light-sensitive width (the pitch for 100 %
    fill factor). ``np.sinc(t) = sin(pi t) / (pi t)``.
    """
    dx = aperture_x_um / UM_PER_MM
    dy = (aperture_x_um if aperture_y_um is None else aperture_y_um) / UM_PER_MM
    return np.abs(np.sinc(dx * np.asarray(freq_x_cpmm)) * np.sinc(dy * np.asarray(freq_y_cpmm)))


def olpf_mtf(freq_x_cpmm: np.ndarray | float, freq_y_cpmm: np.ndarray | float, separation_um: float,
             separation_y_um: float | None = None) -> np.ndarray:
    """MTF of a four-spot birefringent optical low-pass filter |cos(pi s mu_x) cos(pi s mu_y)|, p. 117-118.

    Two crossed birefringent plates split a point into four equal spots at
    (+-s/2, +-s/2), ``s`` = ``separation_um``; the first zero is at 1/(2s),
    the Nyquist frequency when s equals the pixel pitch.
    """
    sx = separation_um / UM_PER_MM
    sy = (separation_um if separation_y_um is None else separation_y_um) / UM_PER_MM
    return np.abs(np.cos(np.pi * sx * np.asarray(freq_x_cpmm)) * np.cos(np.pi * sy * np.asarray(freq_y_cpmm)))


def system_mtf(*components: np.ndarray | float) -> np.ndarray:
    """System MTF: the product of the component MTFs (lens, OLPF, detector, ...), broadcast together."""
    if not components:
        raise ValueError("system_mtf needs at least one component")
    out = np.asarray(components[0], dtype=np.float64)
    for c in components[1:]:
        out = out * np.asarray(c, dtype=np.float64)
    return out


def mtf_2d(psf: np.ndarray, grid: ImageGrid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two-dimensional MTF by FFT: (freq_x (cols,), freq_y (rows,), mtf (rows, cols)) in cycles/mm.

    Shown like the PSF: zero frequency in the middle, +freq_y toward row 0.
    """
    a = np.asarray(psf, dtype=np.float64)
    tot = a.sum()
    if not tot > 0:
        raise LensrtError("the PSF holds no light: no MTF")
    otf = np.fft.fftshift(np.fft.fft2(np.flipud(a))) / tot
    fx = np.fft.fftshift(np.fft.fftfreq(a.shape[1], grid.pitch_mm))
    fy = np.fft.fftshift(np.fft.fftfreq(a.shape[0], grid.pitch_mm))[::-1]
    return fx, fy, np.abs(np.flipud(otf))


def otf_along(psf: np.ndarray, grid: ImageGrid, freqs_cpmm: Sequence[float] | np.ndarray, angle_rad: float,
              binned: bool = False, total: float | None = None) -> np.ndarray:
    """Complex OTF at frequencies along direction ``angle_rad`` (from +x toward +y), by a direct DFT.

    Parameters
    ----------
    binned : bool
        The PSF is a histogram (each value the mean over its bin), not point
        samples: divide out the bins' own box MTF sinc(p mu_x) sinc(p mu_y).
    total : float, optional
        The PSF's sum over the WHOLE image plane, in the array's units (default: the window's own sum).
        A window cuts the PSF's wings; normalised by its own sum, the MTF of what is left lies above the
        true MTF (the Airy wings beyond 13 radii hold 1.3 % of the energy: +0.012 at low frequencies).
        Normalised by the power that entered the pupil it lies at or below it.
    """
    a = np.asarray(psf, dtype=np.float64)
    tot = a.sum() if total is None else float(total)
    if not tot > 0:
        raise LensrtError("the PSF holds no light: no MTF")
    f = np.atleast_1d(np.asarray(freqs_cpmm, dtype=np.float64))
    fx, fy = f * math.cos(angle_rad), f * math.sin(angle_rad)
    nyq = 0.5 / grid.pitch_mm
    if np.max(np.maximum(np.abs(fx), np.abs(fy)), initial=0.0) > nyq * (1 + 1e-9):
        raise LensrtError(f"frequency {f.max():g} cycles/mm is beyond this PSF grid's Nyquist {nyq:g}",
                          hint="sample the PSF on a finer grid or ask for lower frequencies")
    cx, cy = grid.centre_mm  # phase origin: only the OTF's phase depends on it
    ex = np.exp(-2j * np.pi * np.outer(fx, grid.x_mm - cx))
    ey = np.exp(-2j * np.pi * np.outer(fy, grid.y_mm - cy))
    otf = np.sum((ey @ a) * ex, axis=1) / tot
    if binned:
        otf = otf / (np.sinc(grid.pitch_mm * fx) * np.sinc(grid.pitch_mm * fy))
    return otf


def mtf_along(psf: np.ndarray, grid: ImageGrid, freqs_cpmm: Sequence[float] | np.ndarray, angle_rad: float,
              binned: bool = False, total: float | None = None) -> np.ndarray:
    """MTF = |OTF| along a direction (see :func:`otf_along`)."""
    return np.abs(otf_along(psf, grid, freqs_cpmm, angle_rad, binned, total))


def tangential_angle_rad(image_point_mm: tuple[float, float]) -> float:
    """Direction of the tangential (radial) frequency axis for an image point; +y on axis."""
    x, y = image_point_mm
    return math.atan2(y, x) if math.hypot(x, y) > 1e-12 else 0.5 * math.pi


def sagittal_tangential(psf: np.ndarray, grid: ImageGrid, freqs_cpmm: Sequence[float] | np.ndarray,
                        image_point_mm: tuple[float, float] | None = None, binned: bool = False
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(sagittal, tangential) MTF curves of a PSF at ``image_point_mm`` (default: the grid centre)."""
    t = tangential_angle_rad(grid.centre_mm if image_point_mm is None else image_point_mm)
    return (mtf_along(psf, grid, freqs_cpmm, t + 0.5 * math.pi, binned),
            mtf_along(psf, grid, freqs_cpmm, t, binned))


def reference_frequencies_cpmm(format_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM,
                               full_frame_cpmm: Sequence[float] = (10.0, 20.0, 40.0)) -> np.ndarray:
    """MTF-against-field frequencies: 10/20/40 lp/mm on full frame, scaled by 43.27 mm / diagonal (p. 114).

    A smaller format is enlarged more to the same print, so the same
    print detail needs proportionally higher frequencies on its sensor.
    """
    if not format_diagonal_mm > 0:
        raise LensrtError(f"format diagonal {format_diagonal_mm} mm must be positive")
    return np.asarray(full_frame_cpmm, dtype=np.float64) * FULL_FRAME_DIAGONAL_MM / format_diagonal_mm


def mtf_vs_field(psfs: Sequence[np.ndarray], grids: Sequence[ImageGrid], image_points_mm: Sequence[tuple[float, float]],
                 freqs_cpmm: Sequence[float], binned: bool = False) -> dict:
    """Sagittal and tangential MTF at ``freqs_cpmm`` for each field point.

    Returns ``{"freqs_cpmm", "image_height_mm" (n_field,), "sagittal" and
    "tangential" (n_field, n_freq)}``.
    """
    s, t = zip(*(sagittal_tangential(p, g, freqs_cpmm, pt, binned)
                 for p, g, pt in zip(psfs, grids, image_points_mm)))
    return {"freqs_cpmm": np.asarray(freqs_cpmm, dtype=np.float64),
            "image_height_mm": np.array([math.hypot(*pt) for pt in image_points_mm]),
            "sagittal": np.array(s), "tangential": np.array(t)}


def through_focus_mtf(psf_stack: np.ndarray, grid: ImageGrid, focus_mm: Sequence[float],
                      freqs_cpmm: Sequence[float], image_point_mm: tuple[float, float] | None = None,
                      binned: bool = False) -> dict:
    """MTF against focus from a stack of PSFs (n_focus, rows, cols) on one grid.

    Returns ``{"focus_mm", "freqs_cpmm", "sagittal", "tangential" (n_focus, n_freq),
    "best_focus_mm": {"sagittal", "tangential"} (n_freq,)}``; the best focus is
    the parabola vertex through the highest sample and its neighbours.
    """
    z = np.asarray(focus_mm, dtype=np.float64)
    stack = np.asarray(psf_stack, dtype=np.float64)
    if stack.ndim != 3 or stack.shape[0] != z.size:
        raise LensrtError("through-focus MTF needs one PSF per focus position")
    s, t = zip(*(sagittal_tangential(p, grid, freqs_cpmm, image_point_mm, binned) for p in stack))
    out = {"focus_mm": z, "freqs_cpmm": np.asarray(freqs_cpmm, dtype=np.float64),
           "sagittal": np.array(s), "tangential": np.array(t)}
    out["best_focus_mm"] = {k: np.array([peak_position(z, out[k][:, j]) for j in range(out[k].shape[1])])
                            for k in ("sagittal", "tangential")}
    return out


def peak_position(z: np.ndarray, v: np.ndarray) -> float:
    i = int(np.argmax(v))
    if 0 < i < z.size - 1:
        a, b, _ = np.polyfit(z[i - 1:i + 2], v[i - 1:i + 2], 2)
        if a < 0:
            return float(-b / (2 * a))
    return float(z[i])


def mtf_estimate(batch_psfs: np.ndarray, grid: ImageGrid, freqs_cpmm: Sequence[float], angle_rad: float,
                 binned: bool = True, seconds: float = 0.0, samples: int = 0) -> Estimate:
    """MTF along a direction from per-batch PSF histograms (B, rows, cols), jackknife standard errors."""
    b = np.asarray(batch_psfs, dtype=np.float64)
    value, se = jackknife(b, lambda h: mtf_along(h, grid, freqs_cpmm, angle_rad, binned))
    return Estimate(np.asarray(value), np.asarray(se), int(samples), float(seconds),
                    f"jackknife over {b.shape[0]} batches", "")


def usable_freqs(freqs_cpmm: np.ndarray, nyquist_cpmm: float) -> np.ndarray:
    """The frequencies (cycles/mm) in [0, Nyquist] (to 1e-9), where a grid samples the MTF."""
    f = np.asarray(freqs_cpmm, dtype=np.float64)
    return f[(f >= 0) & (f <= nyquist_cpmm * (1 - 1e-9))]


def mtf_directions(freqs_cpmm: Sequence[float], angles_rad: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(fx, fy) cycles/mm of every frequency along every direction, angle by angle (A * F each)."""
    f = np.atleast_1d(np.asarray(freqs_cpmm, dtype=np.float64))
    return (np.concatenate([f * math.cos(a) for a in angles_rad]),
            np.concatenate([f * math.sin(a) for a in angles_rad]))
