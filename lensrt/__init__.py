"""lensrt: a GPU-parallel, spectral, Monte Carlo raytracer for real camera lenses."""
from __future__ import annotations

__version__ = "0.1.0"

from .errors import LensrtError, PrescriptionError  # noqa: E402
from .loading import load_lens  # noqa: E402

__all__ = ["__version__", "LensrtError", "PrescriptionError", "load_lens"]
