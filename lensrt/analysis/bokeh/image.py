"""A bokeh image: the XYZ picture on the sensor frame, its variance, and its per-source records."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import LensrtError
from .trace import Frame

__all__ = ["BokehImage", "sensor_frame"]

# ---- the image -----------------------------------------------------------------------------

@dataclass
class BokehImage:
    """A bokeh image: CIE XYZ on a pixel grid of the sensor plane, with its error, rays and time.

    Attributes
    ----------
    sensor_xyz : ndarray (3, ny, nx)
        X, Y, Z in lux (Y = illuminance on the sensor) in *sensor orientation* (row 0 at the
        lowest y, column 0 at the lowest x); :meth:`picture` gives the upright picture.
    var_y : ndarray (ny, nx)
        Variance of Y per pixel (lux^2), by each source's noise method.
    frame : Frame
        Pixel grid on the sensor plane.
    sources : list of dict
        Per source: where it is (``object_mm``, ``depth_mm``, ``target_mm`` ...), pupil box and
        transmission with standard errors, centroid and RMS radius with standard errors, rays,
        the noise level in its disc and how it was estimated.
    rays, seconds : int, float
        Rays traced (all sources) and wall-clock seconds.
    settings : dict
        Lens, focus, light, iris, sampler, precision, pixel pitch (the metadata of the files).
    timing : dict
        Seconds spent on placement, pupil boxes and items.
    seed : int
    batch_xyz : ndarray (batches, 3, ny, nx) or None
        XYZ of each independent batch, each scaled to estimate the whole image (spots with
        batch noise only; sensor orientation): for jackknife errors of derived quantities.
    """

    sensor_xyz: np.ndarray
    var_y: np.ndarray
    frame: Frame
    sources: list
    rays: int
    seconds: float
    settings: dict
    timing: dict = field(default_factory=dict)
    seed: int = 0
    batch_xyz: np.ndarray | None = None

    # -- the one mapping between picture pixels and the sensor plane ---------------------------
    def picture(self) -> np.ndarray:
        """(rows, cols, 3) XYZ (lux), upright as a photograph: the sensor image turned by 180 deg."""
        return np.moveaxis(self.sensor_xyz[:, :, ::-1], 0, -1)

    def picture_rel_stderr(self) -> np.ndarray:
        """(rows, cols) relative standard error of Y per pixel (0 where Y = 0), upright."""
        y = self.sensor_xyz[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(y > 0, np.sqrt(np.maximum(self.var_y, 0.0)) / np.where(y > 0, y, 1.0), 0.0)
        return rel[:, ::-1]

    def picture_batches(self) -> np.ndarray | None:
        """(batches, rows, cols, 3) XYZ of each batch, upright (None unless kept)."""
        return None if self.batch_xyz is None else np.moveaxis(self.batch_xyz[:, :, :, ::-1], 1, -1)

    def sensor_xy(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """Sensor-plane (x, y) in mm of continuous picture coordinates (pixel centres at integers)."""
        f = self.frame
        x = f.x0_mm + (f.nx - 0.5 - np.asarray(col, dtype=np.float64)) * f.pitch_mm
        y = f.y0_mm + (np.asarray(row, dtype=np.float64) + 0.5) * f.pitch_mm
        return x, y

    def pixel_of(self, x_mm, y_mm) -> tuple[np.ndarray, np.ndarray]:
        """Continuous picture (row, col) of sensor-plane points (mm); inverse of :meth:`sensor_xy`."""
        f = self.frame
        col = f.nx - 0.5 - (np.asarray(x_mm, dtype=np.float64) - f.x0_mm) / f.pitch_mm
        row = (np.asarray(y_mm, dtype=np.float64) - f.y0_mm) / f.pitch_mm - 0.5
        return row, col

    # -- summaries -----------------------------------------------------------------------------
    @property
    def noise(self) -> dict:
        """Per-pixel relative standard error of Y in the discs: median over sources of each
        source's median over its disc pixels, the largest source value, the largest RMS over a
        disc (what a target error is compared with), and the method."""
        vals = [r["noise"] for r in self.sources if r.get("reached_sensor") and math.isfinite(r.get("noise", math.nan))]
        rms = [r["noise_rms"] for r in self.sources
               if r.get("reached_sensor") and math.isfinite(r.get("noise_rms", math.nan))]
        methods = sorted({r["noise_method"] for r in self.sources if r.get("reached_sensor")})
        return {"rel_stderr_median": float(np.median(vals)) if vals else None,
                "rel_stderr_max": float(np.max(vals)) if vals else None,
                "rel_stderr_rms_max": float(np.max(rms)) if rms else None,
                "method": "; ".join(methods) + (f"; disc = pixels >= 10 % of the source's 99th-percentile Y"
                                                if methods else "")}

    def digest(self) -> str:
        """SHA-256 (hex, 16 digits) of what the image holds -- pixels, variances and per-source results,
        not the timings: equal digests mean bit-identical images (benchmarks/bench_multigpu.py)."""
        import hashlib
        import json
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.sensor_xyz).tobytes())
        h.update(np.ascontiguousarray(self.var_y).tobytes())
        recs = [{k: v for k, v in r.items() if k != "seconds"} for r in self.sources]
        h.update(json.dumps(recs, sort_keys=True, default=str).encode())
        return h.hexdigest()[:16]

    def to_dict(self) -> dict:
        """JSON-ready summary (arrays go to EXR/PNG files)."""
        f = self.frame
        reached = sum(1 for r in self.sources if r.get("reached_sensor"))
        return {"settings": self.settings, "rays": int(self.rays), "seconds": float(self.seconds),
                "rays_per_second": self.rays / self.seconds if self.seconds > 0 else None, "seed": self.seed,
                "noise": self.noise, "n_sources": len(self.sources), "n_sources_on_sensor": reached,
                "frame": {"pixels": [f.nx, f.ny], "pitch_um": f.pitch_mm * 1000.0,
                          "sensor_x_mm": [f.x0_mm, f.x0_mm + f.nx * f.pitch_mm],
                          "sensor_y_mm": [f.y0_mm, f.y0_mm + f.ny * f.pitch_mm],
                          "orientation": "picture upright (sensor image turned by 180 deg)"},
                "timing": self.timing, "sources": self.sources}


# ---- sources ---------------------------------------------------------------------------------

def sensor_frame(size_mm: tuple[float, float], pixels: tuple[int, int]) -> Frame:
    """The frame of a sensor ``size_mm`` (width, height) with ``pixels`` (nx, ny), square pixels,
    centred on the axis."""
    w, h = (float(v) for v in size_mm)
    nx, ny = (int(v) for v in pixels)
    if nx < 1 or ny < 1 or not (w > 0 and h > 0):
        raise LensrtError(f"a sensor needs a positive size and pixel counts, not {w:g} x {h:g} mm at {nx} x {ny}")
    p = w / nx
    if abs(ny * p - h) > 0.01 * h + 0.5 * p:
        raise LensrtError(f"{nx} x {ny} pixels on {w:g} x {h:g} mm are not square",
                          hint=f"use {nx} x {max(1, round(h / p))} pixels")
    return Frame(nx, ny, p, -0.5 * w, -0.5 * ny * p)


