"""Bokeh set-up: unit focusing, the Gaussian blur disc, source placement by the real chief ray, the XYZ light."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bokeh_cases import BK7, singlet

from lensrt import load_lens
from lensrt.analysis.bokeh.entry import (focus_lens, gaussian_blur, map_sources, sensor_frame, spot_source,
                                   stop_radius_for_f_number)
from lensrt.analysis.bokeh.light import bokeh_light
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order
from lensrt.paraxial.photographic import unit_focus_extension_mm


@pytest.fixture(scope="module")
def dgauss():
    return load_lens("dgauss_50mm_f2")


def test_unit_focus_moves_the_sensor_by_newtons_extension(dgauss):
    fo = first_order(dgauss)
    for s in (500.0, 2000.0, 1.0e5):
        f = focus_lens(dgauss, s)
        # the object at s (from the first vertex of the focused lens) images onto the sensor plane
        assert f.sensor_z_mm == pytest.approx(first_order(dgauss, object_distance_mm=s).image_z_mm, abs=1e-9)
        # e = f f' / (s_P - f) with s_P from the front principal plane (p. 12)
        s_p = s + fo.front_principal_z_mm
        assert f.extension_mm == pytest.approx(unit_focus_extension_mm(s_p, fo.front_focal_length_mm,
                                                                       fo.rear_focal_length_mm), rel=1e-9)
        back = focus_lens(dgauss, extension_mm=f.extension_mm)
        assert back.distance_mm == pytest.approx(s, rel=1e-9)
        assert focus_lens(dgauss, sensor_z_mm=f.sensor_z_mm).distance_mm == pytest.approx(s, rel=1e-9)
    inf = focus_lens(dgauss, math.inf)
    assert inf.extension_mm == 0.0 and inf.sensor_z_mm == dgauss.image_z_mm


def test_unit_focus_keeps_the_files_focus_offset(dgauss):
    # a file whose image surface sits 0.05 mm behind the paraxial focus keeps that offset when focused
    shifted = dgauss.replace_surface(dgauss.n_surfaces - 1, thickness_mm=dgauss.surfaces[-1].thickness_mm + 0.05)
    for s in (math.inf, 1500.0):
        assert focus_lens(shifted, s).sensor_z_mm - focus_lens(dgauss, s).sensor_z_mm == pytest.approx(0.05, abs=1e-9)


def test_focus_errors(dgauss):
    with pytest.raises(LensrtError, match="front focal point"):
        focus_lens(dgauss, 20.0)  # F lies 27.1 mm in front of the first vertex
    with pytest.raises(LensrtError, match="one of"):
        focus_lens(dgauss, 1000.0, extension_mm=1.0)
    with pytest.raises(LensrtError, match="beyond infinity"):
        focus_lens(dgauss, extension_mm=-1.0)
    with pytest.raises(LensrtError, match="not behind the last vertex"):
        focus_lens(dgauss, sensor_z_mm=10.0)
    beyond = focus_lens(dgauss, sensor_z_mm=dgauss.image_z_mm - 0.1)
    assert math.isnan(beyond.distance_mm) and beyond.to_dict()["distance_mm"] is None


def test_gaussian_blur_formula_forms_agree_and_scale_with_the_stop(dgauss):
    f = focus_lens(dgauss, 2000.0)
    for d in (800.0, 10000.0):
        g = gaussian_blur(dgauss, f, d)
        # D_XP |dz| / (z' - z_XP) equals |dz| / N_w of the source's conjugate (in air)
        assert g.diameter_mm == pytest.approx(g.diameter_from_working_f_number_mm, rel=1e-10)
        assert (g.defocus_mm > 0) == (d > 2000.0)  # background: the sensor lies behind the image
        half = gaussian_blur(dgauss, f, d, stop_radius_mm=0.5 * dgauss.surfaces[dgauss.stop_index].semi_diameter_mm)
        assert half.diameter_mm == pytest.approx(0.5 * g.diameter_mm, rel=1e-12)
    assert gaussian_blur(dgauss, f, 2000.0).diameter_mm == pytest.approx(0.0, abs=1e-9)


def test_stop_radius_for_f_number(dgauss):
    n0 = first_order(dgauss).f_number
    r4 = stop_radius_for_f_number(dgauss, 4.0)
    # at the lens's own (paraxial) f-number: its own stop but for the real pupil's aberration (~1 %);
    # stopped down, nearly proportional to D = f/N
    assert stop_radius_for_f_number(dgauss, n0) == pytest.approx(dgauss.surfaces[dgauss.stop_index].semi_diameter_mm,
                                                                 rel=0.02)
    assert r4 == pytest.approx(dgauss.surfaces[dgauss.stop_index].semi_diameter_mm * n0 / 4.0, rel=0.03)


def test_map_sources_land_on_a_uniform_sensor_grid(dgauss, device):
    from lensrt.trace import RayBatch, trace
    from lensrt.trace.aiming import FieldPoint, aim_rays, reference_to_stop
    f = focus_lens(dgauss, 2000.0)
    frame = sensor_frame((36.0, 24.0), (360, 240))
    src = map_sources(dgauss, f, frame, (4, 3), [1000.0, 20000.0], device=device)
    assert len(src) == 24
    # picture left to right: depths in order inside each cell, the grid uniform in the sensor frame
    xs = sorted({round(s["target_mm"][0], 9) for s in src})
    assert np.allclose(np.diff(xs), 36.0 / 8)
    assert src[0]["depth_mm"] == 1000.0 and src[1]["depth_mm"] == 20000.0
    assert src[0]["intensity_cd"] == pytest.approx(1.0) and src[1]["intensity_cd"] == pytest.approx(400.0)
    # the real chief ray (through the centre of the real stop) of each object point meets its target
    for s in src[::5]:
        fp = FieldPoint(False, None, tuple(s["object_mm"]))
        o, d, ok = aim_rays(dgauss, fp, np.zeros(1), np.zeros(1), f.wavelength_nm, "real", reference_to_stop(dgauss))
        r = trace(dgauss, RayBatch(o, d, f.wavelength_nm), "float64", device, clip=False, plane_z_mm=f.sensor_z_mm)
        assert ok[0] and r.ok[0]
        assert r.position_mm[0, :2] == pytest.approx(s["target_mm"], abs=1e-6)


def test_spot_source_placements(dgauss):
    from lensrt.paraxial import first_order as fo_
    f = focus_lens(dgauss, 2000.0)
    z_ep = fo_(dgauss).entrance_pupil_z_mm
    s = spot_source(dgauss, f, 5000.0, field_deg=(0.0, 10.0))
    # seen at 10 deg from the entrance pupil; a positive field angle puts the object below the axis
    assert math.degrees(math.atan2(-s["object_mm"][1], 5000.0 + z_ep)) == pytest.approx(10.0, abs=1e-12)
    assert spot_source(dgauss, f, 5000.0)["object_mm"] == [0.0, 0.0, -5000.0]
    assert spot_source(dgauss, f, 5000.0, object_mm=(3.0, -4.0))["object_mm"] == [3.0, -4.0, -5000.0]
    with pytest.raises(LensrtError, match="one of"):
        spot_source(dgauss, f, 5000.0, field_deg=(0, 1), image_mm=(0, 1))
    with pytest.raises(LensrtError, match="positive"):
        spot_source(dgauss, f, -1.0)


def test_sensor_frame():
    fr = sensor_frame((36.0, 24.0), (1500, 1000))
    assert fr.pitch_mm == pytest.approx(0.024) and fr.x0_mm == -18.0 and fr.y0_mm == pytest.approx(-12.0)
    with pytest.raises(LensrtError, match="not square"):
        sensor_frame((36.0, 24.0), (1500, 1500))


def test_light_tables_reproduce_cie_data():
    import colour
    d65 = bokeh_light("D65")
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    assert d65.chromaticity_xy == pytest.approx(tuple(white), abs=2e-4)
    a = bokeh_light("A")
    assert a.chromaticity_xy == pytest.approx(tuple(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["A"]),
                                              abs=2e-4)
    # a single line: its chromaticity is the spectral locus there, and no spectral noise (kappa = 1)
    line = bokeh_light("550")
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"][550]
    assert line.chromaticity_xy == pytest.approx(tuple(cmfs[:2] / cmfs.sum()), abs=1e-9)
    assert np.allclose(line.kappa, 1.0)
    assert np.all(d65.kappa > 1.0)
    bb = bokeh_light("blackbody:6504")
    assert bb.chromaticity_xy == pytest.approx((0.3135, 0.3236), abs=2e-3)  # near D65, below the locus
    lens_light = bokeh_light("lens", singlet(material=BK7))
    assert lens_light.mode == 0 and len(lens_light.line_nm) == 3


@pytest.mark.parametrize("spec,msg", [("D66", "did you mean D65"), ("1000", "no line lies"),
                                      ("blackbody:warm", "blackbody:K"), ("blackbody:50", "outside")])
def test_light_errors(spec, msg):
    with pytest.raises(LensrtError, match=msg):
        bokeh_light(spec)


def test_near_far_depths_give_equal_blur(dgauss):
    from lensrt.analysis.bokeh.entry import near_far_depths_mm
    near, far = near_far_depths_mm(2000.0)
    assert near < 2000.0 < far == 40000.0
    f = focus_lens(dgauss, 2000.0)
    g_near, g_far = gaussian_blur(dgauss, f, near), gaussian_blur(dgauss, f, far)
    assert g_near.defocus_mm < 0 < g_far.defocus_mm
    assert g_near.diameter_mm == pytest.approx(g_far.diameter_mm, rel=0.1)  # equal for s >> f
    with pytest.raises(LensrtError):
        near_far_depths_mm(math.inf)


def test_placement_through_strong_distortion():
    # the macro lens focused far away maps object height to image height very non-linearly; the
    # paraxial start for 11-14 mm has no chief ray at all, and the solve must still land there
    from lensrt.analysis.bokeh.trace import object_heights_for_image
    lens = load_lens("micro_nikkor_105mm_f2.8_macro")
    f = focus_lens(lens, 2000.0)
    r = np.array([8.0, 11.0, 14.0])
    y, ok = object_heights_for_image(lens, 1000.0, f.sensor_z_mm, r, f.wavelength_nm, "cpu")
    assert ok.all() and np.all(np.diff(y) < 0)
    y2, ok2 = object_heights_for_image(lens, 1000.0, f.sensor_z_mm, r + 1e-3, f.wavelength_nm, "cpu")
    assert ok2.all() and np.all(y2 < y)  # monotonic: a nearby target, a nearby object point
