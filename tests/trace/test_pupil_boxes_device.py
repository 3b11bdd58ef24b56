"""The pupil-box grid pass on the device (one launch: rays made, traced and reduced in the kernel)
against the host pass (rays built in NumPy, traced by the store kernel): the same boxes and footprints."""
from __future__ import annotations

import numpy as np
import pytest

from lensrt.loading import load_lens
from lensrt.prescription.model import Iris
from lensrt.trace.aiming import field_point
from lensrt.trace.pupil_boxes import pupil_boxes


def _both(lens, fields, **kw):
    host = pupil_boxes(lens, fields, footprint=True, on_device=False, **kw)
    dev = pupil_boxes(lens, fields, footprint=True, on_device=True, **kw)
    return host, dev


def _same(host, dev) -> None:
    (hb, hf), (db, df) = host, dev
    assert len(hb) == len(db) > 0
    for a, b in zip(hb, db):
        assert (a.centre, a.axis, a.e1, a.e2) == (b.centre, b.axis, b.e1, b.e2)
        scale = max(a.a1 - a.a0, a.b1 - a.b0, 1.0)
        assert np.allclose([a.a0, a.a1, a.b0, a.b1], [b.a0, b.a1, b.b0, b.b1], rtol=0.0, atol=1e-12 * scale)
    assert np.array_equal(np.isnan(hf), np.isnan(df))
    ok = ~np.isnan(hf)
    assert np.allclose(hf[ok], df[ok], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("lens_name", ["dgauss_50mm_f2", "fisheye_10mm_f4"])
def test_device_pass_matches_host_pass_infinite_fields(lens_name: str, device: str) -> None:
    lens = load_lens(lens_name)
    fps = [field_point(lens, 0.0, h) for h in (0.0, 0.5, 0.9, 1.0)] + [field_point(lens, 0.6, -0.6)]
    # a fisheye's front element is much larger than its pupil: cells across the pupil, as maps ask
    host, dev = _both(lens, fps, device=device, coarse=24, fine=16, min_cells_across_pupil=12)
    _same(host, dev)
    assert sum(b.area_mm2 > 0 for b in dev[0]) >= 4


def test_device_pass_matches_host_pass_object_points_with_iris(device: str) -> None:
    lens = load_lens("dgauss_50mm_f2")
    obj = np.array([[0.0, 0.0, -2000.0], [150.0, -80.0, -1500.0], [-400.0, 300.0, -3000.0], [9e4, 0.0, -1000.0]])
    host, dev = _both(lens, obj, device=device, coarse=24, fine=16, plane_z_mm=lens.image_z_mm + 0.3,
                      iris=Iris(blades=7))
    _same(host, dev)
    assert host[0][3].area_mm2 == 0.0 and np.all(np.isnan(host[1][3]))  # far outside the field: nothing passes
