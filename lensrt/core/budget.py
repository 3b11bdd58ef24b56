"""Know the cost before paying it: memory estimates and caps checked before a job allocates.

Every job whose memory grows with a size the user gives (image pixels, map pixels, pupil grids,
sensor frames) estimates its peak memory with one of the ``estimate_*`` functions below and calls
:func:`check_memory` before it allocates. Above the limit it refuses with ONE line that gives the
estimate, the limit and the flag that raises it (``--max-memory``). The default limit is
:data:`DEFAULT_FRACTION` of the memory available now (``MemAvailable`` in ``/proc/meminfo``,
else ``os.sysconf``). Counts that grow run time rather than memory (rays, sweep rows) are capped by
:func:`check_count`, whose message names its override flag too.

The estimates are deliberately simple sums of the arrays a job holds at its peak (host and, on a
CPU device, the device arrays too); they are upper bounds within a small factor, not measurements.
This module is a floor module: it imports nothing of lensrt but :mod:`lensrt.errors`.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from ..errors import LensrtError

__all__ = ["DEFAULT_FRACTION", "MemoryEstimate", "available_memory_bytes", "default_limit_bytes", "format_bytes",
           "parse_memory", "check_memory", "check_count", "estimate_render_bytes", "estimate_bokeh_map_bytes",
           "estimate_psf_bytes", "estimate_sensor_bytes", "estimate_sweep_bytes", "MAX_RAYS_PER_POINT",
           "MAX_SWEEP_ROWS", "MAX_SIDE_PX"]

#: the default memory limit is this fraction of the memory available when the job starts
DEFAULT_FRACTION = 0.8
#: rays per field point or source above which a run needs --max-rays (about 10^10: minutes on a GPU, hours on a CPU)
MAX_RAYS_PER_POINT = 10_000_000_000
#: rows a sweep may tabulate without --max-rows
MAX_SWEEP_ROWS = 100_000
#: the largest image side any job accepts (pixels), whatever the memory
MAX_SIDE_PX = 65_536

_UNITS = {"": 1, "b": 1, "k": 1 << 10, "kb": 1000, "kib": 1 << 10, "m": 1 << 20, "mb": 1000 ** 2, "mib": 1 << 20,
          "g": 1 << 30, "gb": 1000 ** 3, "gib": 1 << 30, "t": 1 << 40, "tb": 1000 ** 4, "tib": 1 << 40}


@dataclass(frozen=True)
class MemoryEstimate:
    """A job's estimated peak memory (bytes) and what it is made of (for the message)."""

    what: str
    bytes: int
    detail: str = ""

    def describe(self) -> str:
        return f"{self.what} needs about {format_bytes(self.bytes)}" + (f" ({self.detail})" if self.detail else "")


def format_bytes(n: float) -> str:
    """``1536`` -> ``'1.5 KiB'`` (binary prefixes)."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024.0 or unit == "PiB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024.0
    return f"{n:.3g} PiB"  # pragma: no cover


def available_memory_bytes() -> int:
    """Memory available to a new job now: ``MemAvailable`` from /proc/meminfo, else free pages x page size."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 8 << 30


def default_limit_bytes() -> int:
    """:data:`DEFAULT_FRACTION` of :func:`available_memory_bytes`."""
    return int(DEFAULT_FRACTION * available_memory_bytes())


def parse_memory(text: str) -> int:
    """``"8G"``, ``"512MiB"``, ``"1.5e9"`` -> bytes (binary K/M/G/T without a B; KB/MB/GB decimal)."""
    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([a-zA-Z]*)\s*", str(text))
    unit = m.group(2).lower() if m else ""
    try:
        value = float(m.group(1)) if m else math.nan
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0) or unit not in _UNITS:
        raise LensrtError(f"--max-memory {text!r} is not a memory size", hint="e.g. 8G, 512M or 2GiB")
    return int(value * _UNITS[unit])


def check_memory(estimate: MemoryEstimate, limit_bytes: int | None = None, flag: str = "--max-memory") -> None:
    """Raise a one-line :class:`LensrtError` when ``estimate`` exceeds the limit.

    Parameters
    ----------
    estimate : MemoryEstimate
        The job's estimated peak memory.
    limit_bytes : int, optional
        The limit (bytes); default :func:`default_limit_bytes`.
    flag : str
        The option that raises the limit, named in the message.
    """
    given = limit_bytes is not None
    limit = int(limit_bytes) if given else default_limit_bytes()
    if estimate.bytes <= limit:
        return
    source = "given by " + flag if given else f"{DEFAULT_FRACTION:.0%} of the {format_bytes(available_memory_bytes())} available"
    raise LensrtError(f"{estimate.describe()}, above the limit of {format_bytes(limit)} ({source})",
                      hint=f"make the job smaller, or pass {flag} {_round_up(estimate.bytes)} if the machine has it")


def _round_up(n: int) -> str:
    gib = n / (1 << 30)
    return f"{math.ceil(gib)}G" if gib >= 1 else f"{math.ceil(n / (1 << 20))}M"


def check_count(value: float, cap: float, what: str, flag: str) -> None:
    """Raise a one-line :class:`LensrtError` when ``value`` (rays, rows, ...) exceeds ``cap``.

    ``what`` names the argument (e.g. ``"--rays 1e+15"``); ``flag`` is the option that raises ``cap``.
    """
    if value > cap:
        raise LensrtError(f"{what} is above the cap of {cap:.3g} ({value:.3g} would run for hours or never end)",
                          hint=f"give fewer, or pass {flag} {value:.3g} to run it anyway")


def _side_check(rows: int, cols: int, what: str) -> None:
    if not (1 <= rows <= MAX_SIDE_PX and 1 <= cols <= MAX_SIDE_PX):
        raise LensrtError(f"{what} of {cols} x {rows} px is outside 1..{MAX_SIDE_PX} px a side")


def estimate_render_bytes(rows: int, cols: int, n_bands: int, what: str = "a render") -> MemoryEstimate:
    """A camera-path render: per pixel the device pass (float32 bands, XYZ, hits), the host float64 spectral
    sum with a pass's float32 copy and its float64 conversion, XYZ sums and squares, and the output image
    (float32 bands and standard errors)."""
    _side_check(rows, cols, what)
    n = int(rows) * int(cols)
    # measured on a CPU render of the default scene (40 bands): 730 B per pixel of peak RSS growth
    per_px = n_bands * (4 + 8 + 4 + 4) + 3 * (4 + 4 + 8 + 8 + 8 + 8) + 4 + 64
    return MemoryEstimate(what, n * per_px, f"{cols} x {rows} px, {n_bands} spectral bands")


def estimate_bokeh_map_bytes(rows: int, cols: int, n_sources: int, batches: int, what: str = "a bokeh image"
                             ) -> MemoryEstimate:
    """A bokeh map/spot image: per pixel XYZ sums and squares (float64) per batch group, the sRGB and EXR
    outputs; per source its chief-ray set-up (a few kB)."""
    _side_check(rows, cols, what)
    n = int(rows) * int(cols)
    per_px = 3 * 8 * 4 + 3 * 4 * 2 + 3
    return MemoryEstimate(what, n * per_px + int(n_sources) * 4096,
                          f"{cols} x {rows} px, {n_sources} sources, {batches} batches")


def estimate_psf_bytes(n_fields: int, pixels: int, batches: int, pupil_samples: int, diffraction: bool,
                       n_lines: int = 1) -> MemoryEstimate:
    """PSFs: per field a ``pixels`` x ``pixels`` float64 histogram per batch (kept for the jackknife) plus
    outputs; a diffraction PSF also, per wavelength line, a complex128 pupil grid with its phase and
    amplitude (``pupil_samples`` a side, doubled up to 512 where the wavefront is steep)."""
    for flag, v in (("--pixels", pixels), ("--pupil-samples", pupil_samples)):
        if not 1 <= v <= MAX_SIDE_PX:
            raise LensrtError(f"{flag} {v} must be 1..{MAX_SIDE_PX}")
    grid = 8 * pixels * pixels * (min(int(batches), 64) + 4) * max(int(n_fields), 1)
    n = max(int(pupil_samples), 512)
    pupil = 48 * n * n * max(int(n_lines), 1) + 64 * pixels * pixels if diffraction else 0
    detail = f"{n_fields} field(s), {pixels} x {pixels} px" + (f", pupil grids of up to {n}^2 samples"
                                                                   if diffraction else "")
    return MemoryEstimate("the PSF job", grid + pupil, detail)


def estimate_sensor_bytes(rows: int, cols: int, frames: int = 1, what: str = "a sensor frame") -> MemoryEstimate:
    """Sensor frames: a dozen float64 frames (electrons, noise draws, raw DN, averages) plus ``frames``."""
    _side_check(rows, cols, what)
    n = int(rows) * int(cols)
    return MemoryEstimate(what, n * 8 * (12 + min(int(frames), 1)), f"{rows} x {cols} photosites")


def estimate_sweep_bytes(rows: int, columns: int) -> MemoryEstimate:
    """A sweep table: ``rows`` x ``columns`` Python floats in dicts (about 100 bytes a cell)."""
    return MemoryEstimate("the sweep table", int(rows) * max(int(columns), 1) * 100, f"{rows} rows")
