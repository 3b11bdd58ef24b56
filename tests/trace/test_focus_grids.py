"""The best-focus grids on the device (lensrt.trace.focus_grids.DeviceGrids: rays made, traced and reduced to
moment sums in Warp kernels) against the host path (HostGrids: rays built in NumPy, traced by the store kernel,
reduced in NumPy -- the oracle): the same cells pass, the same rays count, the same moments to rounding.

The two sum the same rays in different orders (and make the rays with the same formulas, one in NumPy, one in
the kernel), so they agree to rounding: 1e-12 relative on every moment. Off axis the moments are large
(E[p.p] ~ |centroid|^2) and the spot's variance is their difference, so the centred moments are held to
1e-12 of |centroid|^2 (mm^2) -- the conditioning of the moments, the same for both paths.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.analysis.raysets import object_field_point
from lensrt.core.telemetry import measure
from lensrt.loading import load_lens
from lensrt.paraxial import first_order
from lensrt.trace.focus import best_focus_plane, focus_moments_fields
from lensrt.trace.focus_grids import DeviceGrids, HostGrids, focus_grids


def _centred(m):
    """var(p), cov(p, t), var(t) of one wavelength's rays (the quantities the focus search uses)."""
    return (m.pp - float(m.mean_p @ m.mean_p), m.pt - float(m.mean_p @ m.mean_t), m.tt - float(m.mean_t @ m.mean_t))


def _same(dev, host) -> None:
    assert len(dev) == len(host) > 0
    for d, h in zip(dev, host):
        assert (d.wavelength_nm, d.z0_mm, d.rays) == (h.wavelength_nm, h.z0_mm, h.rays)
        scale = max(1.0, float(h.mean_p @ h.mean_p))
        np.testing.assert_allclose(d.mean_p, h.mean_p, rtol=1e-12, atol=1e-14 * math.sqrt(scale))
        np.testing.assert_allclose(d.mean_t, h.mean_t, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose([d.pp, d.pt, d.tt], [h.pp, h.pt, h.tt], rtol=1e-12, atol=0)
        np.testing.assert_allclose(_centred(d), _centred(h), rtol=1e-12, atol=1e-12 * scale)
        a, b = best_focus_plane([d]), best_focus_plane([h])
        assert a.z_mm == pytest.approx(b.z_mm, rel=0, abs=1e-12 * scale)
        assert a.rms_radius_mm ** 2 == pytest.approx(b.rms_radius_mm ** 2, rel=1e-12, abs=1e-12 * scale)


def test_device_grids_match_the_host_path_for_distances_planes_fields_and_wavelengths(device: str) -> None:
    """The focus-breathing case (one job per object distance, each on its own plane: traced to the image and on
    in a straight line), an off-axis field and a second wavelength."""
    lens = load_lens("dgauss_50mm_f2")
    ats = [lens.replace(object_distance_mm=d) for d in (math.inf, 3000.0, 700.0)]
    jobs = [(object_field_point(a, 0.0), 587.56, first_order(a).image_z_mm) for a in ats]
    jobs += [(object_field_point(ats[0], 0.25), 486.13, lens.image_z_mm),
             (object_field_point(ats[1], 0.0), 656.27, lens.image_z_mm + 0.05)]
    dev = focus_moments_fields(ats[0], jobs, n=48, sub=4, device=device, on_device=True)
    host = focus_moments_fields(ats[0], jobs, n=48, sub=4, device=device, on_device=False)
    _same(dev, host)
    assert abs(dev[3].mean_p[1]) > 5.0  # the off-axis job is off axis
    for d, h in zip(dev[:3], host[:3]):  # the axial jobs' best foci: to 1e-12 mm
        assert best_focus_plane([d]).z_mm == pytest.approx(best_focus_plane([h]).z_mm, rel=0, abs=1e-12)


def test_device_grids_one_plane_finite_object_and_stop_radius(device: str) -> None:
    """Every job on one plane (the rays traced to it directly), an object at a finite distance (Lambertian
    weights), a stop radius other than the lens's."""
    lens = load_lens("dgauss_50mm_f2").replace(object_distance_mm=1500.0)
    z0 = first_order(lens).image_z_mm
    jobs = [(object_field_point(lens, v), w, z0) for v, w in ((0.0, 486.13), (0.0, 656.27), (120.0, 587.56))]
    kw = dict(n=40, sub=4, stop_radius_mm=7.0, device=device)
    _same(focus_moments_fields(lens, jobs, on_device=True, **kw),
          focus_moments_fields(lens, jobs, on_device=False, **kw))


def test_device_grids_cut_away_a_disconnected_ring_as_the_host_does() -> None:
    """The wide end of the Canon RF 15-35 mm passes a ring of axial rays far outside its stop's beam (module
    docstring of lensrt.trace.focus): the main-pupil refinement rounds run on the device grids' pass/fail cells."""
    from lensrt.loading import load_configurations
    wide = load_configurations("canon_rf_15-35mm_f2.8").configuration("15.45mm")
    jobs = [(object_field_point(wide, 0.0), wide.wavelengths.primary_nm, wide.image_z_mm)]
    host_grids = HostGrids(wide, jobs, 64, 4, None, "cpu")
    dev_grids = DeviceGrids(wide, jobs, 64, 4, None, "cpu")
    from lensrt.trace.pupil_boxes import box_wavelengths, pupil_boxes
    boxes = pupil_boxes(wide, [jobs[0][0]], box_wavelengths(wide, [jobs[0][1]]), device="cpu")
    ok_host, ok_dev = host_grids.grid([0], boxes)[0], dev_grids.grid([0], boxes)[0]
    assert np.array_equal(ok_host, ok_dev)
    from scipy import ndimage
    assert ndimage.label(ok_dev, structure=np.ones((3, 3)))[1] > 1  # the ring is there, apart from the pupil
    kw = dict(n=64, sub=4, device="cpu")
    _same(focus_moments_fields(wide, jobs, on_device=True, **kw),
          focus_moments_fields(wide, jobs, on_device=False, **kw))


def test_device_grids_are_reproducible_and_launch_as_the_host_path() -> None:
    """Same inputs, same bits (no atomics: fixed-order sums), whatever the other jobs of the call; the launches
    are the host path's (a grid round each, one for the boundary sub-rays)."""
    lens = load_lens("dgauss_50mm_f2")
    jobs = [(object_field_point(lens, 0.0), w, lens.image_z_mm + dz) for w, dz in ((486.13, 0.0), (587.56, 0.1))]
    kw = dict(n=32, sub=4, device="cpu", reuse=False)
    focus_moments_fields(lens, jobs, on_device=True, **kw)  # compile, pack
    with measure() as dev_rec:
        a = focus_moments_fields(lens, jobs, on_device=True, **kw)
    with measure() as host_rec:
        focus_moments_fields(lens, jobs, on_device=False, **kw)
    b = focus_moments_fields(lens, jobs[::-1], on_device=True, **kw)[::-1]
    c = [focus_moments_fields(lens, [j], on_device=True, **kw)[0] for j in jobs]
    for x, y, z in zip(a, b, c):
        assert (x.mean_p.tobytes(), x.mean_t.tobytes(), x.pp, x.pt, x.tt, x.rays) == \
            (y.mean_p.tobytes(), y.mean_t.tobytes(), y.pp, y.pt, y.tt, y.rays) == \
            (z.mean_p.tobytes(), z.mean_t.tobytes(), z.pp, z.pt, z.tt, z.rays)
    assert dev_rec.launches == host_rec.launches


def test_moments_found_once_are_reused() -> None:
    """The report asks for the axial moments in several sections: asked again (among new jobs), known jobs
    are not traced again and are the moments found before; a different plane, grid or path is a new job."""
    lens = load_lens("dgauss_50mm_f2")
    axis = object_field_point(lens, 0.0)
    first = focus_moments_fields(lens, [(axis, 587.56, lens.image_z_mm)], n=24, sub=2, device="cpu")
    with measure() as rec:
        again = focus_moments_fields(lens, [(axis, 587.56, lens.image_z_mm)], n=24, sub=2, device="cpu")
    assert rec.launches == 0 and again[0] is first[0]
    with measure() as rec:
        mixed = focus_moments_fields(lens, [(axis, 587.56, lens.image_z_mm + 0.2), (axis, 587.56, lens.image_z_mm)],
                                     n=24, sub=2, device="cpu")
    assert mixed[1] is first[0] and mixed[0].z0_mm == lens.image_z_mm + 0.2 and rec.launches > 0
    host = focus_moments_fields(lens, [(axis, 587.56, lens.image_z_mm)], n=24, sub=2, device="cpu", on_device=False)
    finer = focus_moments_fields(lens, [(axis, 587.56, lens.image_z_mm)], n=26, sub=2, device="cpu")
    assert host[0] is not first[0] and finer[0].rays != first[0].rays


def test_general_lenses_take_the_host_path_and_asking_for_the_device_is_one_error() -> None:
    from lensrt.errors import LensrtError
    from lensrt.trace.pack import pack_lens
    lens = load_lens("dgauss_50mm_f2")
    curved = lens.replace(image_curvature_per_mm=-0.002)  # a curved image: the general kernel variant
    assert pack_lens(curved, "float64", "cpu").general
    jobs = [(object_field_point(curved, 0.0), 587.56, curved.image_z_mm)]
    assert isinstance(focus_grids(curved, jobs, 16, 2, None, "cpu"), HostGrids)
    assert isinstance(focus_grids(lens, jobs, 16, 2, None, "cpu"), DeviceGrids)
    assert isinstance(focus_grids(lens, jobs, 16, 2, None, "cpu", on_device=False), HostGrids)
    with pytest.raises(LensrtError, match="rotationally symmetric"):
        focus_grids(curved, jobs, 16, 2, None, "cpu", on_device=True)
    for n, sub in ((1, 2), (16, 0), (16.5, 2)):
        with pytest.raises(LensrtError, match="best-focus grid needs"):
            focus_moments_fields(lens, jobs, n=n, sub=sub, device="cpu")
