"""How a lens focuses: the mechanism a lens file declares (data only; the solver is
:mod:`lensrt.analysis.focusing`).

Three kinds (Field Guide p. 12-13):

* ``unit`` -- the whole lens moves; in the lens frame the image surface moves back
  (the last thickness grows by the extension e). The default.
* ``group`` -- one group moves inside the lens: the thicknesses of ``gaps`` change
  by ``sign * t`` for a travel t (mm); e.g. a group between gaps 10 and 13 moving
  toward the image is ``gaps = (10, 13)``, ``signs = (+1, -1)``. The image surface
  stays put.
* ``floating`` -- several gaps move on a cam: their thicknesses are tabulated at
  object distances (``distances_mm``, e.g. a patent's infinity and close-focus
  columns) and interpolated linearly in the object vergence 1/s between the
  tabulated positions (extrapolated past the last one). The image surface stays put.

Surface indices are 0-based here (``gaps[k]`` is the thickness after surface
``gaps[k]``); files write 1-based surface numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import PrescriptionError

__all__ = ["FOCUS_KINDS", "FocusMechanism", "UNIT_FOCUS"]

FOCUS_KINDS = ("unit", "group", "floating")


@dataclass(frozen=True)
class FocusMechanism:
    """A focus mechanism (module docstring); lengths in mm, surface indices 0-based."""

    kind: str = "unit"
    gaps: tuple[int, ...] = ()
    signs: tuple[float, ...] = ()
    distances_mm: tuple[float, ...] = ()
    thickness_mm: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in FOCUS_KINDS:
            raise PrescriptionError(f"unknown focus type {self.kind!r}", hint=f"use one of {', '.join(FOCUS_KINDS)}")
        gaps = tuple(int(g) for g in self.gaps)
        object.__setattr__(self, "gaps", gaps)
        if self.kind == "unit":
            if gaps or self.signs or self.distances_mm or self.thickness_mm:
                raise PrescriptionError("unit focusing takes no gaps, signs or table",
                                        hint="give type = \"group\" or \"floating\" for a moving group")
            return
        if not gaps:
            raise PrescriptionError(f"{self.kind} focusing needs the gaps that change (surface numbers)")
        if len(set(gaps)) != len(gaps) or any(g < 0 for g in gaps):
            raise PrescriptionError(f"focus gaps {[g + 1 for g in gaps]} must be distinct surface numbers")
        if self.kind == "group":
            signs = tuple(float(s) for s in self.signs)
            if len(signs) != len(gaps) or any(s == 0.0 or not math.isfinite(s) for s in signs):
                raise PrescriptionError(f"group focusing needs one non-zero sign per gap ({len(gaps)} gaps, "
                                        f"{len(signs)} signs)", hint="e.g. gaps = [10, 13], signs = [1, -1]")
            object.__setattr__(self, "signs", signs)
            return
        self._check_table()

    def _check_table(self) -> None:
        d = tuple(float(v) for v in self.distances_mm)
        rows = tuple(tuple(float(v) for v in row) for row in self.thickness_mm)
        if len(d) < 2 or len(rows) != len(d):
            raise PrescriptionError(f"floating focus needs at least two tabulated positions, one row of gap "
                                    f"thicknesses per distance ({len(d)} distances, {len(rows)} rows)")
        if any(len(r) != len(self.gaps) for r in rows):
            raise PrescriptionError(f"each floating-focus row must give {len(self.gaps)} thicknesses "
                                    f"(one per gap)")
        if any(not (v > 0.0) for v in d) or any(not math.isfinite(v) for r in rows for v in r):
            raise PrescriptionError("floating-focus distances must be positive (inf allowed) and thicknesses finite")
        vergence = [0.0 if math.isinf(v) else 1.0 / v for v in d]
        if any(b <= a for a, b in zip(vergence, vergence[1:])):
            raise PrescriptionError("floating-focus distances must run from far to near without repeats",
                                    hint="e.g. distances_mm = [inf, 2000, 700]")
        object.__setattr__(self, "distances_mm", d)
        object.__setattr__(self, "thickness_mm", rows)

    @property
    def is_unit(self) -> bool:
        return self.kind == "unit"

    @property
    def vergences_per_mm(self) -> np.ndarray:
        """1/s of the tabulated floating positions (0 for infinity)."""
        return np.array([0.0 if math.isinf(v) else 1.0 / v for v in self.distances_mm])

    def floating_thickness_mm(self, vergence_per_mm: float) -> np.ndarray:
        """Gap thicknesses of a floating mechanism at object vergence 1/s, piecewise linear (extrapolated)."""
        v = self.vergences_per_mm
        table = np.asarray(self.thickness_mm, dtype=np.float64)
        k = int(np.clip(np.searchsorted(v, vergence_per_mm) - 1, 0, len(v) - 2))
        w = (vergence_per_mm - v[k]) / (v[k + 1] - v[k])
        return table[k] + w * (table[k + 1] - table[k])

    def describe(self) -> str:
        if self.is_unit:
            return "unit focusing (the whole lens moves)"
        gaps = ", ".join(str(g + 1) for g in self.gaps)
        if self.kind == "group":
            signs = ", ".join(f"{s:+g}" for s in self.signs)
            return f"focus group: gaps after surfaces {gaps} change by ({signs}) x travel"
        return f"floating groups: gaps after surfaces {gaps} tabulated at {len(self.distances_mm)} distances"

    def check_against(self, n_surfaces: int) -> None:
        """Raise when a gap is not after one of the ``n_surfaces`` surfaces (the last one runs to the image)."""
        bad = [g + 1 for g in self.gaps if g >= n_surfaces]
        if bad:
            raise PrescriptionError(f"focus gap after surface {bad[0]} does not exist: the lens has {n_surfaces} "
                                    "surfaces", hint="name gaps by the surface before them (1, 2, ...)")


#: the default: the whole lens moves
UNIT_FOCUS = FocusMechanism()
