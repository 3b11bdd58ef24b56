"""first_order keeps what it found per (lens, wavelength, object distance): the same immutable result when asked
again, never a stale one for another lens, wavelength or distance (the oracle: the data computed afresh)."""
from __future__ import annotations

import math
import sys

import pytest

from lensrt.errors import LensrtError
from lensrt.loading import load_lens
from lensrt.paraxial import first_order


def test_first_order_is_found_once_and_never_stale() -> None:
    fresh = sys.modules["lensrt.paraxial.first_order"]._first_order
    lens = load_lens("dgauss_50mm_f2")
    a = first_order(lens)
    assert first_order(lens) is a and a == fresh(lens, None, None)
    assert first_order(lens, 486.13) == fresh(lens, 486.13, None) != a
    assert first_order(lens, None, 1500.0) == fresh(lens, None, 1500.0) != a
    thicker = lens.replace_surface(0, thickness_mm=lens.surfaces[0].thickness_mm + 1.0)  # another lens, another EFL
    assert first_order(thicker) == fresh(thicker, None, None) and first_order(thicker).efl_mm != a.efl_mm
    with pytest.raises(LensrtError, match="must be positive"):  # refused every time, never kept
        first_order(lens, None, -5.0)
    with pytest.raises(LensrtError, match="must be positive"):
        first_order(lens, None, -5.0)
    assert math.isfinite(first_order(lens, 587.56).efl_mm)


def test_paraxial_systems_are_kept_read_only_and_equal_to_a_fresh_reduction() -> None:
    import numpy as np
    from lensrt.paraxial.ynu import paraxial_system
    fresh = sys.modules["lensrt.paraxial.ynu"]._paraxial_system
    lens = load_lens("dgauss_50mm_f2")
    a = paraxial_system(lens, 486.13)
    assert paraxial_system(lens, 486.13) is a
    b = fresh(lens, 486.13)
    for name in ("curvature_per_mm", "thickness_mm", "index", "power_per_mm"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
        with pytest.raises(ValueError):  # a kept system cannot be changed in place by a caller
            getattr(a, name)[0] = 0.0
    assert not np.array_equal(paraxial_system(lens, 656.27).index, a.index)
