"""Ray status codes, shared by the Warp kernels, the NumPy reference and the analyses.

GPU kernels cannot raise: every ray ends with one of these codes plus the
0-based index of the surface where it stopped (``-1`` for an OK ray; the
image surface has index ``n_surfaces``). Analyses count the codes
(:func:`count_statuses`); no ray ever carries a NaN instead.
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

__all__ = ["RayStatus", "OK", "MISSED", "VIGNETTED", "TIR", "NO_CONVERGE", "INVALID",
           "STATUS_NAMES", "N_STATUS", "describe_status", "count_statuses", "APERTURE_TOLERANCE",
           "GRAZING_INCIDENCE_DEG", "GRAZING_COS"]


class RayStatus(IntEnum):
    """Why a ray stopped. The surface index travels beside the code."""

    #: reached the image surface
    OK = 0
    #: no intersection with a surface (beyond a conic's extent, a plane it runs parallel to,
    #: a surface it would meet on the far branch, or one it could meet only from behind,
    #: from the medium after it)
    MISSED = 1
    #: outside a surface's clear semi-diameter, or blocked by the iris / central obstruction
    VIGNETTED = 2
    #: total internal reflection at a surface
    TIR = 3
    #: the Newton iteration on an aspheric sag did not converge
    NO_CONVERGE = 4
    #: bad input: a zero or non-finite direction, or an index that is not real at this wavelength
    INVALID = 5


OK, MISSED, VIGNETTED, TIR, NO_CONVERGE, INVALID = (int(s) for s in RayStatus)
STATUS_NAMES: tuple[str, ...] = tuple(s.name for s in RayStatus)
N_STATUS = len(STATUS_NAMES)

#: a ray that meets a surface more steeply than this (angle of incidence, deg), or leaves it
#: more steeply (angle of refraction: just short of total internal reflection, where
#: dI'/dI = n cos I / (n' cos I') diverges), is *grazing*: its intersection or refraction is
#: ill-conditioned, so rounding grows there (float32 rays may then differ from float64 beyond
#: the documented bound); results flag such rays
GRAZING_INCIDENCE_DEG = 80.0
GRAZING_COS = math.cos(math.radians(GRAZING_INCIDENCE_DEG))

#: clear apertures (semi-diameters, stop radius, iris) are tested as
#: r <= sd * (1 + APERTURE_TOLERANCE), so that a ray aimed exactly at an edge (the
#: marginal ray that defined an automatic semi-diameter) passes in both precisions
APERTURE_TOLERANCE = 1e-6


def describe_status(status: int, surface: int, n_surfaces: int | None = None) -> str:
    """``"OK"``, ``"VIGNETTED(surface 3)"``, ... (surfaces numbered from 1, the image as IMG)."""
    name = STATUS_NAMES[int(status)] if 0 <= int(status) < N_STATUS else f"UNKNOWN({int(status)})"
    if int(status) == OK or surface < 0:
        return name
    where = "IMG" if n_surfaces is not None and surface >= n_surfaces else f"surface {surface + 1}"
    return f"{name}({where})"


def count_statuses(status: np.ndarray) -> dict[str, int]:
    """Number of rays per status name (every name present, zeros included)."""
    counts = np.bincount(np.asarray(status, dtype=np.int64).ravel(), minlength=N_STATUS)
    return {name: int(counts[i]) for i, name in enumerate(STATUS_NAMES)}
