"""Physical rims of a Mangin mirror's surfaces: after a mirror the gap between two faces runs toward -z.

Closed form: two spherical faces of radii R1, R2 (same sign) whose vertices are t apart meet where
their sags differ by t; a light path folded back by the silvered face must give the same rim as the
unfolded element.
"""
from __future__ import annotations

import json
import math

import pytest

from geometry_cases import mangin_system

from lensrt import load_lens
from lensrt.analysis.compare.pupils import physical_rim_mm
from lensrt.cli import main


def _meet_mm(r1: float, r2: float, t: float) -> float:
    """Height where sphere sags z1(r) = r1 - sqrt(r1^2 - r^2) and t + z2(r) meet (bisection)."""
    def gap(r: float) -> float:
        z1 = r1 - math.copysign(math.sqrt(r1 * r1 - r * r), r1)
        z2 = r2 - math.copysign(math.sqrt(r2 * r2 - r * r), r2)
        return t + z2 - z1
    lo, hi = 0.0, min(abs(r1), abs(r2))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if gap(mid) > 0:
            lo = mid
        else:
            hi = mid
    return lo


def test_mangin_mirror_rim_is_where_its_faces_meet() -> None:
    lens = mangin_system()  # front R -120, silvered back R -100, 1 mm thick: the faces meet at the rim
    want = _meet_mm(-120.0, -100.0, 1.0)
    assert physical_rim_mm(lens, 0) == pytest.approx(want, abs=1e-4)  # physical_rim_mm allows a contact tolerance
    # the silvered face and the front face met again on the way back: the same glass, the same rim
    assert physical_rim_mm(lens, 1) == pytest.approx(want, abs=1e-4)  # physical_rim_mm allows a contact tolerance
    assert physical_rim_mm(lens, 2) == pytest.approx(want, abs=1e-4)  # physical_rim_mm allows a contact tolerance


def test_reflex_lens_compares_and_sweeps(capsys: pytest.CaptureFixture) -> None:
    lens = load_lens("reflex_nikkor_500mm_f8")
    for i, s in enumerate(lens.surfaces):
        rim = physical_rim_mm(lens, i)
        assert rim is None or rim >= s.semi_diameter_mm
    # sweep's default focus distances leave out those inside the front focal point (1.58 m here)
    assert main(["sweep", "reflex_nikkor_500mm_f8", "--quantity", "magnification", "--format", "json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert rows and all(r["focus_distance_mm"] is None or r["focus_distance_mm"] > 1584.0 for r in rows)
