"""Vignetting and relative illumination: the cos^4 law where it must hold, and independent integrations.

Where cos^4 must hold: a thin plano-convex lens (f = 1000 mm, 0.1 mm thick, f/100) with its stop on
its flat first face. Nothing precedes the stop, so the entrance pupil is the flat stop disc itself:
a collimated beam at angle theta sees it foreshortened, A(theta) = A(0) cos(theta), exactly, with no
pupil aberration and no vignetting (no other aperture clips). The chief ray enters at the vertex of
the plane face and leaves a 0.1 mm thin lens almost undeviated, so the image is rectilinear,
y' = f tan(theta), up to a distortion of 4e-5 at 30 deg; with dA/dOmega = y' y'_theta / sin(theta)
= f^2 / cos^3(theta) the irradiance goes as cos(theta) cos^3(theta) = cos^4(theta) (Field Guide p. 32).
The exit pupil, the stop's image through the lens, sits at the lens, so seen from the image point
at f / cos(theta) its projected solid angle also goes as cos^4.

Independent integration for a vignetting lens (the 50 mm f/2 double Gauss at 22 deg, 74 % of the
pupil vignetted): the pupil's outline found by bisection with the float64 *reference tracer* and
integrated in polar coordinates, against the stream kernel's Monte Carlo estimate.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.compare.distortion import distortion_curve
from lensrt.analysis.compare.pupils import pupil_outline, stop_only_lens
from lensrt.analysis.compare.vignetting import mapping_factor, vignetting
from lensrt.loading import complete_lens
from lensrt.paraxial import first_order
from lensrt.prescription.materials import AIR, ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths


def thin_lens(thickness_mm: float = 0.1, radius_mm: float = -500.0, stop_radius_mm: float = 5.0) -> Lens:
    """Plano-convex, n = 1.5, f = 1000 mm, stop on the flat front face, image at the paraxial focus."""
    s = (Surface(0.0, thickness_mm, ConstantIndex(1.5), semi_diameter_mm=stop_radius_mm, is_stop=True),
         Surface(1.0 / radius_mm, 100.0, AIR, semi_diameter_mm=stop_radius_mm + 2.0))
    lens = Lens(s, Aperture("float_by_stop", 0.0), Fields("angle", (0.0, math.radians(30.0))),
                Wavelengths((587.6,)), name="thin plano-convex, stop on the flat face")
    return complete_lens(lens.replace_surface(1, thickness_mm=first_order(lens).bfl_mm))


def test_thin_lens_is_rectilinear():
    lens = thin_lens()
    assert first_order(lens).efl_mm == pytest.approx(1000.0, rel=1e-12)
    c = distortion_curve(lens, [0.5, 0.8, 1.0], device="cpu")
    assert np.max(np.abs(c.distortion_percent)) < 5e-3  # < 5e-5 relative: the mapping is f tan(theta)


def test_relative_illumination_is_cos4_for_the_thin_lens():
    lens = thin_lens()
    v = vignetting(lens, [0.5, 0.8, 1.0], rays=1 << 17, batches=32, device="cpu")
    ri, se = v.values("relative_illumination"), v.stderrs("relative_illumination")
    cos4 = np.cos(np.radians([15.0, 24.0, 30.0])) ** 4
    np.testing.assert_allclose(v.cos4, cos4, rtol=1e-12)
    assert np.all(se < 4e-4)
    np.testing.assert_allclose(ri, cos4, atol=1e-3)
    np.testing.assert_allclose(v.relative_illumination_exit_pupil, cos4, atol=1e-3)
    # the pupil area is the stop foreshortened, A(0) cos(theta); nothing vignettes
    area = v.values("pupil_area")
    np.testing.assert_allclose(area, math.pi * 25.0 * np.cos(np.radians([15.0, 24.0, 30.0])), rtol=1e-3)
    np.testing.assert_allclose(v.values("vignetting_fraction"), 1.0, atol=1e-12)
    # the mapping factor is cos^3 to the lens's tiny distortion
    np.testing.assert_allclose(v.mapping_factor, np.cos(np.radians([15.0, 24.0, 30.0])) ** 3, rtol=3e-4)


def test_vignetted_pupil_area_against_reference_integration():
    """Stream kernel estimate (Monte Carlo, +- s.e.) against the reference tracer's outline integral."""
    lens = library_lens("dgauss_50mm_f2")
    theta = math.radians(22.0)
    ref = pupil_outline(lens, theta, n_azimuth=240, iterations=28, tracer="reference", device="cpu")
    ref0 = pupil_outline(lens, 0.0, n_azimuth=240, iterations=28, tracer="reference", device="cpu")
    v = vignetting(lens, object_values=[theta], rays=1 << 17, batches=32, exit_pupil=False, device="cpu")
    est = v.pupil_area[0]
    assert est.value / ref0.area_mm2 < 0.3  # strongly vignetted (a cat's eye)
    assert abs(est.value - ref.area_mm2) < 4.0 * est.stderr + 1e-4 * ref.area_mm2
    assert est.stderr / est.value < 1e-3
    # relative illumination with the reference areas and the same chief-ray mapping
    m, _ = mapping_factor(lens, np.array([theta]), lens.wavelengths.primary_nm, "cpu")
    ri_ref = ref.area_mm2 / ref0.area_mm2 * m[0]
    ri = v.relative_illumination[0]
    assert abs(ri.value - ri_ref) < 4.0 * ri.stderr + 1e-4 * ri_ref
    # the kernel outline agrees with the reference one (same method, other tracer)
    ker = pupil_outline(lens, theta, n_azimuth=240, iterations=28, tracer="kernel", device="cpu")
    assert ker.area_mm2 == pytest.approx(ref.area_mm2, rel=1e-9)


def test_vignetting_fraction_against_outlines():
    lens = library_lens("dgauss_50mm_f2")
    theta = math.radians(15.4)
    a = pupil_outline(lens, theta, device="cpu").area_mm2
    a_stop = pupil_outline(stop_only_lens(lens), theta, device="cpu").area_mm2
    v = vignetting(lens, object_values=[theta], rays=1 << 16, exit_pupil=False, device="cpu")
    frac = v.vignetting_fraction[0]
    assert abs(frac.value - a / a_stop) < 4.0 * frac.stderr + 1e-4


def test_finite_object_projected_solid_angle():
    """The Lambertian-weighted stream estimate (sr) against the outline's quadrature, at 1:1."""
    lens = library_lens("micro_nikkor_105mm_f2.8_macro")
    from lensrt.analysis.raysets import field_spec
    h = field_spec(lens, 1.0).object_value
    out = pupil_outline(lens, h, device="cpu")
    assert out.projected_solid_angle_sr is not None and out.projected_solid_angle_sr > 0
    v = vignetting(lens, object_values=[h], rays=1 << 16, exit_pupil=False, device="cpu")
    est = v.pupil_area[0]
    assert est.unit == "sr"
    assert abs(est.value - out.projected_solid_angle_sr) < 4.0 * est.stderr + 1e-4 * est.value


def test_relative_illumination_json_and_bad_input():
    lens = thin_lens()
    v = vignetting(lens, [0.0, 1.0], rays=1 << 10, batches=8, device="cpu")
    d = v.to_dict()
    assert "pupil_area_mm2" in d and "relative_illumination" in d and d["field_deg"][1] == pytest.approx(30.0)
    assert d["relative_illumination"][0]["stderr"] >= 0.0
    from lensrt.errors import LensrtError
    with pytest.raises(LensrtError):
        vignetting(lens, object_values=[-0.1], rays=1 << 10, device="cpu")


def test_stop_only_pupil_respects_element_rims():
    """The Cooke triplet does not vignette with its computed clear apertures (a deterministic 801 x 801 grid
    gives the same pupil area with every aperture as with the stop alone), so the unvignetted fraction is 1
    within its error at every field -- with a stop-only lens that keeps each element's physical rim. Its
    front element's faces meet at 11.3 mm: a stop-only pupil without that rim let rays through at 20 mm."""
    from lensrt.analysis.compare.pupils import physical_rim_mm
    from lensrt.analysis.raysets import object_field_point
    from lensrt.trace.pupil_boxes import pupil_box
    lens = library_lens("cooke_triplet_50mm_f5")
    rim = physical_rim_mm(lens, 0)
    a, b = lens.surfaces[0], lens.surfaces[1]
    assert a.thickness_mm + b.sag(rim) - a.sag(rim) == pytest.approx(0.0, abs=2e-6)   # the two faces meet there
    assert 11.0 < rim < 11.6
    v = vignetting(lens, [0.1, 0.4, 1.0], rays=1 << 15, exit_pupil=False, device="cpu")
    for frac in v.vignetting_fraction:
        assert abs(frac.value - 1.0) < 3.0 * frac.stderr + 2e-4, frac
    # the Monte Carlo box of the stop-only pupil stays close to the pupil (was 895 mm^2 for a 79 mm^2 pupil)
    stop_lens = stop_only_lens(lens)
    for theta, area in zip(v.object_value, v.stop_pupil_area):
        box = pupil_box(stop_lens, object_field_point(stop_lens, float(theta)), device="cpu")
        assert box.area_mm2 <= 1.5 * area.value, (theta, box.area_mm2, area.value)



def test_relative_illumination_methods_are_flagged_where_they_part():
    """On the f/1.4 Petzval at 7 deg the exit-pupil method (valid only where a field's rays meet in a point)
    gives 0.937 against the flux method's 0.964 +- 0.001: the comparison flags it and says which to read; on
    the thin f/100 lens (cos^4) the two agree and nothing is flagged."""
    lens = library_lens("petzval_51mm_f1.4")
    v = vignetting(lens, object_values=[math.radians(7.0)], rays=1 << 14, device="cpu")
    flux, xp = v.relative_illumination[0], v.relative_illumination_exit_pupil[0]
    assert abs(flux.value - xp) > 10 * flux.stderr
    assert v.ri_methods_agree == [False]
    assert "7.00 deg" in v.ri_disagreement_note() and "flux" in v.ri_disagreement_note()
    assert v.to_dict()["relative_illumination_methods_agree"] == [False]
    good = vignetting(thin_lens(), object_values=[math.radians(20.0)], rays=1 << 14, device="cpu")
    assert good.ri_methods_agree == [True] and good.ri_disagreement_note() is None
