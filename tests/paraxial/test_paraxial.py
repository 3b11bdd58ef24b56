"""Gaussian optics: closed forms, the CODE V listing (to its digits), the OpticStudio-checked Cooke triplet."""
from __future__ import annotations

import math

import numpy as np
import pytest

from _codev_listing import decimals, fio_table, first_order_values
from lensrt import load_lens
from lensrt.errors import LensrtError
from lensrt.paraxial import (chief_ray, first_order, paraxial_rays, paraxial_system, pupils, trace_ynu,
                             trace_ynu_reverse)
from lensrt.paraxial.photographic import afov_rad
from lensrt.prescription.materials import AIR, ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths


def _lens(rows, *, epd=10.0, distance=math.inf, object_material=AIR, fields=(0.0, math.radians(10.0))):
    return Lens(surfaces=tuple(Surface(**r) for r in rows), aperture=Aperture("epd", epd),
                fields=Fields("angle", tuple(fields)), wavelengths=Wavelengths((587.5618,)),
                object_distance_mm=distance, object_material=object_material)


def _printed(value: float, text: str) -> None:
    """``value`` rounds to the printed ``text`` (half a unit of its last digit)."""
    assert abs(value - float(text)) <= 0.5 * 10.0 ** -decimals(text) + 1e-12, (value, text)


# ---- closed forms -------------------------------------------------------------------------

def test_single_refracting_surface_gaussian_equation() -> None:
    """n/s + n'/s' = Phi (p. 2), f = n/Phi, f' = n'/Phi, P = P' at the vertex, N = N' at the centre."""
    R, n2, s = 50.0, 1.5, 300.0
    lens = _lens([dict(curvature_per_mm=1 / R, thickness_mm=400.0, material=ConstantIndex(n2), is_stop=True)],
                 distance=s)
    phi = (n2 - 1.0) / R
    fo = first_order(lens)
    s_img = n2 / (phi - 1.0 / s)
    assert 1.0 / s + n2 / s_img == pytest.approx(phi, rel=1e-14)
    assert fo.image_z_mm == pytest.approx(s_img, rel=1e-13)
    assert fo.efl_mm == pytest.approx(1 / phi, rel=1e-14)
    assert fo.front_focal_length_mm == pytest.approx(1 / phi, rel=1e-14)
    assert fo.rear_focal_length_mm == pytest.approx(n2 / phi, rel=1e-14)
    assert fo.front_principal_z_mm == pytest.approx(0.0, abs=1e-12)
    assert fo.rear_principal_z_mm == pytest.approx(0.0, abs=1e-12)
    assert fo.front_nodal_z_mm == pytest.approx(R, rel=1e-13)  # the centre of curvature
    assert fo.rear_nodal_z_mm == pytest.approx(R, rel=1e-13)
    # m = n s' / (n' s) with Cartesian s = -300 (p. 8)
    assert fo.magnification == pytest.approx(1.0 * s_img / (n2 * -s), rel=1e-13)


def test_thin_lens_lensmaker_and_unit_magnification() -> None:
    """1/f = (n - 1)(1/R1 - 1/R2); at s = 2f: s' = 2f, m = -1, mp = 1, b = 2, Nw = 2N (p. 31)."""
    n, R1, R2 = 1.5168, 60.0, -80.0
    f = 1.0 / ((n - 1.0) * (1 / R1 - 1 / R2))
    rows = [dict(curvature_per_mm=1 / R1, thickness_mm=0.0, material=ConstantIndex(n), is_stop=True),
            dict(curvature_per_mm=1 / R2, thickness_mm=2 * f)]
    fo = first_order(_lens(rows, distance=2 * f))
    assert fo.efl_mm == pytest.approx(f, rel=1e-14)
    assert fo.image_z_mm == pytest.approx(2 * f, rel=1e-13)
    assert fo.magnification == pytest.approx(-1.0, rel=1e-13)
    assert fo.pupil_magnification == pytest.approx(1.0, rel=1e-14)
    assert fo.bellows_factor == pytest.approx(2.0, rel=1e-13)
    assert fo.working_f_number == pytest.approx(2 * f / 10.0, rel=1e-13)
    assert fo.petzval_sum_per_mm == pytest.approx(1 / (n * f), rel=1e-13)  # thin lens: Phi / n


def test_thick_lens_power_and_cardinal_points() -> None:
    """Phi = Phi1 + Phi2 - (t/n) Phi1 Phi2 (p. 7); BFL = f (1 - t Phi1 / n); FFL = -f (1 - t Phi2 / n)."""
    n, R1, R2, t = 1.7, 40.0, -120.0, 9.0
    p1, p2 = (n - 1) / R1, (1 - n) / R2
    phi = p1 + p2 - t / n * p1 * p2
    rows = [dict(curvature_per_mm=1 / R1, thickness_mm=t, material=ConstantIndex(n), is_stop=True),
            dict(curvature_per_mm=1 / R2, thickness_mm=50.0)]
    fo = first_order(_lens(rows))
    assert fo.efl_mm == pytest.approx(1 / phi, rel=1e-14)
    assert fo.bfl_mm == pytest.approx((1 - t * p1 / n) / phi, rel=1e-13)
    assert fo.ffl_mm == pytest.approx(-(1 - t * p2 / n) / phi, rel=1e-13)
    assert fo.rear_principal_z_mm == pytest.approx(t - t * p1 / (n * phi), rel=1e-12)
    assert fo.front_principal_z_mm == pytest.approx(t * p2 / (n * phi), rel=1e-12)


def test_immersed_lens_front_and_rear_focal_lengths_differ() -> None:
    """Water in front, oil behind: f = n/Phi != f' = n'/Phi; nodal points shift (n' - n)/Phi; rays through N leave N' parallel."""
    n0, nl, nk, R1, R2, t = 1.333, 1.62, 1.48, 35.0, -60.0, 6.0
    p1, p2 = (nl - n0) / R1, (nk - nl) / R2
    phi = p1 + p2 - t / nl * p1 * p2
    rows = [dict(curvature_per_mm=1 / R1, thickness_mm=t, material=ConstantIndex(nl), is_stop=True),
            dict(curvature_per_mm=1 / R2, thickness_mm=80.0, material=ConstantIndex(nk))]
    lens = _lens(rows, object_material=ConstantIndex(n0), distance=400.0)
    fo = first_order(lens)
    assert fo.front_focal_length_mm == pytest.approx(n0 / phi, rel=1e-13)
    assert fo.rear_focal_length_mm == pytest.approx(nk / phi, rel=1e-13)
    assert fo.front_focal_length_mm != pytest.approx(fo.rear_focal_length_mm, rel=1e-3)
    assert fo.front_nodal_z_mm - fo.front_principal_z_mm == pytest.approx((nk - n0) / phi, rel=1e-12)
    # Gaussian conjugates in media (Cartesian): n'/s' - n/s = Phi, measured from P and P'
    s = fo.object_z_mm - fo.front_principal_z_mm
    s_img = fo.image_z_mm - fo.rear_principal_z_mm
    assert nk / s_img - n0 / s == pytest.approx(phi, rel=1e-12)
    assert fo.magnification == pytest.approx(n0 * s_img / (nk * s), rel=1e-12)
    # nodal property by trace: a ray aimed at N emerges from N' at the same angle
    sysm = paraxial_system(lens)
    u = 0.01
    ray = trace_ynu(sysm, -u * fo.front_nodal_z_mm, u)
    assert ray.u[-1] == pytest.approx(u, rel=1e-12)
    z_last = sysm.vertex_z_mm[-2]
    assert ray.height_at(fo.rear_nodal_z_mm - z_last) == pytest.approx(0.0, abs=1e-12)


def test_reverse_trace_inverts_forward_and_finds_front_focus(library_dir) -> None:
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    sysm = paraxial_system(lens, 486.1)
    fwd = trace_ynu(sysm, 7.0, -0.03)
    back = trace_ynu_reverse(sysm, fwd.y[-2], fwd.u[-1])
    np.testing.assert_allclose(back.y, fwd.y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back.u, fwd.u, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(back.i_angle, fwd.i_angle, rtol=1e-11, atol=1e-14)
    # a ray parallel in image space came from the front focal point
    fo = first_order(lens, 486.1)
    par = trace_ynu_reverse(sysm, 5.0, 0.0)
    assert -par.y[0] / par.u[0] == pytest.approx(fo.front_focal_z_mm, rel=1e-12)


def test_pupil_distances_match_principal_plane_formulas(library_dir) -> None:
    """s_EP = (1 - 1/mp) f and s'_XP = (1 - mp) f' (p. 10) against the traced pupils."""
    for name, wl in (("codev_dblgauss_100mm_f2.toml", 656.3), ("codev_dblgauss_100mm_f2.toml", 486.1)):
        fo = first_order(load_lens(library_dir / name), wl)
        mp = fo.pupil_magnification
        assert fo.front_principal_z_mm - fo.entrance_pupil_z_mm == pytest.approx(
            (1 - 1 / mp) * fo.front_focal_length_mm, rel=1e-12)
        assert fo.entrance_pupil_distance_mm == pytest.approx((1 - 1 / mp) * fo.front_focal_length_mm, rel=1e-12)
        assert fo.exit_pupil_z_mm - fo.rear_principal_z_mm == pytest.approx(
            (1 - mp) * fo.rear_focal_length_mm, rel=1e-12)
    # immersed, stop behind a strong front group: mp far from 1, f != f'
    rows = [dict(curvature_per_mm=1 / 30.0, thickness_mm=5.0, material=ConstantIndex(1.7)),
            dict(curvature_per_mm=0.0, thickness_mm=10.0, material=ConstantIndex(1.2)),
            dict(curvature_per_mm=0.0, thickness_mm=8.0, material=ConstantIndex(1.2), is_stop=True),
            dict(curvature_per_mm=-1 / 45.0, thickness_mm=40.0, material=ConstantIndex(1.4))]
    fo = first_order(_lens(rows, object_material=ConstantIndex(1.1)))
    mp = fo.pupil_magnification
    assert abs(mp - 1) > 0.05
    assert fo.entrance_pupil_distance_mm == pytest.approx((1 - 1 / mp) * fo.front_focal_length_mm, rel=1e-12)
    assert fo.exit_pupil_distance_mm == pytest.approx((1 - mp) * fo.rear_focal_length_mm, rel=1e-12)


def test_finite_distance_magnification_working_fnumber_and_afov(library_dir) -> None:
    """|m| = f/(s - f) (p. 8); Nw = b N = 1/(2 n'|u'|); AFoV with b equals the traced chief-ray angle (p. 17)."""
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    d = 450.0
    fo = first_order(lens, object_distance_mm=d)
    s = fo.front_principal_z_mm - fo.object_z_mm
    assert abs(fo.magnification) == pytest.approx(fo.efl_mm / (s - fo.efl_mm), rel=1e-12)
    m_ray, _, sysm = paraxial_rays(lens, object_distance_mm=d)
    assert fo.working_f_number == pytest.approx(1 / (2 * abs(m_ray.u[-1])), rel=1e-12)
    assert fo.bellows_factor == pytest.approx(1 + abs(fo.magnification) / fo.pupil_magnification, rel=1e-14)
    # chief ray that lands at the edge of a 36 mm wide sensor in the image plane
    half_width = 18.0
    hl = lens.replace(fields=Fields("paraxial_image_height", (half_width,)))
    pup = pupils(sysm)
    ray = chief_ray(hl, sysm, half_width, d, pup.entrance_z_mm, fo.entrance_pupil_diameter_mm)
    assert ray.height_at(fo.image_distance_mm) == pytest.approx(half_width, rel=1e-12)
    assert 2 * math.atan(ray.u[0]) == pytest.approx(
        afov_rad(2 * half_width, fo.efl_mm, fo.bellows_factor), rel=1e-12)
    # unit focusing: the image moved back by e = f^2 / (s - f) (p. 12)
    assert fo.unit_focus_extension_mm == pytest.approx(fo.efl_mm ** 2 / (s - fo.efl_mm), rel=1e-12)


def test_lagrange_invariant_at_image(library_dir) -> None:
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    fo = first_order(lens)
    m, c, _ = paraxial_rays(lens)
    assert fo.lagrange_invariant == pytest.approx(-m.u[-1] * fo.paraxial_image_height_mm, rel=1e-12)
    # every surface: n (u_c y_m - u_m y_c) is invariant
    n = m.n
    h = n[1:] * (c.u[1:] * m.y[:-1] - m.u[1:] * c.y[:-1])
    np.testing.assert_allclose(h, fo.lagrange_invariant, rtol=1e-12)


def test_afocal_and_bad_distance_are_reported() -> None:
    rows = [dict(curvature_per_mm=0.0, thickness_mm=5.0, material=ConstantIndex(1.5), is_stop=True),
            dict(curvature_per_mm=0.0, thickness_mm=10.0)]
    plate = first_order(_lens(rows))  # afocal (issue 17): angular magnification instead of an error
    assert plate.afocal and plate.angular_magnification == pytest.approx(1.0, rel=1e-15)
    assert math.isinf(plate.efl_mm) and plate.entrance_pupil_diameter_mm > 0.0
    rows = [dict(curvature_per_mm=1 / 50.0, thickness_mm=5.0, material=ConstantIndex(1.5), is_stop=True),
            dict(curvature_per_mm=0.0, thickness_mm=90.0)]
    lens = _lens(rows)
    with pytest.raises(LensrtError, match="positive"):
        first_order(lens, object_distance_mm=-5.0)
    fo = first_order(lens)
    with pytest.raises(LensrtError, match="image is at infinity"):
        first_order(lens, object_distance_mm=-fo.front_focal_z_mm)


def test_image_space_telecentric_lens_has_exit_pupil_at_infinity() -> None:
    """Stop at the front focal point: XP at infinity, reported as inf (null in JSON), b = 1."""
    f = 100.0
    rows = [dict(curvature_per_mm=0.0, thickness_mm=f, is_stop=True),
            dict(curvature_per_mm=1 / (0.5 * f), thickness_mm=0.0, material=ConstantIndex(1.5)),
            dict(curvature_per_mm=0.0, thickness_mm=f)]
    fo = first_order(_lens(rows, distance=1000.0))
    assert math.isinf(fo.exit_pupil_z_mm) and math.isinf(fo.exit_pupil_diameter_mm)
    assert fo.bellows_factor == 1.0


# ---- the CODE V double Gauss listing ------------------------------------------------------

def test_codev_first_order_to_listing_digits(library_dir) -> None:
    lis = first_order_values()
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    fo = first_order(lens)
    last_vertex = fo.overall_length_mm
    _printed(fo.efl_mm, lis["EFL"])
    _printed(fo.bfl_mm, lis["BFL"])
    _printed(fo.ffl_mm, lis["FFL"])
    _printed(fo.f_number, lis["FNO"])
    _printed(fo.image_surface_distance_mm, lis["IMG DIS"])
    _printed(fo.overall_length_mm, lis["OAL"])
    _printed(fo.paraxial_image_height_mm, lis["HT"])
    _printed(fo.half_field_deg, lis["ANG"])
    _printed(fo.entrance_pupil_diameter_mm, lis["ENTRANCE PUPIL DIA"])
    _printed(fo.entrance_pupil_z_mm, lis["ENTRANCE PUPIL THI"])
    _printed(fo.exit_pupil_diameter_mm, lis["EXIT PUPIL DIA"])
    _printed(fo.exit_pupil_z_mm - last_vertex, lis["EXIT PUPIL THI"])
    # the .seq's field is YAN 10.0000000023 deg (the library file keeps the sequence's digits)
    assert fo.field_image_heights_mm[1] == pytest.approx(fo.efl_mm * math.tan(lens.fields.y[1]), rel=1e-12)


def test_codev_fio_table_to_listing_digits(library_dir) -> None:
    """HMY UMY N*IMY HCY UCY N*ICY per surface, the EP and IMG rows (CODE V ``fio``)."""
    table = fio_table()
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    m, c, sysm = paraxial_rays(lens)
    z_ep = pupils(sysm).entrance_z_mm
    ep = table.pop("EP")
    for got, text in zip((m.y[0] + m.u[0] * z_ep, m.u[0], c.y[0] + c.u[0] * z_ep, c.u[0]), ep):
        _printed(got, text)
    img = table.pop("IMG")
    for got, text in zip((m.y[-1], m.u[-1], c.y[-1], c.u[-1]), img):
        _printed(got, text)
    assert len(table) == lens.n_surfaces
    for label, row in table.items():
        i = lens.stop_index if label == "STO" else int(label) - 1
        got = (m.y[i], m.u[i + 1], m.n[i] * m.i_angle[i], c.y[i], c.u[i + 1], c.n[i] * c.i_angle[i])
        for g, text in zip(got, row):
            _printed(g, text)


# ---- the OpticStudio-checked Cooke triplet ------------------------------------------------

def test_cooke_triplet_matches_opticstudio(data_dir) -> None:
    lens = load_lens(data_dir / "cooke_triplet.toml")
    assert lens.wavelengths.primary_nm == 550.0
    fo = first_order(lens)
    rel = 1e-5
    assert fo.efl_mm == pytest.approx(49.999783, rel=rel)
    assert fo.f_number == pytest.approx(4.999978, rel=rel)
    assert fo.entrance_pupil_z_mm == pytest.approx(11.512159, rel=rel)
    assert fo.exit_pupil_diameter_mm == pytest.approx(10.233729, rel=rel)
    assert fo.exit_pupil_z_mm - fo.total_track_mm == pytest.approx(-50.961348, rel=rel)
    assert fo.lagrange_invariant == pytest.approx(1.819851, rel=rel)
