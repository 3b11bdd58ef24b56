"""What a report is made with: quality presets, the options, and the lens as the report sees it
(stopped down to ``f_number``, focused on ``object_distance_mm`` by unit focusing)."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

from ..errors import LensrtError
from ..prescription.model import Lens

__all__ = ["Quality", "QUALITIES", "ReportOptions", "prepare_lens", "default_near_focus_mm"]


def default_near_focus_mm(efl_mm: float) -> float:
    """Focus distance (mm from the first vertex) of the bokeh map and the depth-of-field table when
    the report's own focus is at infinity (both need a finite one): 20 focal lengths rounded to
    1, 2 or 5 x 10^n mm, at least 200 mm -- 1 m for a 50 mm lens, 5 m for a 250 mm one -- so the
    blur discs take a similar share of the frame whatever the focal length."""
    target = max(20.0 * abs(efl_mm), 200.0)
    e = 10.0 ** math.floor(math.log10(target))
    return min((m * e for m in (1.0, 2.0, 5.0, 10.0)), key=lambda v: abs(math.log(v / target)))


@dataclass(frozen=True)
class Quality:
    """Sample counts of one quality preset.

    Attributes
    ----------
    compare_rays, spot_rays : int
        Monte Carlo rays per field point for vignetting / relative illumination (each of two
        pupils) and per field and wavelength for the spot statistics (:func:`compare_lens`).
    psf_grid : (rows, cols)
        PSF map over the sensor, corners included.
    psf_rays, psf_pixels : int
        Rays per PSF of the map and its grid size (pixels per side).
    mtf_fields, mtf_rays, mtf_freqs : int
        Real image heights from the centre to the corner, rays per field, points per MTF curve.
    mtf_method : str
        ``auto`` (diffraction where the wavefront allows, else geometric) or ``geometric``.
    bokeh_grid : (cols, rows)
        Source positions of the bokeh map (a near and a far source in each cell).
    bokeh_width_px, bokeh_rays : int
        Bokeh map width in pixels (height from the sensor's aspect) and rays per source.
    """

    name: str
    compare_rays: int
    spot_rays: int
    psf_grid: tuple[int, int]
    psf_rays: int
    psf_pixels: int
    mtf_fields: int
    mtf_rays: int
    mtf_freqs: int
    mtf_method: str
    bokeh_grid: tuple[int, int]
    bokeh_width_px: int
    bokeh_rays: int


QUALITIES: dict[str, Quality] = {q.name: q for q in (
    Quality("draft", compare_rays=1 << 12, spot_rays=1 << 10, psf_grid=(3, 3), psf_rays=1 << 14, psf_pixels=64,
            mtf_fields=4, mtf_rays=1 << 14, mtf_freqs=33, mtf_method="geometric", bokeh_grid=(5, 3),
            bokeh_width_px=480, bokeh_rays=20_000),
    Quality("normal", compare_rays=1 << 16, spot_rays=1 << 14, psf_grid=(7, 7), psf_rays=1 << 18, psf_pixels=96,
            mtf_fields=9, mtf_rays=1 << 19, mtf_freqs=65, mtf_method="auto", bokeh_grid=(9, 6),
            bokeh_width_px=900, bokeh_rays=500_000),
    Quality("high", compare_rays=1 << 18, spot_rays=1 << 16, psf_grid=(9, 9), psf_rays=1 << 20, psf_pixels=128,
            mtf_fields=11, mtf_rays=1 << 20, mtf_freqs=81, mtf_method="auto", bokeh_grid=(9, 6),
            bokeh_width_px=1350, bokeh_rays=2_000_000),
)}


@dataclass(frozen=True)
class ReportOptions:
    """Everything ``lensrt report`` can be told (docs/tutorials/first-report.md).

    Attributes
    ----------
    quality : str
        A key of :data:`QUALITIES`.
    sensor : str
        Sensor format (``full-frame``, ``aps-c``, ... or ``WxH`` mm): PSF map, MTF reference
        frequencies and field range, bokeh frame, depth of field.
    object_distance_mm : float or None
        Focus: object plane to first vertex (mm; ``inf`` allowed); None: the lens file's own.
    f_number : float or None
        Stop the lens down to f/N (paraxial f-number at infinity); None: the file's aperture.
    coc_mm : float or None
        Circle of confusion for the depth of field (default: the format's, p. 22).
    pixel_pitch_um : float
        Pixel pitch of the system MTF (detector aperture, 4-spot OLPF, Nyquist).
    time_budget_s : float or None
        Seconds for the Monte Carlo PSF and MTF runs together: each field point gets its share
        as a progressive run (rays added in rounds, capped at the high preset's count).
    device : str or None
        Warp device (``cpu``, ``cuda``, ``cuda:N``; None: CUDA when present).
    precision : str
        Precision of the Monte Carlo stream kernels (PSF, MTF, bokeh); the analyses of the
        paraxial-against-real section are always float64.
    seed : int
        Seed of every Monte Carlo estimate.
    command_line : str
        How the report was asked for (shown on the page).
    ray_fraction : float
        Every Monte Carlo ray count of the preset (``compare_rays``, ``spot_rays``, ``psf_rays``,
        ``mtf_rays``, ``bokeh_rays``) times this fraction, in (0, 1]; grids, fields, pixels and methods
        stay the preset's. The report makes the same kernel launches at any fraction (the launch
        budget test, tests/report/test_launch_budget.py, runs the normal report this way on a CPU and
        checks it), with larger standard errors.
    """

    quality: str = "normal"
    sensor: str = "full-frame"
    object_distance_mm: float | None = None
    f_number: float | None = None
    coc_mm: float | None = None
    pixel_pitch_um: float = 4.0
    time_budget_s: float | None = None
    device: str | None = None
    precision: str = "float32"
    seed: int = 0
    command_line: str = ""
    ray_fraction: float = 1.0

    def __post_init__(self) -> None:
        from ..paraxial.photographic import sensor_format
        if self.quality not in QUALITIES:
            raise LensrtError(f"unknown quality {self.quality!r}", hint=f"use one of {', '.join(QUALITIES)}")
        sensor_format(self.sensor)  # raises a LensrtError for a bad format
        if self.object_distance_mm is not None and (math.isnan(self.object_distance_mm)
                                                    or self.object_distance_mm <= 0):
            raise LensrtError(f"focus distance {self.object_distance_mm:g} mm must be positive (inf for infinity)")
        if self.f_number is not None and not (math.isfinite(self.f_number) and self.f_number > 0):
            raise LensrtError(f"--f-number {self.f_number:g} must be a positive number")
        if self.coc_mm is not None and not (math.isfinite(self.coc_mm) and self.coc_mm > 0):
            raise LensrtError(f"--coc-mm {self.coc_mm:g} must be a positive diameter in mm")
        if not (math.isfinite(self.pixel_pitch_um) and self.pixel_pitch_um > 0):
            raise LensrtError(f"--pixel-pitch-um {self.pixel_pitch_um:g} must be positive")
        if self.time_budget_s is not None and not (math.isfinite(self.time_budget_s) and self.time_budget_s > 0):
            raise LensrtError(f"--time-budget {self.time_budget_s:g} must be a positive number of seconds")
        if not (isinstance(self.ray_fraction, (int, float)) and 0.0 < self.ray_fraction <= 1.0):
            raise LensrtError(f"ray fraction {self.ray_fraction!r} must be in (0, 1]",
                              hint="e.g. 0.01 for a hundredth of the preset's rays")
        if self.precision not in ("float32", "float64"):
            raise LensrtError(f"unknown precision {self.precision!r}", hint="use float32 or float64")

    @property
    def preset(self) -> Quality:
        """The quality preset, its ray counts times ``ray_fraction`` (at least 64 rays each)."""
        q = QUALITIES[self.quality]
        if self.ray_fraction == 1.0:
            return q
        counts = ("compare_rays", "spot_rays", "psf_rays", "mtf_rays", "bokeh_rays")
        return replace(q, **{k: max(64, int(getattr(q, k) * self.ray_fraction)) for k in counts})

    def with_(self, **changes: Any) -> "ReportOptions":
        return replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["preset"] = asdict(self.preset)
        return d


def prepare_lens(lens: Lens, options: ReportOptions) -> tuple[Lens, list[str]]:
    """The lens the report analyses, and what was changed (sentences for the page).

    ``f_number``: the aperture becomes an image-space f-number at infinity, N = f/D (only
    stopping down: the clear apertures of the file stay as they are). ``object_distance_mm``:
    the object plane moves there and the image surface moves back with it by unit focusing
    (Field Guide p. 12), the extension e(D) - e(file) from first-order data at the primary
    wavelength -- the whole lens moved out, in the lens frame of the first vertex.
    """
    from ..prescription.model import Aperture
    notes = []
    if options.f_number is not None:
        from ..paraxial.fnumber import check_f_number
        n_full = check_f_number(lens, options.f_number)
        lens = lens.replace(aperture=Aperture("image_fno", float(options.f_number)))
        notes.append(f"stopped down from f/{n_full:.3g} to f/{options.f_number:g} (the stop's radius scaled; "
                     "clear apertures as in the file)")
    d = options.object_distance_mm
    if d is not None and not (math.isinf(d) and math.isinf(lens.object_distance_mm)) \
            and d != lens.object_distance_mm:
        if not lens.focus.is_unit:
            return _focus_by_mechanism(lens, float(d), notes)
        from ..analysis.bokeh.focus import focus_lens
        f = focus_lens(lens, d)
        last = lens.n_surfaces - 1
        shift = f.sensor_z_mm - lens.image_z_mm
        lens = lens.replace_surface(last, thickness_mm=lens.surfaces[last].thickness_mm + shift)
        lens = lens.replace(object_distance_mm=float(d))
        where = "infinity" if math.isinf(d) else f"{d / 1000.0:g} m"
        notes.append(f"focused at {where} from the first vertex by unit focusing: the image surface moved "
                     f"{shift:+.4f} mm (extension {f.extension_mm:.4f} mm from infinity focus)")
    return lens, notes


def _focus_by_mechanism(lens, distance_mm: float, notes: list[str]):
    """Focus a lens that declares a focus group or floating groups with that mechanism (real best focus)."""
    from ..analysis.focusing import focus_at
    sol = focus_at(lens, distance_mm)
    where = "infinity" if math.isinf(distance_mm) else f"{distance_mm / 1000.0:g} m"
    notes.append(f"focused at {where} from the first vertex by the lens's own mechanism ({sol.mechanism}): "
                 f"travel {sol.travel:.6g} {sol.travel_unit}, real best focus on the image surface")
    return sol.lens, notes
