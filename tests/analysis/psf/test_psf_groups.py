"""PSF maps in groups of fields: batched set-up, one stream launch per group, the same bits as field by field."""
from __future__ import annotations

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.fields import chief_height_table
from lensrt.analysis.psf.map import field_seeds, map_arrays, psf_at, psf_map_job
from lensrt.analysis.pupil_rays import chief_ray_at
from lensrt.parallel.local import LocalExecutor
from lensrt.parallel.workloads import get_workload
from lensrt.trace.aiming import field_point
from lensrt.trace.stream import stream_source, stream_sources


def test_map_is_the_same_bits_in_any_grouping_and_field_by_field():
    job = get_workload("psf-map")("grid=2,rays=8192,pixels=16,groups=1", 5)
    setup = job.context
    fields = [p[1] for it in job.items for p in it.params]
    with LocalExecutor("cpu") as ex:
        one = ex.run(job).value
        for g in (2, 4):
            other = ex.run(psf_map_job(setup, fields, 5, reduce=map_arrays, groups=g)).value
            for k in one:
                assert np.array_equal(one[k], other[k]), (g, k)
    alone = map_arrays([psf_at(setup, f, s, "cpu") for f, s in zip(fields, field_seeds(len(fields), 5))])
    for k in one:
        assert np.array_equal(one[k], alone[k]), k
    assert one["psf"].shape == (4, 16, 16) and np.all(one["samples"] == 8192)


def test_chief_ray_table_in_one_batch_equals_one_ray_at_a_time():
    lens = library_lens("dgauss_50mm_f2")
    tab = chief_height_table(lens, lens.image_z_mm, device="cpu")
    wl = lens.wavelengths.primary_nm
    ys = [chief_ray_at(lens, field_point(lens, 0.0, float(h)), [wl], lens.image_z_mm, "cpu").position_mm[0, 1]
          for h in tab.h[1:]]
    np.testing.assert_allclose(tab.height_mm[1:], ys, rtol=0, atol=1e-12)
    assert len(tab.h) > 10 and np.all(np.diff(np.abs(tab.height_mm)) > 0)


@pytest.mark.parametrize("lens_name", ["dgauss_50mm_f2", "fisheye_10mm_f4"])
def test_batched_sources_equal_one_at_a_time(lens_name):
    lens = library_lens(lens_name)
    fields = [(0.0, 0.0), (0.3, 0.5), (0.0, 1.0)]
    many = stream_sources(lens, fields, device="cpu")
    for k, (hx, hy) in enumerate(fields):
        one = stream_source(lens, hx, hy, layer=k, device="cpu")
        assert many[k].layer == k
        for name in ("a0", "a1", "b0", "b1"):
            assert getattr(many[k].box, name) == pytest.approx(getattr(one.box, name), abs=1e-9)
        np.testing.assert_allclose(many[k].centre_mm, one.centre_mm, atol=1e-12)


def test_psf_from_stream_builds_the_grid_of_the_source():
    from lensrt.analysis.psf.geometric import psf_from_stream
    from lensrt.trace.stream import Grid, stream
    lens = library_lens("dgauss_50mm_f2")
    src = stream_source(lens, 0.0, 0.5, device="cpu")
    from dataclasses import replace
    res = stream(lens, [replace(src, pixel_mm=0.003)], Grid(40, 40, 0.01), 1 << 13, batches=8,
                 batch_histograms=True, device="cpu")
    psf = psf_from_stream(res)
    assert psf.grid.pitch_um == pytest.approx(3.0) and psf.grid.shape == (40, 40)
    assert psf.grid.centre_mm == pytest.approx(src.centre_mm)
    rms, _ = res.rms_radius()
    assert float(psf.estimates["rms_radius_mm"].value) == pytest.approx(rms, rel=1e-6)
