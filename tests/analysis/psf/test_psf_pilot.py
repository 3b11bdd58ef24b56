"""The pilot grids that size a PSF map's grids, made for all fields at once: the same bits as field by field."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from trace_cases import library_lens

from lensrt.analysis.fields import sensor_grid_fields
from lensrt.analysis.psf.geometric import pilot_rays, prepare_fields, psf_windows
from lensrt.analysis.psf.setup import make_setup
from lensrt.analysis.pupil_rays import pupil_grid_rays
from lensrt.trace import RayBatch, trace
from lensrt.trace.aiming import FieldPoint


def _setup_and_geoms(grid: int = 3):
    lens = library_lens("dgauss_50mm_f2")
    setup = make_setup(lens, None, "image", "cpu", rays=4096, pixels=32)
    fields = sensor_grid_fields(lens, "full-frame", (grid, grid), setup.plane_z_mm, "cpu")
    return setup, prepare_fields(setup, fields, "cpu")


def test_pilot_rays_of_all_fields_are_those_of_each_field_alone():
    setup, geoms = _setup_and_geoms()
    # an object point at a finite distance among the fields at infinity (taken field by field)
    geoms = list(geoms)
    geoms.insert(2, replace(geoms[4], fp=FieldPoint(False, None, (0.5, 3.0, -800.0))))
    assert sum(g.fp.infinite for g in geoms) == len(geoms) - 1
    o, d = pilot_rays(geoms, 12)
    ref = [pupil_grid_rays(g.fp, g.box, 12) for g in geoms]
    assert np.array_equal(o, np.concatenate([r.origin_mm for r in ref]))
    assert np.array_equal(d, np.concatenate([r.direction for r in ref]))


def test_psf_windows_equal_a_trace_per_field_and_wavelength():
    setup, geoms = _setup_and_geoms()
    spec = setup.spectrum
    wls = sorted({spec.min_nm, spec.primary_nm, spec.max_nm})
    got = psf_windows(setup, geoms, "cpu", n_side=16)
    for g, (pitch_um, pixels, half) in zip(geoms, got):
        rays = pupil_grid_rays(g.fp, g.box, 16)
        far = 0.0
        for wl in wls:
            r = trace(setup.lens, RayBatch(rays.origin_mm, rays.direction, np.full(len(rays.weight), wl)),
                      "float64", "cpu", plane_z_mm=setup.plane_z_mm)
            dev = np.max(np.abs(r.position_mm[:, :2] - np.asarray(g.reference_mm)), axis=1)
            far = max(far, float(np.where(r.ok, dev, 0.0).max()))
        assert half == max(1.1 * far, 2e-3)
        assert pixels == setup.pixels and pitch_um == 2.0 * half * 1e3 / pixels
