"""Batched ray aiming (aim_many) gives the rays of aim_rays one field point at a time, in fewer launches."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.core.telemetry import measure
from lensrt.trace import kernel_to_stop
from lensrt.trace.aiming import aim_many, aim_rays, field_point, pupil_geometry


def _case(name: str, distance_mm: float | None = None):
    lens = load_lens(name)
    if distance_mm is not None:  # a finite object: rays from object points, not collimated beams
        lens = dataclasses.replace(lens, object_distance_mm=distance_mm)
    hs = [0.0, 0.5, 0.9, 1.0]
    fps = [field_point(lens, 0.0, h) for h in hs] + [field_point(lens, 0.7, 0.7)]
    rng = np.random.default_rng(3)
    n = 40
    rows = rng.integers(0, len(fps), n)
    px, py = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    wls = np.array(lens.wavelengths.nm)
    wl = wls[rng.integers(0, len(wls), n)]
    return lens, fps, rows, px, py, wl


def _per_field(lens, fps, rows, px, py, wl, aim, to_stop):
    geom = pupil_geometry(lens)
    o, d, ok = np.empty((len(rows), 3)), np.empty((len(rows), 3)), np.ones(len(rows), dtype=bool)
    for f, fp in enumerate(fps):
        sel = np.nonzero(rows == f)[0]
        if len(sel):
            o[sel], d[sel], ok[sel] = aim_rays(lens, fp, px[sel], py[sel], wl[sel], aim, to_stop, geom)
    return o, d, ok


@pytest.mark.parametrize("name, distance_mm", [("dgauss_50mm_f2", None), ("fisheye_10mm_f4", None),
                                               ("dgauss_50mm_f2", 400.0)])
@pytest.mark.parametrize("aim", ["real", "chief", "paraxial"])
def test_aim_many_matches_aim_rays_field_by_field(name, distance_mm, aim):
    lens, fps, rows, px, py, wl = _case(name, distance_mm)
    to_stop = kernel_to_stop(lens, "cpu")
    with measure() as one:
        o1, d1, ok1 = _per_field(lens, fps, rows, px, py, wl, aim, to_stop)
    with measure() as many:
        o2, d2, ok2 = aim_many(lens, fps, rows, px, py, wl, aim, to_stop)
    np.testing.assert_array_equal(ok1, ok2)
    assert np.max(np.abs(o1 - o2)) <= 1e-12
    assert np.max(np.abs(d1 - d2)) <= 1e-12
    if aim != "paraxial":
        assert many.launches < one.launches
    else:
        assert many.launches == one.launches == 0
