"""A regular image-plane grid of square pixels: where a sampled PSF lives.

Arrays are (row, col) with row 0 at the top (scikit-image); the sensor plane
(x_mm, y_mm) is centred on the optical axis with +y up. :meth:`ImageGrid.pixel_of`
and :meth:`ImageGrid.position_of` are the only maps between the two that the
PSF code uses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from ..units import UM_PER_MM

__all__ = ["ImageGrid"]


@dataclass(frozen=True)
class ImageGrid:
    """Pixel centres ``x = x0_mm + col * pitch``, ``y = y0_mm - row * pitch`` (mm).

    Attributes
    ----------
    shape : (int, int)
        (rows, cols).
    pitch_um : float
        Pixel pitch (um), the same along x and y.
    x0_mm, y0_mm : float
        Sensor-plane position of the centre of pixel (row 0, col 0), i.e. the
        top-left pixel (mm).
    """

    shape: tuple[int, int]
    pitch_um: float
    x0_mm: float = 0.0
    y0_mm: float = 0.0

    def __post_init__(self) -> None:
        rows, cols = (int(v) for v in self.shape)
        if rows < 1 or cols < 1:
            raise LensrtError(f"an image grid needs at least one pixel, not shape {self.shape}")
        if not (math.isfinite(self.pitch_um) and self.pitch_um > 0):
            raise LensrtError(f"grid pitch {self.pitch_um!r} um must be a positive number")
        object.__setattr__(self, "shape", (rows, cols))

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def centred(cls, shape: tuple[int, int] | int, pitch_um: float,
                centre_mm: tuple[float, float] = (0.0, 0.0)) -> "ImageGrid":
        """Grid whose pixel centres are symmetric about ``centre_mm`` (even sizes: centre on a corner)."""
        rows, cols = (shape, shape) if isinstance(shape, (int, np.integer)) else shape
        p = pitch_um / UM_PER_MM
        return cls((int(rows), int(cols)), float(pitch_um),
                   centre_mm[0] - 0.5 * (cols - 1) * p, centre_mm[1] + 0.5 * (rows - 1) * p)

    @classmethod
    def fft(cls, n: int, pitch_um: float, centre_mm: tuple[float, float] = (0.0, 0.0)) -> "ImageGrid":
        """The grid of an ``n`` x ``n`` FFT image shown with row 0 at the top.

        ``centre_mm`` falls on the centre of pixel (row ``n - 1 - n//2``, col ``n//2``):
        the zero-frequency sample of an ``fftshift``-ed array after a vertical flip.
        """
        p = pitch_um / UM_PER_MM
        return cls((n, n), float(pitch_um), centre_mm[0] - (n // 2) * p, centre_mm[1] + (n - 1 - n // 2) * p)

    # -- coordinates ---------------------------------------------------------------------------
    @property
    def pitch_mm(self) -> float:
        return self.pitch_um / UM_PER_MM

    @property
    def x_mm(self) -> np.ndarray:
        """x of each column's pixel centres (mm), shape (cols,)."""
        return self.x0_mm + self.pitch_mm * np.arange(self.shape[1])

    @property
    def y_mm(self) -> np.ndarray:
        """y of each row's pixel centres (mm), shape (rows,); decreasing (+y up)."""
        return self.y0_mm - self.pitch_mm * np.arange(self.shape[0])

    def mesh_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of every pixel centre (mm), each of shape ``shape``."""
        return np.meshgrid(self.x_mm, self.y_mm)

    @property
    def centre_mm(self) -> tuple[float, float]:
        """Sensor-plane position of the grid's geometric centre (mm)."""
        return (float(self.x0_mm + 0.5 * (self.shape[1] - 1) * self.pitch_mm),
                float(self.y0_mm - 0.5 * (self.shape[0] - 1) * self.pitch_mm))

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) pixel-edge bounds, for ``imshow(extent=...)`` (mm)."""
        h = 0.5 * self.pitch_mm
        return (float(self.x0_mm - h), float(self.x_mm[-1] + h), float(self.y_mm[-1] - h), float(self.y0_mm + h))

    @property
    def pixel_area_mm2(self) -> float:
        return self.pitch_mm ** 2

    def pixel_of(self, x_mm: np.ndarray, y_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Continuous (row, col) of sensor-plane points; pixel (r, c) covers [r - 0.5, r + 0.5)."""
        col = (np.asarray(x_mm, dtype=np.float64) - self.x0_mm) / self.pitch_mm
        row = (self.y0_mm - np.asarray(y_mm, dtype=np.float64)) / self.pitch_mm
        return row, col

    def position_of(self, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor-plane (x_mm, y_mm) of continuous (row, col) pixel coordinates."""
        return (self.x0_mm + np.asarray(col, dtype=np.float64) * self.pitch_mm,
                self.y0_mm - np.asarray(row, dtype=np.float64) * self.pitch_mm)

    def to_dict(self) -> dict:
        return {"shape": list(self.shape), "pitch_um": self.pitch_um, "x0_mm": self.x0_mm,
                "y0_mm": self.y0_mm, "extent_mm": list(self.extent_mm)}
