"""Best focus, spots, colour, fisheye mappings and grid distortion: internal consistency and closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.compare.aberrations import ray_fan, spot_diagrams
from lensrt.analysis.compare.comparison import lateral_colour
from lensrt.analysis.compare.distortion import MAPPINGS, distortion_curve, grid_distortion, mapping_height_mm
from lensrt.analysis.compare.focus import best_focus, chromatic_focal_shift, correction_name
from lensrt.analysis.raysets import lens_fields, object_field_point, pupil_grid_rays, trace64
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order


@pytest.fixture(scope="module")
def dgauss():
    return library_lens("dgauss_50mm_f2")


def test_best_focus_is_the_rms_minimum(dgauss):
    """The closed-form minimum against the RMS radius of the same pupil's rays traced to planes around it."""
    from lensrt.trace.focus import best_focus_plane, focus_moments
    bf = best_focus(dgauss, device="cpu")
    wl = dgauss.wavelengths.primary_nm

    def rms(z: float) -> float:   # the rays traced again, to the plane z
        return best_focus_plane([focus_moments(dgauss, wl, z0_mm=z, device="cpu")]).rms_radius_z0_mm

    assert rms(bf.z_mm) == pytest.approx(bf.rms_radius_mm, rel=1e-9)
    assert rms(bf.paraxial_image_z_mm) == pytest.approx(bf.rms_radius_paraxial_mm, rel=1e-9)
    for dz in (-0.01, 0.01):
        assert rms(bf.z_mm + dz) > bf.rms_radius_mm
    assert bf.rays > 500


def test_spot_statistics_against_dense_grid(dgauss):
    """Stream-kernel RMS radius (+- s.e.) against a dense deterministic pupil grid, per wavelength."""
    wl = dgauss.wavelengths.primary_nm
    spots = spot_diagrams(dgauss, [0.0, 0.7], [wl], n_grid=17, rays=1 << 15, device="cpu")
    for s, h in zip(spots, (0.0, 0.7)):
        fp = object_field_point(dgauss, lens_fields(dgauss)[0].object_value if h == 0 else math.radians(15.4))
        r = trace64(dgauss, pupil_grid_rays(dgauss, fp, wl, 160, "cpu"), "cpu", clip=True)
        x = r.position_mm[r.ok, 0] - s.reference_mm[0]
        y = r.position_mm[r.ok, 1] - s.reference_mm[1]
        dense = math.sqrt(np.mean(x * x + y * y))
        est = s.per_wavelength[wl]["rms_radius_mm"]
        assert abs(est.value - dense) < 4 * est.stderr + 2e-3 * dense
        assert est.samples == 1 << 15 and est.seconds > 0
        cy = s.per_wavelength[wl]["centroid_y_mm"]
        assert abs(cy.value - y.mean()) < 4 * cy.stderr + 2e-3 * dense
    cx = spots[0].estimates["centroid_x_mm"]
    assert abs(cx.value) < 4 * cx.stderr  # on the axis the centroid is the chief ray's point (symmetry)
    # referred to the (polychromatic) centroid, the centroid is at the origin and the RMS is the centroid RMS
    c = spot_diagrams(dgauss, [0.7], [wl], n_grid=9, rays=1 << 12, reference="centroid", device="cpu")[0]
    assert c.estimates["rms_radius_mm"].value == pytest.approx(c.estimates["rms_radius_centroid_mm"].value, rel=1e-9)
    assert c.estimates["centroid_y_mm"].value == pytest.approx(0.0, abs=1e-12)


def test_axial_and_lateral_colour(dgauss):
    ch = chromatic_focal_shift(dgauss, wavelength_nm=[486.1327, 587.5618, 656.2725], device="cpu")
    ref = first_order(dgauss).image_z_mm
    want = [first_order(dgauss, w).image_z_mm - ref for w in (486.1327, 587.5618, 656.2725)]
    np.testing.assert_allclose(ch.paraxial_shift_mm, want, atol=1e-12)
    assert ch.paraxial_shift_mm[1] == 0.0
    lat = lateral_colour(dgauss, lens_fields(dgauss), dgauss.wavelengths.nm, "cpu")
    d = lat.to_dict()
    assert np.all(np.asarray(d["real_from_primary_mm"])[:, 1] == 0.0)
    assert np.all(np.asarray(d["paraxial_from_primary_mm"])[0] == 0.0)  # the axis has no lateral colour
    # the fans carry lateral colour as their chief-ray offset: F minus C at the chief ray equals the table's
    # (this lens's image surface is its paraxial image plane)
    assert dgauss.image_z_mm == pytest.approx(lat.plane_z_mm, abs=1e-9)
    f = ray_fan(dgauss, 1.0, "tangential", [486.1327, 656.2725], [0.0], device="cpu")
    assert f.ey_mm[0, 0] - f.ey_mm[1, 0] == pytest.approx(lat.real_height_mm[-1, 0] - lat.real_height_mm[-1, 2],
                                                         abs=1e-8)


def test_fisheye_mappings():
    lens = library_lens("fisheye_10mm_f4")
    theta = np.radians([20.0, 50.0, 77.0, 95.0])
    c = distortion_curve(lens, object_values=theta, device="cpu")
    f = c.focal_length_mm
    np.testing.assert_allclose(c.mapping_height_mm["equidistant"], f * theta, rtol=1e-14)
    np.testing.assert_allclose(c.mapping_height_mm["equisolid"], 2 * f * np.sin(theta / 2), rtol=1e-14)
    np.testing.assert_allclose(c.mapping_height_mm["stereographic"], 2 * f * np.tan(theta / 2), rtol=1e-14)
    assert np.isnan(c.paraxial_height_mm[-1]) and np.isnan(c.distortion_percent[-1])  # no f tan(theta) at 95 deg
    assert np.isnan(c.mapping_height_mm["rectilinear"][-1])
    assert np.all(np.isfinite(c.paraxial_height_mm[:3]))
    assert c.closest_mapping() == "equidistant"
    assert abs(c.mapping_distortion_percent["equidistant"][2]) < 1.0  # an f-theta lens to 1 %
    with pytest.raises(LensrtError):
        mapping_height_mm("gnomonic", theta, 1.0)
    assert set(MAPPINGS) == {"rectilinear", "equidistant", "equisolid", "stereographic", "orthographic"}


def test_grid_distortion_is_the_radial_curve(dgauss):
    g = grid_distortion(dgauss, 5, device="cpu")
    assert g.mapping == "rectilinear"
    r = np.hypot(g.ideal_x_mm, g.ideal_y_mm)
    corner = r == r.max()
    fo = first_order(dgauss)
    assert r.max() == pytest.approx(fo.paraxial_image_height_mm, rel=1e-12)
    c = distortion_curve(dgauss, [1.0], device="cpu")
    np.testing.assert_allclose(g.distortion_percent[corner], c.distortion_percent[0], atol=1e-6)
    assert g.distortion_percent[2, 2] == 0.0
    # points stay on their azimuth (rotational symmetry)
    ok = r > 0
    np.testing.assert_allclose(np.arctan2(g.real_y_mm[ok], g.real_x_mm[ok]),
                               np.arctan2(g.ideal_y_mm[ok], g.ideal_x_mm[ok]), atol=1e-12)
    assert grid_distortion(library_lens("fisheye_10mm_f4"), 3, device="cpu").mapping == "equidistant"


def test_correction_names():
    assert correction_name(-0.1) == "under-corrected"
    assert correction_name(0.2) == "over-corrected"
    assert correction_name(1e-6, 1e-3) == "corrected"
