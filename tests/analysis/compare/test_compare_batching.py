"""compare_lens's batched traces: every field's ray fans in two launches, every wavelength's distortion and
field-curvature rays in one -- the same bits as each analysis tracing its own rays (the oracle)."""
from __future__ import annotations

import numpy as np
import pytest

from lensrt import load_lens
from lensrt.analysis.compare.aberrations import fan_jobs, ray_fan, trace_fans
from lensrt.analysis.compare.distortion import distortion_curve
from lensrt.analysis.compare.focus import field_curvature
from lensrt.analysis.raysets import aim_batches, chief_batches, close_ray_batch, field_spec, object_field_point, \
    trace64_many
from lensrt.core.telemetry import measure


@pytest.fixture(scope="module")
def dg():
    return load_lens(None)


def test_fans_of_every_field_traced_together_equal_each_fan_alone(dg):
    wls = list(dg.wavelengths.nm)
    cases = [(hy, fan, pupil) for hy in (0.0, 0.7, 1.0)
             for fan, pupil in (("tangential", None), ("sagittal", np.linspace(0.0, 1.0, 21)))]
    aimed = [aim_batches(dg, fan_jobs(dg, hy, fan, wls, pupil), "real", "cpu") for hy, fan, pupil in cases]
    with measure() as rec:
        traced = trace_fans(dg, aimed, "cpu")
    assert rec.launches == 2  # the fans, then the chief rays: six fans of three wavelengths each
    for (hy, fan, pupil), a, t in zip(cases, aimed, traced):
        got = ray_fan(dg, hy, fan, wls, pupil, device="cpu", aimed=a, traced=t)
        want = ray_fan(dg, hy, fan, wls, pupil, device="cpu", aimed=a)
        for name in ("ex_mm", "ey_mm", "opd_waves", "passed", "exit_pupil_z_mm"):
            assert np.array_equal(getattr(got, name), getattr(want, name), equal_nan=name != "passed"), name
        assert got.reference_mm == want.reference_mm and np.isfinite(got.ey_mm).any()


def test_distortion_and_field_curvature_of_all_wavelengths_in_one_trace(dg):
    wls = list(dg.wavelengths.nm)
    hy = np.linspace(0.0, 1.0, 7)
    fps = [object_field_point(dg, field_spec(dg, h).object_value) for h in hy]
    chiefs = chief_batches(dg, fps, wls, "cpu")
    with measure() as rec:
        curves = trace64_many(dg, list(chiefs) + [close_ray_batch(dg, c, fps) for c in chiefs], "cpu")
    assert rec.launches == 1
    for w, c, t_d, t_f in zip(wls, chiefs, curves[:len(wls)], curves[len(wls):]):
        d, d0 = distortion_curve(dg, hy, w, "cpu", chief=c, traced=t_d), distortion_curve(dg, hy, w, "cpu", chief=c)
        assert np.array_equal(d.real_height_mm, d0.real_height_mm, equal_nan=True)
        f, f0 = field_curvature(dg, hy, w, "cpu", chief=c, traced=t_f), field_curvature(dg, hy, w, "cpu", chief=c)
        for name in ("sagittal_z_mm", "tangential_z_mm"):
            assert np.array_equal(getattr(f, name), getattr(f0, name), equal_nan=True), name
        assert np.isfinite(f.tangential_z_mm[1:]).all()


def test_real_pupils_trace_every_field_and_the_marginal_ray_in_one_launch(dg):
    """real_pupils of three fields: the same sizes and positions as each field alone, in one trace (the
    stop-rim rays of every field and the axial marginal ray) after the aiming."""
    from lensrt.analysis.compare.pupils import real_pupils
    hy = [0.0, 0.6, 1.0]
    with measure() as one_field:
        real_pupils(dg, [0.3], outlines=False, device="cpu")
    with measure() as rec:
        both = real_pupils(dg, hy, outlines=False, device="cpu")
    # one aiming run and one trace whatever the number of fields (was a trace per field and one more)
    assert rec.launches <= one_field.launches
    alone = [real_pupils(dg, [h], outlines=False, device="cpu") for h in hy]
    for k, one in enumerate(alone):
        for name in ("entrance_pupil_z_mm", "exit_pupil_z_mm", "entrance_tangential_mm", "exit_sagittal_mm"):
            assert np.array_equal(getattr(both, name)[k:k + 1], getattr(one, name), equal_nan=True), name
        assert both.real_working_f_number == one.real_working_f_number


def test_lateral_colour_and_longitudinal_aberration_trace_every_wavelength_together(dg):
    """Three wavelengths in one trace each (was a trace per wavelength); the numbers are each wavelength's alone."""
    from lensrt.analysis.compare.comparison import lateral_colour
    from lensrt.analysis.compare.focus import longitudinal_aberration
    from lensrt.analysis.raysets import lens_fields
    wls = list(dg.wavelengths.nm)
    fields = lens_fields(dg, None)
    lateral_colour(dg, fields, wls, "cpu")  # aim the chief rays (kept by aim_batches)
    with measure() as rec:
        lat = lateral_colour(dg, fields, wls, "cpu")
        lsa = longitudinal_aberration(dg, wls, device="cpu")  # paraxial aiming: no launch
    assert rec.launches == 2
    for j, w in enumerate(wls):
        assert np.array_equal(lat.real_height_mm[:, j], lateral_colour(dg, fields, [w], "cpu").real_height_mm[:, 0],
                              equal_nan=True)
        assert np.array_equal(lsa.focus_z_mm[j], longitudinal_aberration(dg, [w], device="cpu").focus_z_mm[0],
                              equal_nan=True)
    assert np.isfinite(lat.real_height_mm).all() and np.isfinite(lsa.focus_z_mm).all()


def test_compare_aims_the_analyses_rays_ahead_in_one_run():
    """compare_lens's one Newton run (_aim_ahead) holds the very rays each analysis then aims: lateral colour,
    the mapping factor, the real pupils' rim rays and the fans launch no aiming of their own afterwards."""
    from lensrt.analysis.compare.comparison import _aim_ahead, _aim_fans, lateral_colour
    from lensrt.analysis.compare.pupils import real_pupil_jobs
    from lensrt.analysis.compare.vignetting import mapping_factor
    from lensrt.analysis.raysets import lens_fields
    lens = load_lens("cooke_triplet_50mm_f5")  # a lens no other test here has aimed
    wls = list(lens.wavelengths.nm)
    fields = lens_fields(lens, [0.25])
    curve_fps = [object_field_point(lens, field_spec(lens, h).object_value) for h in np.linspace(0.0, 1.0, 5)]
    vhy = np.linspace(0.0, 1.0, 4)
    _aim_ahead(lens, fields, wls, curve_fps, vhy, True, "cpu")
    with measure() as rec:
        lateral_colour(lens, fields, wls, "cpu")  # one trace
        mapping_factor(lens, np.array([field_spec(lens, h).object_value for h in vhy]), lens.wavelengths.primary_nm,
                       "cpu")  # one trace
        aim_batches(lens, real_pupil_jobs(lens, [f.hy for f in fields], lens.wavelengths.primary_nm), "real", "cpu")
        aimed = _aim_fans(lens, fields, wls, "cpu")
        chief_batches(lens, curve_fps, wls, "cpu")
    assert rec.launches == 2 and all(a is not None for a in aimed)


def test_spot_diagram_runs_share_one_stream_launch(dg):
    """The per-wavelength and polychromatic Monte Carlo runs of spot_diagrams in one stream launch: wavelength i's
    estimates are those of spot_diagrams at that wavelength alone with seed + i (its run's seed)."""
    from lensrt.analysis.compare.aberrations import spot_diagrams
    from lensrt.trace import stream as stream_module
    wls, hy, seed = list(dg.wavelengths.nm), [0.0, 0.8], 7
    calls = []
    real = stream_module.stream

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)
    stream_module.stream = counting
    try:
        both = spot_diagrams(dg, hy, wls, rays=2048, batches=8, seed=seed, device="cpu")
    finally:
        stream_module.stream = real
    assert len(calls) == 1  # was one per wavelength and one more
    for i, w in enumerate(wls):
        alone = spot_diagrams(dg, hy, [w], rays=2048, batches=8, seed=seed + i, device="cpu")
        for a, b in zip(both, alone):
            for key, e in b.per_wavelength[w].items():
                assert (a.per_wavelength[w][key].value, a.per_wavelength[w][key].stderr) == (e.value, e.stderr), key
    assert all(s.estimates["rms_radius_mm"].value > 0 for s in both)
