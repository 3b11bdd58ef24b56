"""Diffraction PSFs on real rays, and the choice between FFT, Huygens and geometric.

For one field point (:func:`diffraction_psf_at`): trace the wavefront at each
wavelength of the spectrum (:func:`lensrt.analysis.wave.wavefront.trace_wavefronts`,
float64 store kernel), grid it into a pupil function, and transform:

* **FFT** (``diffraction-fft``): one wavelength -- the zero-padded FFT
  (padding Q, pitch lambda N_w / Q), cropped to the central ``pixels`` square;
* **MFT** (``diffraction-mft``): several wavelengths -- each evaluated by the
  matrix Fourier transform on one common grid (pitch lambda_min N_w / Q, so
  every wavelength is at or above Nyquist) and summed with the spectral weights;
* **Huygens** (``diffraction-huygens``): direct summation of spherical wavelets
  from the reference sphere (exact distances), each wavelength on the common
  grid -- used where the Debye (Fourier) picture fails.

Sampling is adapted before anything is transformed: the pupil grid starts at
``setup.pupil_samples`` cells and doubles (up to ``max_pupil_samples``) until
the OPD changes by at most half a wave between neighbouring cells; the ray
grid starts at ``setup.ray_grid`` rays per side and grows (x1.5, up to
``max_ray_grid``) until the linear interpolation error estimate
(max |second difference of the OPD| / 8) is below 0.02 waves.

Which method when (``method="auto"``, reported as ``metadata["method"]`` with
``metadata["method_reason"]``):

1. **geometric** when the OPD peak-to-valley exceeds ``pv_max_waves`` (20 waves)
   or the pupil cannot be sampled at half a wave per cell with
   ``max_pupil_samples`` cells: aberrations dominate diffraction and the ray
   histogram is the right PSF (and far cheaper);
2. **Huygens** when the Fresnel number a^2 / (lambda R) = NA^2 R / lambda of the
   reference sphere is below ``fresnel_min`` (20): the Debye approximation behind
   the Fourier methods needs N_F >> 1 (Li & Wolf 1981);
3. **FFT** (one wavelength) or **MFT** (several) otherwise.

``method="diffraction"`` skips rule 1 (the sampling limits are then reported,
not acted on).
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ...errors import LensrtError
from ...units import NM_PER_MM, UM_PER_MM
from ..wave.propagation import psf_fft, psf_huygens, psf_mft, sampling_report
from ..fields import FieldSpec
from ..grid import ImageGrid
from .result import PsfResult, diffraction_result
from .setup import PsfSetup
from .geometric import FieldGeometry, add_mtf_estimates, prepare_field
from ..pupil_rays import chief_rays_at_many, field_xy_of
from ..wave.wavefront import pupil_function_from_wavefront, trace_wavefronts_many

__all__ = ["diffraction_psf_at", "choose_method", "WavefrontSet", "wavefront_sets", "wavefront_chief_wavelengths"]

#: ray-grid interpolation error goal (waves) and pupil phase-step limit (waves per cell)
_INTERP_GOAL_WAVES = 0.02
_PHASE_STEP_MAX = 0.5


class WavefrontSet:
    """Traced wavefronts of one field point with the ray grid adapted to the interpolation goal."""

    def __init__(self, setup: PsfSetup, geom: FieldGeometry, device: str | None = None, chief=None) -> None:
        got = wavefront_sets(setup, [geom], device, None if chief is None else [chief])[0]
        if isinstance(got, LensrtError):
            raise got
        self._fill(got.wavefronts, got.ray_grid, got.interp_error_waves)

    @classmethod
    def of(cls, wfs: list, ray_grid: int, interp_error_waves: float) -> WavefrontSet:
        """The set of wavefronts already traced on a ``ray_grid`` x ``ray_grid`` grid."""
        self = cls.__new__(cls)
        self._fill(wfs, ray_grid, interp_error_waves)
        return self

    def _fill(self, wfs: list, m: int, err: float) -> None:
        self.wavefronts = wfs
        self.ray_grid = m
        self.interp_error_waves = err
        self.pv_waves = max(w.opd_pv_waves for w in wfs)
        self.rms_waves = max(w.opd_rms_waves for w in wfs)
        sph = wfs[0].sphere
        self.sphere = sph
        r = abs(sph.radius_mm)
        self.fresnel_number = min(w.na_real ** 2 * r / (w.wavelength_nm / NM_PER_MM) for w in wfs) \
            if math.isfinite(r) else math.inf
        self.rays = sum(w.rays for w in wfs) * 2
        self.spot_half_mm = max(w.spot_half_mm for w in wfs)

    def pupils(self, n: int):
        out = [pupil_function_from_wavefront(w, n) for w in self.wavefronts]
        return [p for p, _ in out], [i for _, i in out]


def wavefront_sets(setup: PsfSetup, geoms: list[FieldGeometry], device: str | None = None,
                   chiefs: list | None = None) -> list:
    """The :class:`WavefrontSet` of each field geometry, the same as one field at a time: each round of the
    ray-grid adaptation traces the fields still short of the interpolation goal together (two launches a
    round, :func:`~lensrt.analysis.wave.wavefront.trace_wavefronts_many`). ``chiefs``: the fields'
    :func:`~lensrt.analysis.pupil_rays.chief_rays_at_many` entries when already found. An entry of the answer
    is the field's WavefrontSet or the :class:`LensrtError` building it raises."""
    spec = setup.spectrum
    if chiefs is None:  # the chief rays do not depend on the grid: traced once for every field
        chiefs = chief_rays_at_many(setup.lens, [g.fp for g in geoms], wavefront_chief_wavelengths(setup),
                                    setup.plane_z_mm, device)
    out: list = [c if isinstance(c, LensrtError) else None for c in chiefs]
    grid = {k: int(setup.ray_grid) for k in range(len(geoms)) if out[k] is None}
    while grid:
        keys = sorted(grid)
        traced = trace_wavefronts_many(setup.lens, [(geoms[k].fp, geoms[k].box, grid[k], chiefs[k]) for k in keys],
                                       spec.lines_nm, setup.plane_z_mm, device)
        for k, wfs in zip(keys, traced):
            m = grid.pop(k)
            if isinstance(wfs, LensrtError):
                out[k] = wfs
                continue
            err = max(w.interp_error_waves for w in wfs)
            if err <= _INTERP_GOAL_WAVES or m >= setup.max_ray_grid:
                out[k] = WavefrontSet.of(wfs, m, err)
            else:
                grid[k] = min(int(setup.max_ray_grid), int(round(m * 1.5)))
    return out


def wavefront_chief_wavelengths(setup: PsfSetup) -> list[float]:
    """The wavelengths (nm) of a field's chief rays for :class:`WavefrontSet`: the primary, then the lines."""
    return [float(setup.spectrum.primary_nm)] + [float(v) for v in setup.spectrum.lines_nm]


def choose_method(setup: PsfSetup, wset: WavefrontSet) -> tuple[str, str]:
    """(method, reason) for ``setup.method`` and a traced wavefront (module docstring)."""
    if setup.method == "geometric":
        return "geometric", "asked for"
    if setup.method == "auto" and wset.pv_waves > setup.pv_max_waves:
        return "geometric", (f"OPD peak-to-valley {wset.pv_waves:.3g} waves > {setup.pv_max_waves:g}: "
                             "aberrations dominate diffraction")
    if setup.method == "auto" and setup.pitch_um is None:
        lam_n = min(w.wavelength_nm / NM_PER_MM * 0.5 / w.na for w in wset.wavefronts)
        if not window_pitch_um(setup, wset, lam_n)[1]:
            return "geometric", (f"the geometric spot (half-width {wset.spot_half_mm * UM_PER_MM:.3g} um) does "
                                 f"not fit {setup.pixels} pixels at the Nyquist pitch: aberrations dominate")
    if wset.fresnel_number < setup.fresnel_min:
        return "huygens", f"Fresnel number {wset.fresnel_number:.3g} < {setup.fresnel_min:g}: Debye fails"
    if len(wset.wavefronts) == 1:
        return "fft", (f"OPD peak-to-valley {wset.pv_waves:.3g} waves, Fresnel number "
                       f"{wset.fresnel_number:.3g}: Fourier (Debye) optics, one wavelength")
    return "mft", (f"OPD peak-to-valley {wset.pv_waves:.3g} waves, Fresnel number {wset.fresnel_number:.3g}: "
                   "Fourier (Debye) optics, wavelengths summed on a common grid")


def window_pitch_um(setup: PsfSetup, wset: WavefrontSet, lam_n_mm: float) -> tuple[float, bool]:
    """(pitch um, fits): lambda_min N_w / Q unless the grid of ``setup.pixels`` must be coarser to hold the
    geometric spot (1.15 x its half-width plus 3 lambda N of diffraction margin on each side); ``fits`` is
    False when even the Nyquist pitch lambda N / 2 cannot hold it (the PSF is then undersampled)."""
    if setup.pitch_um is not None:
        return float(setup.pitch_um), True
    need_mm = 2.0 * (1.15 * wset.spot_half_mm + 3.0 * lam_n_mm)
    pitch_mm = lam_n_mm / setup.padding
    if setup.pixels * pitch_mm >= need_mm:
        return pitch_mm * UM_PER_MM, True
    return need_mm / setup.pixels * UM_PER_MM, need_mm / setup.pixels <= 0.5 * lam_n_mm * (1 + 1e-9)


def sampled_pupils(setup: PsfSetup, wset: WavefrontSet):
    n = int(setup.pupil_samples)
    while True:
        pupils, infos = wset.pupils(n)
        step = max(sampling_report(p)["max_phase_step_waves"] for p in pupils)
        if step <= _PHASE_STEP_MAX or n >= setup.max_pupil_samples:
            return pupils, infos, n, step
        n = min(int(setup.max_pupil_samples), 2 * n)


def diffraction_psf_at(setup: PsfSetup, f: FieldSpec, device: str | None = None,
                       geom: FieldGeometry | None = None, wset: WavefrontSet | None = None,
                       method: str | None = None, reason: str = "") -> PsfResult:
    """The diffraction PSF of field ``f`` by FFT, MFT or Huygens (module docstring).

    ``method`` ("fft", "mft", "huygens") overrides the choice; by default
    :func:`choose_method` decides (and may answer "geometric": then call
    :func:`lensrt.analysis.psf.geometric.geometric_psf_at` instead).
    """
    t0 = time.perf_counter()
    geom = prepare_field(setup, f, device) if geom is None else geom
    wset = WavefrontSet(setup, geom, device) if wset is None else wset
    if method is None:
        method, reason = choose_method(setup, wset)
        if method == "geometric":
            raise LensrtError(f"field {f.label}: {reason}; this is a case for the geometric PSF")
    pupils, infos, n, step = sampled_pupils(setup, wset)
    spec = setup.spectrum
    weights = np.asarray(spec.line_weights)
    q = setup.padding
    ref = (float(wset.sphere.centre_mm[0]), float(wset.sphere.centre_mm[1]))
    lam_n_min = min(p.wavelength_mm * p.working_f_number for p in pupils)
    pixels = int(setup.pixels)
    pitch_um, fits = window_pitch_um(setup, wset, lam_n_min)
    sampling = []
    if method == "fft" and not math.isclose(pitch_um, lam_n_min * UM_PER_MM / q, rel_tol=1e-12):
        method = "mft"  # a pitch other than lambda N / Q: evaluate on that grid instead
    if method == "fft":
        psf, fgrid, rep = psf_fft(pupils[0], q, ref)
        sampling.append(rep)
        m = fgrid.shape[0]
        if pixels < m:  # crop the central pixels x pixels; Q stays on the same (zero-frequency) pixel
            r0 = (m - 1 - m // 2) - (pixels - 1 - pixels // 2)
            c0 = m // 2 - pixels // 2
            psf = psf[r0:r0 + pixels, c0:c0 + pixels]
            grid = ImageGrid.fft(pixels, fgrid.pitch_um, ref)
        else:
            grid = fgrid
        kind = "diffraction-fft"
    else:
        grid = ImageGrid.fft(pixels, pitch_um, ref)
        psf = np.zeros(grid.shape)
        for p, w in zip(pupils, weights / weights.sum()):
            if w <= 0:
                continue
            sampling.append(sampling_report(p, grid=grid))
            if method == "huygens":
                psf += w * psf_huygens(p, grid, abs(wset.sphere.radius_mm), ref)
            else:
                psf += w * psf_mft(p, grid, ref)
        kind = "diffraction-huygens" if method == "huygens" else "diffraction-mft"
    seconds = time.perf_counter() - t0
    na_eq = float(infos[0]["equivalent_na"])
    meta = {"method": kind.replace("diffraction-", ""), "method_reason": reason, "focus": setup.focus,
            "spectrum": spec.to_dict(), "field": f.to_dict(), "reference_sphere": wset.sphere.to_dict(),
            "fresnel_number": wset.fresnel_number if math.isfinite(wset.fresnel_number) else None,
            "opd_pv_waves": wset.pv_waves, "opd_rms_waves": wset.rms_waves, "ray_grid": wset.ray_grid,
            "ray_interp_error_waves": wset.interp_error_waves, "pupil_samples": n,
            "max_phase_step_waves": step, "pupil_sampling_ok": step <= _PHASE_STEP_MAX,
            "padding": q, "window_holds_spot": fits, "working_f_number": 0.5 / na_eq if na_eq > 0 else None,
            "working_f_number_definition": "1 / (2 NA) of the circle with the clear pupil's area in "
                                           "direction-cosine space (first wavelength)",
            "grid_working_f_number": pupils[0].working_f_number,
            "sampling": sampling, "gridding": [{k: v for k, v in i.items() if k != "zernike_mm"} for i in infos],
            "precision": "float64", "device": device or "auto"}
    result = diffraction_result(psf, grid, kind, wavelengths_nm=spec.lines_nm, weights=spec.line_weights,
                                reference_mm=ref, field_xy=field_xy_of(setup.lens, f.hx, f.hy),
                                field_kind=setup.lens.fields.kind, samples=wset.rays, seconds=seconds,
                                ee_fractions=setup.ee_fractions, metadata=meta)
    if method == "huygens":  # no Fourier shortcut: the MTF of the sampled window
        add_mtf_estimates(result, None, setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm)
    else:
        result.metadata["mtf_from"] = "weighted sum of each wavelength's OTF (pupil autocorrelation)"
        add_mtf_estimates(result, None, setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm,
                          pupil_mtf_function(pupils, weights, q, ref))
    return replace(result, seconds=time.perf_counter() - t0)


#: the largest fine pupil grid (cells a side) an OTF is taken on: (2 x this)^2 complex FFTs per wavelength
OTF_MAX_FINE_CELLS = 256


def _otf_field(pupil) -> tuple[np.ndarray, int]:
    """The complex pupil field the OTF autocorrelates, and its cells a side.

    With a fine mask (:attr:`PupilFunction.fine_mask`): the cell's amplitude without its clear fraction and
    its phase on every clear sub-cell -- a hard, supersampled edge (at most :data:`OTF_MAX_FINE_CELLS` a side).
    Without one: the cell field itself (a soft edge where the amplitude carries clear fractions).
    """
    from ..wave.pupil_grid import clear_fraction
    n = pupil.n
    fine = pupil.fine_mask
    if fine is None:
        return pupil.field(), n
    s = fine.shape[0] // n
    while s > 1 and n * s > OTF_MAX_FINE_CELLS:  # coarsen the sub-cells (any power of two divides s here)
        if s % 2:
            s = 1
            break
        fine = fine.reshape(n * s // 2, 2, n * s // 2, 2).mean(axis=(1, 3)) >= 0.5  # majority of 2 x 2
        s //= 2
    if s == 1:
        return pupil.field(), n
    frac = clear_fraction(fine, n)
    a_cell = np.where(frac > 0, pupil.amplitude / np.where(frac > 0, frac, 1.0), 0.0)
    cell = a_cell * np.exp(2j * np.pi * pupil.opd_waves)
    return np.repeat(np.repeat(cell, s, axis=0), s, axis=1) * fine, n * s


def pupil_otf(pupil) -> tuple[np.ndarray, float]:
    """The OTF of a pupil function on its shift grid: (C (2m, 2m) complex, cycles/mm per cell).

    OTF(nu) = sum_p P(p) P*(p + nu lambda / NA) / sum |P|^2 (the PSF's Fourier transform about the
    reference point), by FFT autocorrelation with 2x padding (no wrap-around), on the pupil's fine grid of
    m = n s cells with its hard edge where it has one (:func:`_otf_field`); index [m + ky, m + kx] holds the
    shift (kx, ky) cells, +y up. One cell is 2 NA / (m lambda) cycles/mm.
    """
    field, m = _otf_field(pupil)
    pm = np.zeros((2 * m, 2 * m), dtype=np.complex128)
    pm[:m, :m] = np.flipud(field)  # math orientation: row index grows with +py
    f = np.fft.fft2(pm)
    acf = np.fft.ifft2(np.abs(f) ** 2)  # acf[d] = sum_p P*(p) P(p + d) = conj(C(d)) = C(-d)
    c = np.fft.fftshift(acf[::-1, ::-1])  # C(d) = acf[-d]; after the shift, index m is d = 0
    c = np.roll(c, 1, axis=(0, 1))
    return c / c[m, m].real, 2.0 * pupil.na / (m * pupil.wavelength_mm)


def pupil_mtf_function(pupils, weights, padding: float, reference_mm: tuple[float, float]):
    """``fn(freqs_cpmm, angle_rad) -> MTF``: |sum_i w_i OTF_i(nu)| from each wavelength's pupil
    autocorrelation (exact for the sampled pupil: no PSF window, no wrap-around), cubic interpolation
    between shift cells. The cubic-spline coefficients of each OTF are computed once for every call
    (``map_coordinates`` would filter the whole OTF again per call; the numbers are the same)."""
    from scipy.ndimage import map_coordinates, spline_filter
    otfs = []
    for p in pupils:
        c, cell = pupil_otf(p)
        otfs.append((spline_filter(c.real, 3, output=np.float64, mode="constant"),
                     spline_filter(c.imag, 3, output=np.float64, mode="constant"), cell))
    w = np.asarray(weights, dtype=np.float64) / np.sum(weights)

    def fn(freqs: np.ndarray, angle: float) -> np.ndarray:
        f = np.asarray(freqs, dtype=np.float64)
        total = np.zeros(f.size, dtype=np.complex128)
        for wi, (cr, ci, cell) in zip(w, otfs):
            if wi <= 0:
                continue
            m = cr.shape[0] // 2
            kx, ky = f * math.cos(angle) / cell + m, f * math.sin(angle) / cell + m
            coords = np.vstack([ky, kx])
            v = (map_coordinates(cr, coords, order=3, mode="constant", prefilter=False)
                 + 1j * map_coordinates(ci, coords, order=3, mode="constant", prefilter=False))
            total += wi * v
        return np.clip(np.abs(total), 0.0, None)
    return fn
