"""Dummy surfaces (the same medium on both sides) that lie inside a neighbour's sag (lensrt.prescription.validate).

A dummy is a reference plane, not matter: OpticStudio traces a ray to it by a backward segment when it lies in
front of the surface before it (YuryStrelkov/ZemaxUtils' 2 m telescope files put a plane at the primary mirror's
vertex, 0 mm after it, with baffles behind). lensrt loads such a lens with a ``dummy_crossing`` warning and traces
it exactly as the lens without the dummy; the real surfaces on either side of a dummy are still compared with each
other, so a dummy cannot hide two elements that overlap.
"""
from __future__ import annotations

import math
import warnings

import pytest

from lensrt.errors import PrescriptionError
from lensrt.loading import load_lens
from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

WL_NM = 587.56


def _lens(surfaces: list[Surface], epd_mm: float) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", epd_mm), fields=Fields("angle", (0.0, math.radians(0.5))),
                wavelengths=Wavelengths((WL_NM,)))


def _mirror(dummy: bool) -> Lens:
    """A concave spherical mirror R = -200 mm (semi-diameter 30 mm, sag -2.26 mm at the rim), optionally a plane
    dummy 0 mm after it (semi-diameter 40 mm), image 100 mm before it."""
    mirror = Surface(-1 / 200.0, 0.0 if dummy else -100.0, semi_diameter_mm=30.0, mirror=True, is_stop=True)
    rest = [Surface(0.0, -100.0, semi_diameter_mm=40.0, label="dummy")] if dummy else []
    return _lens([mirror] + rest, 50.0)


def _load(lens: Lens) -> Lens:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_lens(lens)


def test_a_dummy_inside_a_mirror_sag_loads_with_a_warning_and_traces_as_without_it() -> None:
    with pytest.warns(UserWarning, match="surface 2 is a dummy"):
        lens = load_lens(_mirror(dummy=True))
    assert [w.code for w in lens.warnings] == ["dummy_crossing"]
    plain = _load(_mirror(dummy=False))
    for y in (0.0, 5.0, 17.0, 24.5):
        a = trace_reference(lens, (0.3, y, -10.0), (0.0, 0.0, 1.0), WL_NM)
        b = trace_reference(plain, (0.3, y, -10.0), (0.0, 0.0, 1.0), WL_NM)
        assert a.status == b.status == OK
        assert (a.x_mm, a.y_mm, a.L, a.M, a.N) == pytest.approx((b.x_mm, b.y_mm, b.L, b.M, b.N), abs=1e-12)
        assert a.opl_mm == pytest.approx(b.opl_mm, abs=1e-9)


def _pair(dummy: bool) -> Lens:
    """A plano-plano plate, 0.5 mm of air, then a meniscus whose concave front (R = -15 mm) reaches 2.3 mm in front
    of its vertex at r = 8 mm: the air gap closes from r ~ 3.9 mm, inside the 12 mm beam."""
    glass = ConstantIndex(1.5)
    gap = [Surface(0.0, 0.25, semi_diameter_mm=9.0), Surface(0.0, 0.25, semi_diameter_mm=9.0, label="dummy")] \
        if dummy else [Surface(0.0, 0.5, semi_diameter_mm=9.0)]
    return _lens([Surface(0.0, 2.0, glass, 9.0, is_stop=True)] + gap +
                 [Surface(-1 / 15.0, 3.0, glass, 9.0), Surface(-1 / 12.0, 40.0, semi_diameter_mm=9.0)], 12.0)


def test_a_dummy_does_not_hide_real_surfaces_that_cross() -> None:
    with pytest.raises(PrescriptionError, match="surfaces 2 and 3 cross"):
        _load(_pair(dummy=False))
    with pytest.raises(PrescriptionError, match="surfaces 2 and 4 cross: .*thickness 0.5 mm"):
        _load(_pair(dummy=True))


def test_cots_objective_stage_with_crossing_dummies_loads_like_its_siblings() -> None:
    """m-d-young's COTS-0002-02-1 (tests/data/corpus) has a dummy 3e-10 mm before a convex face and a reference
    plane 2.96 mm in front of its last lens surface; it was refused as crossing. It now loads with
    ``dummy_crossing`` warnings, and its rear focal length (into water) is that of the same objective's other stages
    (04-1, 12-1) to 1e-7 relative -- optiland 0.6.3 gives 11.10112 mm for it, the stages' common 1.5e-4 offset."""
    from pathlib import Path

    from lensrt.paraxial import first_order
    corpus = Path(__file__).resolve().parents[1] / "data" / "corpus"
    lens = _load_file(corpus / "COTS-0002-02-1.zmx")
    assert "dummy_crossing" in {w.code for w in lens.warnings}
    f2 = first_order(lens).rear_focal_length_mm
    for sibling in ("COTS-0002-04-1.zmx", "COTS-0002-12-1.zmx"):
        assert f2 == pytest.approx(first_order(_load_file(corpus / sibling)).rear_focal_length_mm, rel=1e-7)


def _load_file(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_lens(path)
