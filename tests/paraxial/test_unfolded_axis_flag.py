"""``FirstOrder.unfolded_axis`` says when paraxial data follow an unfolded axis (tilts/decenters), not
when a centred lens merely carries central obscurations (a reflex lens, a Cassegrain): those stay
rotationally symmetric and their paraxial data exact."""
from __future__ import annotations

import math

from geometry_cases import cassegrain_system, folded_system

from lensrt import load_lens
from lensrt.paraxial import first_order
from lensrt.prescription.tilt_shift import tilt_shift_lens


def test_obscured_centred_lenses_are_not_unfolded() -> None:
    assert not first_order(cassegrain_system()).unfolded_axis
    reflex = load_lens("reflex_nikkor_500mm_f8")
    assert not first_order(reflex).unfolded_axis and any(s.apertures for s in reflex.surfaces)


def test_tilts_and_folds_are_unfolded() -> None:
    assert first_order(folded_system()).unfolded_axis
    assert first_order(tilt_shift_lens(load_lens("dgauss_50mm_f2"), math.radians(3.0))).unfolded_axis
    assert not first_order(load_lens("dgauss_50mm_f2")).unfolded_axis
