"""Kernel-launch budgets (issue 19): counts, not seconds -- the same on every machine for the same work.

The fast tests pin the batching of the loops that used to launch per field point, per wavelength or
per Newton step; the slow one holds the whole report to its budget.
"""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.analysis.raysets import chief_batch, object_field_point
from lensrt.core.telemetry import measure


@pytest.fixture(scope="module")
def dg():
    return load_lens(None)


def _fields(lens, n: int):
    return [object_field_point(lens, float(v)) for v in np.linspace(0.0, 0.38, n)]


def test_aiming_launches_do_not_grow_with_the_number_of_field_points(dg):
    chief_batch(dg, _fields(dg, 1), 587.56, "cpu")  # pack the lens, compile
    with measure() as one:  # the widest field alone (the axis converges at once)
        chief_batch(dg, _fields(dg, 9)[-1:], 587.56, "cpu")
    with measure() as nine:
        chief_batch(dg, _fields(dg, 9), 587.56, "cpu")
    # one trace to the stop per Newton step for all rays (the Jacobian's two neighbours ride along);
    # Newton from the axis converges in 3 steps here: 1 + 3 launches, was 1 + 3 x 3
    assert nine.launches <= 5
    assert nine.launches <= one.launches + 1


def test_pupil_boxes_trace_every_field_point_and_wavelength_in_one_launch_per_pass(dg):
    from lensrt.trace.pupil_boxes import pupil_boxes
    with measure() as rec:
        boxes = pupil_boxes(dg, _fields(dg, 9), [486.13, 587.56, 656.27], device="cpu")
    assert rec.launches == 2  # the coarse grid and the fine grid (was 2 x 3 wavelengths)
    assert all(b.area_mm2 > 0 for b in boxes)


def test_the_real_half_field_is_found_in_a_few_batched_rounds(dg):
    from lensrt.analysis.focusing import real_half_field_rad
    from lensrt.analysis.raysets import chief_batch as chiefs, trace64
    with measure() as rec:
        a = real_half_field_rad(dg, 18.0)
    # the chief ray at that angle lands at 18 mm (tolerance 1e-7 mm)
    fp = object_field_point(dg, a)
    y = trace64(dg, chiefs(dg, [fp], dg.wavelengths.primary_nm, "cpu"), "cpu").position_mm[0, 1]
    assert abs(abs(y) - 18.0) < 1e-6
    assert rec.launches <= 20  # ~3 rounds of 9 chief rays (aiming + one trace each); was ~66 (one chief ray at a time)


@pytest.mark.slow
def test_the_report_keeps_its_launch_budget(tmp_path, dg):
    """The report's plan at draft quality on the CPU (normal quality, the default, traces ~30x more rays
    and runs the same loops with more fields: 548 launches, docs/benchmarks.md). Today's breakdown
    (draft, CPU): lens 15, first_order 158, zoom 184 (at each of the breathing table's 8 distances --
    one lens per distance -- a focus secant and ~3 rounds of batched chief rays), psf 21, mtf 31,
    bokeh 28: 437."""
    from lensrt.report import ReportOptions, build_report
    rep = build_report(dg, tmp_path, ReportOptions(quality="draft", device="cpu"), quiet=True)
    assert not rep.failed
    assert rep.telemetry["launches"] <= 500  # was 3,093 (issue 19), 1,353 before this budget
