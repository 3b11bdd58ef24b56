"""First-order data from real rays about the chief ray (``lensrt.analysis.parabasal``).

Oracles, each independent of the parabasal code:

* a rotationally symmetric lens: the y-nu trace (``lensrt.paraxial.first_order``), to 1e-8 relative;
* a lens folded by a tilted flat mirror: the y-nu trace of the unfolded axis (exact there);
* a concave spherical mirror tilted by theta: Coddington's closed forms, tangential focus R cos(theta)/2,
  sagittal R / (2 cos(theta)) (Kingslake, Lens Design Fundamentals, ch. on astigmatism);
* an ideal paraxial lens (OpticStudio's law on direction tangents) tilted by theta: f / cos(theta) in both
  sections (the tangent change -h/(f cos theta) over the tilted plane, projected on the chief ray);
* a tilt-shift lens (Cooke triplet tilted 8 deg about its stop): Coddington's equations traced along the
  real chief ray, surface by surface -- the tangential and sagittal focal distances are the y-z and x-z
  back focal distances;
* the same lens only shifted: the centred lens's y-nu data (a decenter alone changes nothing about the chief
  ray of the central field).
"""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from geometry_cases import folded_system

from lensrt.analysis.parabasal import FIRST_ORDER_METHOD, parabasal_first_order
from lensrt.cli import main
from lensrt.loading import load_lens
from lensrt.paraxial import first_order
from lensrt.prescription.geometry import CoordinateTransform
from lensrt.prescription.materials import AIR
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.prescription.tilt_shift import tilt_shift_lens
from lensrt.trace.reference import trace_reference
from lensrt.views.first_order import first_order_rows, info_data

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]
REL = 1e-8


def _lens(surfaces: list[Surface]) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", 4.0), fields=Fields("angle", (0.0,)),
                wavelengths=Wavelengths((587.5618,)))


@pytest.mark.parametrize("name", ["lens_prescriptions/dgauss_50mm_f2.toml", "tests/data/cooke_triplet.toml",
                                  "lens_prescriptions/reflex_nikkor_500mm_f8.toml"])
@pytest.mark.parametrize("distance_mm", [math.inf, 1500.0])
def test_rotationally_symmetric_lens_equals_ynu(name: str, distance_mm: float) -> None:
    lens = load_lens(ROOT / name)
    p, f = parabasal_first_order(lens, object_distance_mm=distance_mm), first_order(lens, None, distance_mm)
    z_last = float(lens.vertex_z_mm()[lens.n_surfaces - 1])
    for got in (p.efl_y_mm, p.efl_x_mm):
        assert got == pytest.approx(f.efl_mm, rel=REL)
    if math.isinf(distance_mm):
        assert p.bfl_y_mm == pytest.approx(f.bfl_mm, rel=REL) and p.bfl_x_mm == pytest.approx(f.bfl_mm, rel=REL)
        assert p.f_number_y == pytest.approx(f.f_number, rel=REL)
    else:
        for got in (p.magnification_y, p.magnification_x):
            assert got == pytest.approx(f.magnification, rel=REL)
        assert p.image_distance_y_mm == pytest.approx(f.image_distance_mm, rel=REL)
    assert p.entrance_pupil_distance_mm == pytest.approx(f.entrance_pupil_z_mm, rel=REL, abs=1e-7)
    assert z_last + p.exit_pupil_distance_mm == pytest.approx(f.exit_pupil_z_mm, rel=REL, abs=1e-7)
    assert abs(p.pupil_magnification) == pytest.approx(f.pupil_magnification, rel=REL)
    assert p.coupling < 1e-9


def test_fold_mirror_equals_the_unfolded_axis() -> None:
    lens = folded_system()
    p, f = parabasal_first_order(lens), first_order(lens)
    assert p.efl_y_mm == pytest.approx(f.efl_mm, rel=REL) and p.efl_x_mm == pytest.approx(f.efl_mm, rel=REL)
    assert p.bfl_y_mm == pytest.approx(f.bfl_mm, rel=REL) and p.bfl_x_mm == pytest.approx(f.bfl_mm, rel=REL)
    assert info_data(lens)["first_order_method"] == "paraxial ynu (unfolded axis)"


def test_decentred_compound_fold_keeps_the_focal_length() -> None:
    """tests/data/folded_obscured.zmx: the singlet's beam folded by a flat mirror decentred 0.5 mm and tilted
    45 deg about x and 2 deg about y. A flat mirror has no power, so the focal length in both sections is the
    singlet's (y-nu) -- which holds only if the sections are carried through the compound fold (the image
    surface's own x axis is turned 1.4 deg about the beam: read there, the EFL would be f / cos 1.4 deg)."""
    lens = load_lens(ROOT / "tests/data/folded_obscured.zmx")
    p, f = parabasal_first_order(lens), first_order(lens)
    assert p.efl_y_mm == pytest.approx(f.efl_mm, rel=REL) and p.efl_x_mm == pytest.approx(f.efl_mm, rel=REL)
    assert p.coupling < 1e-8
    assert info_data(lens)["first_order_method"] == "paraxial ynu (unfolded axis)"


def test_off_axis_parabola_focuses_at_its_focal_radius() -> None:
    """tests/data/readers_keywords.zmx: a 90 deg off-axis parabola (R = -190.6 mm, k = -1) fed by a
    collimated beam parallel to its axis. Every such ray reflects to the focus (stigmatic), at the distance
    f + r^2 / (4 f) from its hit (the focus-directrix property; f = R/2 in size, r the hit's distance from
    the parabola's axis): both sections' EFL and back focal distance are that distance."""
    lens = load_lens(ROOT / "tests/data/readers_keywords.zmx")
    p = parabasal_first_order(lens)
    mirror = next(i for i, s in enumerate(lens.surfaces) if s.mirror)
    wl = lens.wavelengths.nm[lens.wavelengths.primary]
    hit = trace_reference(lens, p.chief_ray_origin_mm, p.chief_ray_direction, wl, clip=False).hits[mirror]
    f = 0.5 / abs(lens.surfaces[mirror].curvature_per_mm)
    expected = f + (hit.x_mm ** 2 + hit.y_mm ** 2) / (4.0 * f)
    assert expected == pytest.approx(2 * f, rel=1e-9)  # the hit is 2 f off the axis: a 90 deg OAP
    for got in (p.efl_y_mm, p.efl_x_mm, p.bfl_y_mm, p.bfl_x_mm):
        assert abs(got) == pytest.approx(expected, rel=1e-9)
    assert info_data(lens)["first_order_method"] == FIRST_ORDER_METHOD


@pytest.mark.parametrize("theta_deg", [10.0, 25.0])
def test_tilted_spherical_mirror_follows_coddington(theta_deg: float) -> None:
    r = -200.0  # concave toward the light
    t = CoordinateTransform(tilt_x_rad=math.radians(theta_deg))
    lens = _lens([Surface(1.0 / r, -80.0, AIR, mirror=True, is_stop=True, transform_before=t, transform_after=t)])
    p, c = parabasal_first_order(lens), math.cos(math.radians(theta_deg))
    # the tilt is about x: the y-z section is the tangential one; after the mirror distances run toward -z
    assert p.bfl_y_mm == pytest.approx(r * c / 2.0, rel=1e-9)
    assert p.bfl_x_mm == pytest.approx(r / (2.0 * c), rel=1e-9)
    assert p.efl_y_mm == pytest.approx(-r * c / 2.0, rel=1e-9) and p.efl_x_mm == pytest.approx(-r / (2 * c), rel=1e-9)
    d = info_data(lens)
    assert d["first_order_method"] == FIRST_ORDER_METHOD == "real-ray parabasal about chief ray"
    assert d["parabasal"]["efl_y_mm"] == p.efl_y_mm


def test_tilted_ideal_lens_has_f_over_cos_theta() -> None:
    f, theta = 80.0, math.radians(15.0)
    t = CoordinateTransform(tilt_x_rad=theta)
    lens = _lens([Surface(0.0, 10.0, AIR, is_stop=True),
                  Surface(0.0, 70.0, AIR, ideal_focal_mm=f, transform_before=t, transform_after=t.inverse())])
    p = parabasal_first_order(lens)
    for got in (p.efl_y_mm, p.efl_x_mm, p.bfl_y_mm, p.bfl_x_mm):
        assert got == pytest.approx(f / math.cos(theta), rel=1e-9)


def _coddington(lens: Lens, origin: tuple, direction: tuple, wl: float) -> tuple[float, float]:
    """Tangential and sagittal focal distances (from the last surface, along the ray) of a parallel beam
    about the real ray (origin, direction): Coddington's equations surface by surface (object at infinity),
    n' cos^2 I' / t' = n cos^2 I / t + P,  n' / s' = n / s + P,  P = (n' cos I' - n cos I) / R."""
    ray = trace_reference(lens, origin, direction, wl, clip=False)
    n = lens.indices(wl)
    t = s = math.inf
    for i, surf in enumerate(lens.surfaces):
        h = ray.hits[i]
        if i > 0:
            t, s = t - h.length_mm, s - h.length_mm
        ci, cr = math.cos(h.incidence_rad), math.cos(h.refraction_rad)
        power = (n[i + 1] * cr - n[i] * ci) * surf.curvature_per_mm
        t = n[i + 1] * cr * cr / ((n[i] * ci * ci / t if math.isfinite(t) else 0.0) + power)
        s = n[i + 1] / ((n[i] / s if math.isfinite(s) else 0.0) + power)
    return t, s


@pytest.mark.parametrize("tilt_deg", [8.0, -5.0])
def test_tilt_shift_lens_follows_coddington_along_the_chief_ray(tilt_deg: float) -> None:
    base = load_lens(ROOT / "tests/data/cooke_triplet.toml")
    lens = tilt_shift_lens(base, math.radians(tilt_deg))  # turned about the stop's vertex
    wl = lens.wavelengths.nm[lens.wavelengths.primary]
    p = parabasal_first_order(lens)
    # the base ray is parallel to the camera axis and meets the stop at its centre
    assert p.chief_ray_direction == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)
    at_stop = trace_reference(lens, p.chief_ray_origin_mm, p.chief_ray_direction, wl, clip=False, end=lens.stop_index)
    assert abs(at_stop.x_mm) < 1e-10 and abs(at_stop.y_mm) < 1e-10
    tan_t, sag = _coddington(lens, p.chief_ray_origin_mm, p.chief_ray_direction, wl)
    assert p.bfl_y_mm == pytest.approx(tan_t, rel=1e-8)
    assert p.bfl_x_mm == pytest.approx(sag, rel=1e-8)
    assert abs(p.bfl_y_mm - p.bfl_x_mm) > 1e-3  # the tilt really makes the two sections differ
    # and the centred lens about its axis: the same Coddington trace is the y-nu back focal length
    assert _coddington(base, (0.0, 0.0, -20.0), (0.0, 0.0, 1.0), wl)[0] == pytest.approx(first_order(base).bfl_mm,
                                                                                          rel=1e-10)


def test_shifted_lens_keeps_the_centred_data() -> None:
    base = load_lens(ROOT / "tests/data/cooke_triplet.toml")
    lens = tilt_shift_lens(base, 0.0, (1.5, -2.0))
    p, f = parabasal_first_order(lens), first_order(base)
    assert p.efl_y_mm == pytest.approx(f.efl_mm, rel=REL) and p.bfl_x_mm == pytest.approx(f.bfl_mm, rel=REL)
    assert info_data(lens)["first_order_method"] == "paraxial ynu (unfolded axis)"


def test_info_labels_the_method(capsys, tmp_path) -> None:
    from lensrt.prescription.formats.native import dumps_native
    r = -200.0
    t = CoordinateTransform(tilt_x_rad=math.radians(20.0))
    lens = _lens([Surface(1.0 / r, -80.0, AIR, mirror=True, is_stop=True, transform_before=t, transform_after=t)])
    path = tmp_path / "tilted_mirror.toml"
    path.write_text(dumps_native(dataclasses.replace(lens, name="tilted mirror")))
    assert main(["info", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["first_order_method"] == "real-ray parabasal about chief ray"
    assert d["parabasal"]["bfl_y_mm"] == pytest.approx(r * math.cos(math.radians(20.0)) / 2.0, rel=1e-9)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert 'first_order_method = "real-ray parabasal about chief ray"' in out and "[parabasal]" in out
    # the first-order table (lensrt info and the report) names the method in a row of its own
    rows = first_order_rows(info_data(lens))
    assert ("first-order method", FIRST_ORDER_METHOD, "") in rows
    centred = tmp_path / "plain.toml"
    centred.write_text(dumps_native(load_lens(ROOT / "tests/data/cooke_triplet.toml")))
    assert main(["info", str(centred), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["first_order_method"] == "paraxial ynu" and "parabasal" not in d


def test_afocal_section_gives_infinite_focal_data() -> None:
    """A Keplerian telescope of two ideal lenses (f 100 and 25 mm, 125 mm apart): dv'/dy vanishes, so the
    focal quantities are inf, and the pupil magnification is the y-nu trace's 1/M = 0.25 in size."""
    lens = Lens((Surface(0.0, 125.0, AIR, ideal_focal_mm=100.0, is_stop=True),
                 Surface(0.0, 30.0, AIR, ideal_focal_mm=25.0)), aperture=Aperture("epd", 10.0),
                fields=Fields("angle", (0.0,)), wavelengths=Wavelengths((587.5618,)))
    p, f = parabasal_first_order(lens), first_order(lens)
    assert f.afocal and math.isinf(p.efl_y_mm) and math.isinf(p.bfl_x_mm) and math.isinf(p.f_number_y)
    assert abs(p.pupil_magnification) == pytest.approx(f.pupil_magnification, rel=REL)
    assert p.to_dict()["efl_y_mm"] is None
