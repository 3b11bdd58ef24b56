"""What every PSF of a run shares: lens, spectrum, focus plane, method, sampling and stopping rules.

A :class:`PsfSetup` is the *context* of a PSF-map job (:mod:`lensrt.analysis.psf.map`):
frozen and picklable, shipped once to every worker; each work item adds a
field point and a seed.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ...errors import LensrtError
from ...prescription.model import Lens
from .spectrum import SpectrumChoice, lens_spectrum

__all__ = ["PsfSetup", "METHODS", "TARGET_QUANTITIES", "make_setup"]

METHODS = ("geometric", "diffraction", "auto")
#: what --target-error measures: the RMS radius's relative standard error, or the largest
#: absolute standard error of the MTF at the reference frequencies
TARGET_QUANTITIES = ("rms", "mtf")


@dataclass(frozen=True)
class PsfSetup:
    """Settings shared by the PSFs of one run.

    Attributes
    ----------
    lens : Lens
    spectrum : SpectrumChoice
    focus : dict
        From :func:`lensrt.analysis.psf.focus.focus_plane`; ``focus["z_mm"]`` is the observation plane.
    method : {"geometric", "diffraction", "auto"}
        ``auto`` chooses per field point (see :mod:`lensrt.analysis.psf.diffraction`).
    rays : int
        Monte Carlo rays per field point (geometric); the cap of a progressive run.
    sampler : {"random", "stratified", "sobol", "r2"}
        Pupil sampler of the stream kernel (sobol and r2 are low-discrepancy).
    batches : int
        Independent batches behind every standard error.
    precision : {"float32", "float64"}
        Precision of the geometric stream kernel (diffraction wavefronts are always float64).
    pixels : int
        PSF grid size (pixels per side).
    pitch_um : float or None
        PSF grid pitch; None: chosen per field point to hold the traced light.
    max_pitch_um : float or None
        Upper bound on an automatic pitch (e.g. to sample an MTF up to 1 / (2 pitch)).
    ee_fractions : tuple of float
        Encircled-energy radii to report.
    mtf_freqs_cpmm : tuple of float
        Reference frequencies whose sagittal/tangential MTF every result carries with a standard error.
    mtf_curve_cpmm : tuple of float
        Frequencies of full MTF curves to compute with each PSF (empty: none).
    target_error, time_budget_s : float or None
        Progressive geometric runs: add rays until the error measure of ``target_quantity``
        reaches ``target_error`` or the field point has used ``time_budget_s``.
    pupil_samples, max_pupil_samples, padding, ray_grid, max_ray_grid
        Diffraction sampling: pupil grid size (doubled up to the maximum until the wavefront's
        phase step is at most half a wave), FFT padding Q, rays per side of the traced grid.
    pv_max_waves, fresnel_min
        ``auto``: geometric beyond this OPD peak-to-valley; Huygens below this Fresnel number.
    """

    lens: Lens
    spectrum: SpectrumChoice
    focus: dict
    method: str = "geometric"
    rays: int = 1 << 20
    sampler: str = "sobol"
    batches: int = 32
    precision: str = "float32"
    pixels: int = 128
    pitch_um: float | None = None
    max_pitch_um: float | None = None
    ee_fractions: tuple[float, ...] = (0.5, 0.8)
    mtf_freqs_cpmm: tuple[float, ...] = (10.0, 20.0, 40.0)
    mtf_curve_cpmm: tuple[float, ...] = ()
    target_error: float | None = None
    target_quantity: str = "rms"
    time_budget_s: float | None = None
    pupil_samples: int = 128
    max_pupil_samples: int = 512
    padding: float = 4.0
    ray_grid: int = 128
    max_ray_grid: int = 384
    pv_max_waves: float = 20.0
    fresnel_min: float = 20.0

    def __post_init__(self) -> None:
        from ...trace.sampling import SAMPLERS
        if self.method not in METHODS:
            raise LensrtError(f"unknown PSF method {self.method!r}", hint=f"use one of {', '.join(METHODS)}")
        if self.sampler not in SAMPLERS:
            raise LensrtError(f"unknown sampler {self.sampler!r}", hint=f"use one of {', '.join(SAMPLERS)}")
        if self.precision not in ("float32", "float64"):
            raise LensrtError(f"unknown precision {self.precision!r}", hint="use float32 or float64")
        if self.target_quantity not in TARGET_QUANTITIES:
            raise LensrtError(f"unknown target quantity {self.target_quantity!r}",
                              hint=f"use one of {', '.join(TARGET_QUANTITIES)}")
        if self.batches < 2:
            raise LensrtError("at least 2 batches are needed for standard errors")
        if self.rays < self.batches * 16:
            raise LensrtError(f"{self.rays} rays are too few for {self.batches} batches",
                              hint=f"use --rays {self.batches * 1024} or more")
        if not 8 <= self.pixels <= 4096:
            raise LensrtError(f"PSF grid of {self.pixels} pixels per side: use 8..4096")
        for name in ("pitch_um", "max_pitch_um", "target_error", "time_budget_s"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise LensrtError(f"{name} must be positive, not {v!r}")
        if self.padding < 2:
            raise LensrtError(f"FFT padding {self.padding:g} undersamples the PSF", hint="use 2 or more (4 is usual)")

    @property
    def plane_z_mm(self) -> float:
        return float(self.focus["z_mm"])

    @property
    def progressive(self) -> bool:
        return self.target_error is not None or self.time_budget_s is not None

    def with_(self, **changes: Any) -> "PsfSetup":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return {"lens": self.lens.name, "spectrum": self.spectrum.to_dict(), "focus": self.focus,
                "method": self.method, "rays": self.rays, "sampler": self.sampler, "batches": self.batches,
                "precision": self.precision, "pixels": self.pixels, "pitch_um": self.pitch_um,
                "target_error": self.target_error, "target_quantity": self.target_quantity,
                "time_budget_s": self.time_budget_s, "mtf_freqs_cpmm": list(self.mtf_freqs_cpmm)}


def make_setup(lens: Lens, spectrum: SpectrumChoice | None = None, focus: str | dict | None = None,
               device: str | None = None, **options: Any) -> PsfSetup:
    """A :class:`PsfSetup` with the focus plane resolved (best focus is searched once, here)."""
    from .focus import focus_plane
    spec = lens_spectrum(lens) if spectrum is None else spectrum
    foc = focus if isinstance(focus, dict) else focus_plane(lens, focus, device)
    return PsfSetup(lens, spec, foc, **options)
