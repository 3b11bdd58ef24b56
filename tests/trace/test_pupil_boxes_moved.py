"""Pupil boxes of a lens moved as a whole (tilt-shift: surface 1 carries the lens's frame).

Oracle: translation invariance. The lens shifted across by s, with the object point shifted by s too, is the
plain lens and point moved together: the passing rays, and so the spot's footprint on the image plane, are the
plain case's moved by s. A box search that took surface 1 where the unmoved lens has it clipped the pupil of a
near point seen through a shifted lens (the light splat and ``lensrt bokeh --lens-shift-mm`` lost light).
"""
from __future__ import annotations

import numpy as np
import pytest

from lensrt.loading import load_lens
from lensrt.prescription.tilt_shift import tilt_shift_lens
from lensrt.trace.pupil_boxes import pupil_boxes


@pytest.mark.parametrize("shift_y_mm,z_mm,stop_mm", [(-12.0, -120.0, 5.0), (12.0, -60.0, 8.0), (-4.0, -300.0, 8.0)])
def test_shifted_lens_and_point_give_the_plain_footprint_moved(shift_y_mm: float, z_mm: float, stop_mm: float) -> None:
    # (before the fix: the first two lost 37 % and 41 % of the footprint's height)
    lens = load_lens("dgauss_50mm_f2")
    moved = tilt_shift_lens(lens, 0.0, (0.0, shift_y_mm))
    point = np.array([[0.0, 0.0, z_mm]])
    _, plain = pupil_boxes(lens, point, [587.6], footprint=True, stop_radius_mm=stop_mm)
    _, shifted = pupil_boxes(moved, point + [0.0, shift_y_mm, 0.0], [587.6], footprint=True, stop_radius_mm=stop_mm)
    size = max(plain[0, 1] - plain[0, 0], plain[0, 3] - plain[0, 2])
    want = plain[0] + np.array([0.0, 0.0, shift_y_mm, shift_y_mm])
    assert np.allclose(shifted[0], want, rtol=0.0, atol=0.02 * size), (shifted[0], want)
