"""``auto`` PSFs of many field points at once (:mod:`lensrt.analysis.psf.auto`): the wavefronts of every field
traced together, the geometric fields in one stream -- the same bits as :func:`psf_at` one field at a time."""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.analysis.fields import image_height_fields
from lensrt.analysis.psf.map import field_seeds, map_arrays, psf_at, run_psf_group
from lensrt.analysis.psf.setup import make_setup
from lensrt.core.telemetry import measure

#: the f/5 Cooke triplet with 64-pixel grids: two diffraction (MFT) fields, two geometric ones
HEIGHTS_MM = [0.0, 6.0, 12.0, 18.0]


@pytest.fixture(scope="module")
def auto_case():
    lens = load_lens("cooke_triplet_50mm_f5")
    setup = make_setup(lens, None, "best", "cpu", method="auto", rays=1 << 13, pixels=64, mtf_freqs_cpmm=(10.0, 40.0))
    fields = image_height_fields(lens, HEIGHTS_MM, setup.plane_z_mm, "cpu")
    return setup, fields, field_seeds(len(fields), 3)


def test_auto_group_is_the_same_bits_as_field_by_field(auto_case):
    setup, fields, seeds = auto_case
    alone = [psf_at(setup, f, s, "cpu") for f, s in zip(fields, seeds)]
    singles = []  # launches of each field as a group of its own (the caches as warm as for the group below)
    for f, s in zip(fields, seeds):
        with measure() as one:
            run_psf_group(setup, [f], [s], "cpu")
        singles.append(one.launches)
    with measure() as rec:
        group = run_psf_group(setup, fields, seeds, "cpu")
    kinds = [r.kind for r in alone]
    assert "geometric" in kinds and any(k.startswith("diffraction") for k in kinds)  # both paths taken
    assert [r.kind for r in group] == kinds
    assert [r.metadata["method_reason"] for r in group] == [r.metadata["method_reason"] for r in alone]
    got, want = map_arrays(group), map_arrays(alone)
    for k in want:
        assert np.array_equal(got[k], want[k]), k
    for g, a in zip(group, alone):  # the MTF estimates (the report's numbers) too
        for name, e in a.estimates.items():
            assert np.array_equal(np.asarray(g.estimates[name].value), np.asarray(e.value)), name
            assert np.array_equal(np.asarray(g.estimates[name].stderr), np.asarray(e.stderr)), name
    # the wavefront rounds of all fields together and one stream for the geometric ones: no more launches
    # than the costliest field alone (plus the stream, when that field is a diffraction one); was their sum
    assert rec.launches <= max(singles) + 1 < sum(singles)


def test_wavefronts_of_many_fields_equal_one_field_at_a_time(auto_case):
    from lensrt.analysis.psf.diffraction import wavefront_chief_wavelengths
    from lensrt.analysis.psf.geometric import prepare_fields
    from lensrt.analysis.pupil_rays import chief_rays_at_many
    from lensrt.analysis.wave.wavefront import trace_wavefronts, trace_wavefronts_many
    setup, fields, _ = auto_case
    lens, spec = setup.lens, setup.spectrum
    geoms = prepare_fields(setup, fields, "cpu")
    chiefs = chief_rays_at_many(lens, [g.fp for g in geoms], wavefront_chief_wavelengths(setup), setup.plane_z_mm,
                                "cpu")
    jobs = [(g.fp, g.box, m, c) for g, c, m in zip(geoms, chiefs, (16, 24, 16, 36))]
    with measure() as rec:
        many = trace_wavefronts_many(lens, jobs, spec.lines_nm, setup.plane_z_mm, "cpu")
    assert rec.launches == 2  # clipped and unclipped, every field and wavelength
    for (fp, box, m, c), got in zip(jobs, many):
        want = trace_wavefronts(lens, fp, box, spec.lines_nm, setup.plane_z_mm, m, spec.primary_nm, "cpu", c)
        assert len(got) == len(want) == len(spec.lines_nm)
        for a, b in zip(got, want):
            for name in ("px", "py", "valid", "opd_mm", "amplitude"):
                assert np.array_equal(getattr(a, name), getattr(b, name)), name
            assert (a.na, a.interp_error_waves, a.opd_pv_waves) == (b.na, b.interp_error_waves, b.opd_pv_waves)


def test_wavefront_error_table_equals_each_field_alone(auto_case):
    from lensrt.analysis.psf.spectrum import line_spectrum
    from lensrt.analysis.psf.wavefront_error import wavefront_error, wavefront_error_table
    setup0, fields, _ = auto_case
    lens = setup0.lens
    setup = make_setup(lens, line_spectrum([lens.wavelengths.primary_nm]), setup0.focus, "cpu",
                       method="diffraction", pupil_samples=64)
    table = wavefront_error_table(setup, fields, device="cpu")
    for f, row in zip(fields, table):
        m = wavefront_error(setup, f, n_terms=4, device="cpu")[0]
        assert (row["rms_waves_no_tilt"], row["pv_waves"], row["strehl"]) == (m.rms_waves_no_tilt, m.pv_waves,
                                                                               m.strehl)


def test_chief_rays_of_another_wavelength_set_reuse_the_rays_aimed(auto_case):
    """chief_rays_at_many at [primary] + the lines, then at [primary, primary] (the wavefront-error table's
    set): the second aims nothing (one trace), and its rays are the first's, bit for bit."""
    from lensrt.analysis.pupil_rays import chief_ray_at, chief_rays_at_many
    from lensrt.trace.aiming import field_point
    setup, fields, _ = auto_case
    lens, z = setup.lens, setup.plane_z_mm
    fps = [field_point(lens, f.hx, 0.97 * f.hy) for f in fields]  # points no other test has aimed
    prim = lens.wavelengths.primary_nm
    first = chief_rays_at_many(lens, fps, [prim] + list(setup.spectrum.lines_nm), z, "cpu")
    with measure() as rec:
        again = chief_rays_at_many(lens, fps, [prim, prim], z, "cpu")
    assert rec.launches == 1
    for fp, a, b in zip(fps, first, again):
        assert np.array_equal(a.position_mm[:1], b.position_mm[:1]) and np.array_equal(a.opl_mm[:1], b.opl_mm[:1])
        alone = chief_ray_at(lens, fp, [prim], z, "cpu")  # aim_rays, one field point: the same ray to rounding
        np.testing.assert_allclose(b.position_mm[0], alone.position_mm[0], rtol=0, atol=1e-9)
