"""Diffraction PSFs from a pupil function: FFT, matrix Fourier transform (any grid), Huygens sum.

The pupil function P(p) = A(p) exp(2 pi i W(p) / lambda) lives on the
normalised pupil grid of :mod:`lensrt.analysis.wave.pupil_grid` (positions p in
[-1, 1]^2, ``n`` cells across, scaled so that |p| = 1 is the image-space
numerical aperture NA = 1 / (2 N_w), N_w the working f-number). In the Debye
picture the field on the sensor plane is the Fourier transform of P over the
direction cosines (L, M) = chief - NA p; with x in mm and f = NA / lambda
(cycles/mm per unit of p),

    U(x, y) = sum_k P_k exp(-2 pi i f (px_k x + py_k y)).

Sampling (the formula every PSF here reports)
---------------------------------------------
A pupil cell is dp = 2/n wide, i.e. du = f dp = 2 NA / (n lambda) cycles/mm.
An FFT of the pupil zero-padded to M = Q n points gives image samples

    dx = 1 / (M du) = lambda / (2 Q NA) = lambda N_w / Q,

and, for a paraxial exit pupil of diameter D at distance R from the image
(N_w = R / D), dx = lambda R / (Q D). The image repeats with period
M dx = n lambda N_w (the field of view, independent of Q): a PSF wider than
that wraps round. The intensity is band-limited to 1/(lambda N_w), so Q >= 2
samples it at or above Nyquist; Q < 2 is refused. The pupil must resolve the
wavefront: the OPD may change by at most lambda/2 between neighbouring
cells (reported as ``max_phase_step_waves``).

Which method when
-----------------
* :func:`psf_fft` -- the whole M x M image at pitch lambda N_w / Q. Fastest;
  use it for near-diffraction-limited points (PSF within n lambda N_w) and
  for MTFs.
* :func:`psf_mft` -- the same Debye integral evaluated on any
  :class:`ImageGrid` (any pitch, size and centre) by two matrix products
  (Soummer et al. 2007, Opt. Express 15, 15935). Exact band-limited
  resampling: it is how :func:`polychromatic_psf` puts every wavelength on a
  common grid, and how a PSF is put on a sensor's pixel grid or on a window
  centred away from the chief ray.
* :func:`psf_huygens` -- direct sum of spherical wavelets from points on the
  reference sphere to image points, exact distances (no Debye/Fraunhofer
  linearisation), any observation plane z. Slow (O(pupil x image points));
  use it as the reference, for small Fresnel numbers a^2/(lambda R) (a
  the pupil radius) where Debye fails, and for image points far (compared
  with the pupil size) from the reference point, e.g. strongly aberrated
  off-axis points whose light lands well away from the chief ray.

All PSFs come normalised to unit volume (Field Guide p. 111) over the whole
plane, in 1/mm^2: a window that misses part of the light sums to less than 1.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...units import NM_PER_MM, UM_PER_MM
from ..grid import ImageGrid
from .pupil_grid import defocus_opd_mm, pupil_coordinates

__all__ = ["PupilFunction", "fft_pitch_um", "sampling_report", "psf_fft", "psf_mft", "psf_points",
           "polychromatic_psf", "psf_huygens", "through_focus_psfs"]


@dataclass(frozen=True)
class PupilFunction:
    """A sampled pupil function at one wavelength.

    Attributes
    ----------
    amplitude : array (n, n)
        Field amplitude >= 0 (0 = opaque); row 0 at +py.
    opd_mm : array (n, n)
        Optical path difference (mm), sign as in :mod:`lensrt.analysis.wave.pupil_grid`.
    wavelength_nm : float
    working_f_number : float
        N_w = 1 / (2 NA): the pupil edge |p| = 1 is at NA.
    chief_direction : (3,)
        Unit image-space direction of the chief ray (used by the Huygens sum
        and exact defocus; (0, 0, 1) on axis).
    intensity : array (n, n), optional
        Cell mean of the transmitted intensity |a|^2, which sets the energy
        (the unit-volume normalisation). Default ``amplitude**2``, right for
        smooth amplitudes and hard 0/1 masks. For an anti-aliased clear
        aperture (cell values = the clear fraction of each cell, as the
        :mod:`~lensrt.analysis.wave.pupil_grid` shape builders return) the energy is the
        clear area, i.e. pass the mask itself: otherwise the PSF comes out
        too bright by sum(mask) / sum(mask^2) (about 0.5 % at n = 128).
    fine_mask : array (n s, n s) of bool, optional
        The clear aperture on s x s sub-cells of every cell: the hard edge the OTF is taken from
        (:func:`lensrt.analysis.psf.diffraction.pupil_otf`). Without it the OTF autocorrelates the soft
        (anti-aliased) amplitude, which acts as an apodiser and lifts the MTF (+0.004 at 0.1 of the cutoff
        for a clear circle at n = 128).
    """

    amplitude: np.ndarray
    opd_mm: np.ndarray
    wavelength_nm: float
    working_f_number: float
    chief_direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    intensity: np.ndarray | None = None
    fine_mask: np.ndarray | None = None

    def __post_init__(self) -> None:
        a, w = np.asarray(self.amplitude, dtype=np.float64), np.asarray(self.opd_mm, dtype=np.float64)
        if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape != w.shape:
            raise LensrtError(f"pupil amplitude {a.shape} and OPD {w.shape} must be the same square grid")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(w))) or np.any(a < 0):
            raise LensrtError("pupil amplitude must be finite and >= 0 and the OPD finite")
        if not a.any():
            raise LensrtError("the pupil is completely dark: no light reaches this image point")
        if not (self.wavelength_nm > 0 and self.working_f_number > 0.5):
            raise LensrtError(f"wavelength {self.wavelength_nm} nm and working f-number "
                              f"{self.working_f_number} must be positive (N_w > 0.5)")
        i = a * a if self.intensity is None else np.asarray(self.intensity, dtype=np.float64)
        if i.shape != a.shape or np.any(i < a * a * (1 - 1e-9)) or not np.all(np.isfinite(i)):
            raise LensrtError("pupil intensity must have the amplitude's shape and be >= amplitude^2 "
                              "(a cell's mean |a|^2 is at least its mean |a| squared)")
        object.__setattr__(self, "intensity", i)
        if self.fine_mask is not None:
            m = np.asarray(self.fine_mask, dtype=bool)
            if m.ndim != 2 or m.shape[0] != m.shape[1] or m.shape[0] % a.shape[0]:
                raise LensrtError(f"fine pupil mask {m.shape} must be a square multiple of the {a.shape} grid")
            object.__setattr__(self, "fine_mask", m)
        object.__setattr__(self, "amplitude", a)
        object.__setattr__(self, "opd_mm", w)
        object.__setattr__(self, "chief_direction", tuple(float(v) for v in self.chief_direction))

    @classmethod
    def from_waves(cls, amplitude: np.ndarray, opd_waves: np.ndarray, wavelength_nm: float,
                   working_f_number: float, **kw) -> "PupilFunction":
        """Pupil function with the OPD given in waves at ``wavelength_nm``."""
        return cls(amplitude, np.asarray(opd_waves, dtype=np.float64) * wavelength_nm / NM_PER_MM,
                   wavelength_nm, working_f_number, **kw)

    @property
    def n(self) -> int:
        return self.amplitude.shape[0]

    @property
    def na(self) -> float:
        return 0.5 / self.working_f_number

    @property
    def wavelength_mm(self) -> float:
        return self.wavelength_nm / NM_PER_MM

    @property
    def opd_waves(self) -> np.ndarray:
        return self.opd_mm / self.wavelength_mm

    def field(self) -> np.ndarray:
        """Complex pupil function A exp(2 pi i W / lambda)."""
        return self.amplitude * np.exp(2j * np.pi * self.opd_waves)

    def with_defocus(self, dz_mm: float) -> "PupilFunction":
        """The same pupil observed on a plane moved by ``dz_mm`` along +z (exact, not paraxial)."""
        px, py = pupil_coordinates(self.n)
        extra = defocus_opd_mm(px, py, self.na, dz_mm, self.chief_direction)
        return replace(self, opd_mm=self.opd_mm + np.where(self.amplitude > 0, extra, 0.0))


def fft_pitch_um(wavelength_nm: float, working_f_number: float, padding: float) -> float:
    """Image-plane sample pitch of an FFT PSF: lambda N_w / Q (um)."""
    return wavelength_nm / NM_PER_MM * UM_PER_MM * working_f_number / padding


def _phase_step(pupil: PupilFunction) -> float:
    w, a = pupil.opd_waves, pupil.amplitude > 0
    steps = [np.abs(np.diff(w, axis=ax))[(a[1:, :] & a[:-1, :]) if ax == 0 else (a[:, 1:] & a[:, :-1])]
             for ax in (0, 1)]
    return float(max((s.max() if s.size else 0.0) for s in steps))


def sampling_report(pupil: PupilFunction, padding: float | None = None, grid: ImageGrid | None = None) -> dict:
    """The sampling of a diffraction PSF in numbers (um), with the checks that make it trustworthy."""
    lam_nw_um = pupil.wavelength_mm * UM_PER_MM * pupil.working_f_number
    rep = {"wavelength_nm": pupil.wavelength_nm, "working_f_number": pupil.working_f_number,
           "pupil_samples": pupil.n, "field_of_view_um": pupil.n * lam_nw_um,
           "nyquist_pitch_um": 0.5 * lam_nw_um, "airy_first_zero_um": 1.2196698912665045 * lam_nw_um,
           "max_phase_step_waves": _phase_step(pupil)}
    rep["pupil_sampling_ok"] = rep["max_phase_step_waves"] <= 0.5
    if padding is not None:
        m = int(round(padding * pupil.n))
        rep.update(padding=m / pupil.n, fft_size=m, pitch_um=lam_nw_um * pupil.n / m)
    if grid is not None:
        width = max(grid.shape) * grid.pitch_um
        rep.update(pitch_um=grid.pitch_um, window_um=width, window_within_period=width <= rep["field_of_view_um"])
    rep["image_sampling_ok"] = rep.get("pitch_um", 0.0) <= rep["nyquist_pitch_um"] * (1 + 1e-9)
    return rep


def psf_fft(pupil: PupilFunction, padding: float = 4.0, reference_mm: tuple[float, float] = (0.0, 0.0)
            ) -> tuple[np.ndarray, ImageGrid, dict]:
    """Diffraction PSF by FFT of the zero-padded pupil.

    Parameters
    ----------
    pupil : PupilFunction
    padding : float
        Q = FFT size / pupil size (>= 2). Pitch = lambda N_w / Q exactly as reported.
    reference_mm : (x, y)
        Sensor-plane position of the reference image point (the centre of the
        reference sphere); it lands on the grid's zero-frequency pixel.

    Returns
    -------
    psf (M, M) in 1/mm^2 (unit volume over the plane; the period holds
    ``energy_in_period`` of it), its ImageGrid, and the :func:`sampling_report`.
    """
    m = int(round(padding * pupil.n))
    if m < 2 * pupil.n:
        raise LensrtError(f"padding {padding:g} undersamples the PSF (Nyquist needs Q >= 2)",
                          hint="use padding >= 2 (4 is a good default)")
    rep = sampling_report(pupil, padding)
    buf = np.zeros((m, m), dtype=np.complex128)
    buf[:pupil.n, :pupil.n] = np.flipud(pupil.field())  # math orientation: row index grows with +py
    grid = ImageGrid.fft(m, rep["pitch_um"], reference_mm)
    psf = np.flipud(np.abs(np.fft.fftshift(np.fft.fft2(buf))) ** 2) * _normalisation(pupil)
    rep["energy_in_period"] = float(psf.sum() * grid.pixel_area_mm2)
    return psf, grid, rep


def _normalisation(pupil: PupilFunction) -> float:
    """|U|^2 du^2 / sum(intensity) is the unit-volume PSF (1/mm^2).

    By Parseval one period of the sampled PSF then holds sum(amplitude^2) /
    sum(intensity) <= 1: what is missing is the light that the aperture's
    sharp edge sends beyond the sampled band (the far wings).
    """
    du = pupil.na / pupil.wavelength_mm * (2.0 / pupil.n)
    return du * du / float(np.sum(pupil.intensity))


def psf_mft(pupil: PupilFunction, grid: ImageGrid, reference_mm: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Diffraction PSF on any grid by a matrix Fourier transform (1/mm^2, unit volume over the plane).

    Same integral as :func:`psf_fft`, evaluated at ``grid``'s pixel centres
    relative to ``reference_mm``. The grid may be coarser than Nyquist (values
    are still exact point samples) and should fit in one period n lambda N_w
    (see :func:`sampling_report`).
    """
    f = pupil.na / pupil.wavelength_mm
    px, py = pupil_coordinates(pupil.n)
    x = grid.x_mm - reference_mm[0]
    y = grid.y_mm - reference_mm[1]
    ex = np.exp(-2j * np.pi * f * np.outer(x, px[0]))
    ey = np.exp(-2j * np.pi * f * np.outer(y, py[:, 0]))
    u = ey @ pupil.field() @ ex.T
    return np.abs(u) ** 2 * _normalisation(pupil)


def psf_points(pupil: PupilFunction, x_mm: np.ndarray, y_mm: np.ndarray,
               reference_mm: tuple[float, float] = (0.0, 0.0), max_block: int = 4_000_000) -> np.ndarray:
    """The Debye PSF (1/mm^2) at arbitrary sensor-plane points (e.g. on a circle, for azimuthal profiles)."""
    f = pupil.na / pupil.wavelength_mm
    px, py = pupil_coordinates(pupil.n)
    lit = pupil.amplitude > 0
    P, qx, qy = pupil.field()[lit], px[lit], py[lit]
    x = np.ravel(np.asarray(x_mm, dtype=np.float64)) - reference_mm[0]
    y = np.ravel(np.asarray(y_mm, dtype=np.float64)) - reference_mm[1]
    out = np.empty(x.size, dtype=np.complex128)
    step = max(1, max_block // max(1, P.size))
    for s in range(0, x.size, step):
        out[s:s + step] = np.exp(-2j * np.pi * f * (np.outer(x[s:s + step], qx) + np.outer(y[s:s + step], qy))) @ P
    return (np.abs(out) ** 2 * _normalisation(pupil)).reshape(np.shape(x_mm))


def polychromatic_psf(pupils: Sequence[PupilFunction], weights: Sequence[float], grid: ImageGrid,
                      reference_mm: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Weighted sum of monochromatic PSFs on one common grid (unit volume if all light is inside).

    Each wavelength is evaluated directly at the common grid's pixels
    (:func:`psf_mft`), i.e. resampled exactly rather than interpolated, then
    summed with ``weights / sum(weights)`` (relative spectral power x
    detector response; transmission differences belong in the weights).
    """
    w = np.asarray(weights, dtype=np.float64)
    if len(pupils) == 0 or w.shape != (len(pupils),) or np.any(w < 0) or w.sum() <= 0:
        raise LensrtError("polychromatic PSF needs one non-negative weight per pupil, not all zero")
    out = np.zeros(grid.shape)
    for p, wi in zip(pupils, w / w.sum()):
        if wi > 0:
            out += wi * psf_mft(p, grid, reference_mm)
    return out


def psf_huygens(pupil: PupilFunction, grid: ImageGrid, distance_mm: float,
                reference_mm: tuple[float, float] = (0.0, 0.0), dz_mm: float = 0.0,
                max_block: int = 4_000_000) -> np.ndarray:
    """Diffraction PSF by direct Huygens-Fresnel summation over the reference sphere (1/mm^2).

    Pupil cell k sits on the reference sphere of radius ``distance_mm``
    centred on (reference, z = 0), at xi_k = ref - R d_k with d_k its ray's
    direction; image points are the pixel centres of ``grid`` on the plane
    z = ``dz_mm``. U(x) = sum_k P_k (R / r_k) exp(i k (r_k - R)), r_k = |x - xi_k|,
    normalised like :func:`psf_mft` (to which it tends when r - R is linear in x).
    """
    if not distance_mm > 0:
        raise LensrtError(f"reference sphere radius {distance_mm} mm must be positive")
    k = 2.0 * np.pi / pupil.wavelength_mm
    px, py = pupil_coordinates(pupil.n)
    lit = pupil.amplitude > 0
    c = pupil.chief_direction
    L = c[0] - pupil.na * px[lit]
    M = c[1] - pupil.na * py[lit]
    d = np.stack([L, M, np.sqrt(np.clip(1.0 - L * L - M * M, 0.0, None))], axis=1)
    P = pupil.field()[lit]
    gx, gy = grid.mesh_mm()
    delta = np.stack([gx.ravel() - reference_mm[0], gy.ravel() - reference_mm[1],
                      np.full(gx.size, float(dz_mm))], axis=1)
    R = float(distance_mm)
    out = np.empty(gx.size, dtype=np.complex128)
    step = max(1, max_block // max(1, P.size))
    for s in range(0, gx.size, step):
        dl = delta[s:s + step]
        # r - R without cancellation: (|delta|^2 + 2 R delta.d) / (r + R)
        num = np.sum(dl * dl, axis=1)[:, None] + 2.0 * R * (dl @ d.T)
        r = np.sqrt(R * R + num)
        out[s:s + step] = (np.exp(1j * k * num / (r + R)) * (R / r)) @ P
    return (np.abs(out) ** 2).reshape(grid.shape) * _normalisation(pupil)


def through_focus_psfs(pupil: PupilFunction, grid: ImageGrid, dz_mm: Sequence[float],
                       reference_mm: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """PSFs (len(dz), rows, cols) on planes moved by each ``dz_mm`` along +z (exact defocus OPD)."""
    return np.stack([psf_mft(pupil.with_defocus(float(z)), grid, reference_mm) for z in dz_mm])

