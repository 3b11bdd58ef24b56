"""Seidel sums: CODE V's transverse third-order table to its digits, and closed forms."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from _codev_listing import decimals, tho_table
from lensrt import load_lens
from lensrt.paraxial import CODEV_THO_COLUMNS, SEIDEL_NAMES, first_order, seidel_sums
from lensrt.prescription.materials import ConstantIndex, ModelGlass
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths


def _printed(value: float, text: str) -> None:
    assert abs(value - float(text)) <= 0.5 * 10.0 ** -decimals(text) + 1e-12, (value, text)


def test_codev_tho_per_surface_and_sum_to_listing_digits(library_dir) -> None:
    """SA TCO TAS SAS PTB DST AX LAT PTZ for every surface and the SUM row (CODE V ``tho``)."""
    table = tho_table()
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    sums = seidel_sums(lens)
    assert (sums.short_nm, sums.long_nm) == (486.1, 656.3)  # the file's F and C wavelengths
    tr = sums.transverse()
    total = sums.transverse_totals()
    for text, col in zip(table.pop("SUM"), CODEV_THO_COLUMNS):
        _printed(total[col], text)
    assert len(table) == lens.n_surfaces
    checked = 0
    for label, row in table.items():
        i = lens.stop_index if label == "STO" else int(label) - 1
        for text, col in zip(row, CODEV_THO_COLUMNS):
            _printed(tr[col][i], text)
            checked += 1
    assert checked == 9 * lens.n_surfaces


def test_petzval_column_is_petzval_curvature(library_dir) -> None:
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    sums = seidel_sums(lens)
    fo = first_order(lens)
    assert sums.transverse_totals()["PTZ"] == pytest.approx(-fo.petzval_sum_per_mm, rel=1e-14)
    # S_IV = H^2 * Petzval sum
    assert sums.totals()["petzval"] == pytest.approx(fo.lagrange_invariant ** 2 * fo.petzval_sum_per_mm, rel=1e-12)


def _thin_lens(n_glass, r1, r2, y=10.0, field_deg=15.0, distance=math.inf, conic2=0.0, asphere2=()):
    rows = (Surface(curvature_per_mm=1 / r1, thickness_mm=0.0, material=n_glass, is_stop=True),
            Surface(curvature_per_mm=1 / r2, thickness_mm=100.0, conic=conic2, asphere=asphere2))
    return Lens(surfaces=rows, aperture=Aperture("epd", 2 * y), fields=Fields("angle", (math.radians(field_deg),)),
                wavelengths=Wavelengths((486.1327, 587.5618, 656.2725), primary=1), object_distance_mm=distance)


def test_thin_lens_stop_at_lens_closed_forms() -> None:
    """Stop at a thin lens: S_III = H^2 K, S_IV = H^2 K / n, S_V = 0, C_I = y^2 K / V, C_II = 0 (Welford)."""
    glass = ModelGlass(1.6, 40.0)
    lens = _thin_lens(glass, 70.0, -150.0, distance=900.0)
    s = seidel_sums(lens)
    fo = first_order(lens)
    n = glass.index(587.5618)
    K = 1 / fo.efl_mm
    H, y = fo.lagrange_invariant, 10.0  # y: marginal height at the lens = EP radius
    t = s.totals()
    assert t["astigmatism"] == pytest.approx(H * H * K, rel=1e-12)
    assert t["petzval"] == pytest.approx(H * H * K / n, rel=1e-12)
    assert t["distortion"] == pytest.approx(0.0, abs=1e-15)
    assert t["lateral_colour"] == pytest.approx(0.0, abs=1e-15)
    dn = glass.index(486.1327) - glass.index(656.2725)
    assert t["axial_colour"] == pytest.approx(y * y * K * dn / (n - 1), rel=1e-12)
    assert glass.abbe_number() == pytest.approx(40.0, rel=1e-12)


def test_stigmatic_ellipsoid_has_no_spherical_aberration() -> None:
    """A conic with k = -1/n^2 refracting from air images the infinite axial point perfectly: S_I = 0."""
    n = 1.7
    rows = (Surface(curvature_per_mm=1 / 40.0, thickness_mm=150.0, material=ConstantIndex(n), is_stop=True,
                    conic=-1 / n ** 2),)
    lens = Lens(surfaces=rows, aperture=Aperture("epd", 20.0), fields=Fields("angle", (0.1,)))
    sphere = seidel_sums(lens.replace_surface(0, conic=0.0))
    conic = seidel_sums(lens)
    assert abs(sphere.totals()["spherical"]) > 1e-2
    assert conic.totals()["spherical"] == pytest.approx(0.0, abs=1e-14 * abs(sphere.totals()["spherical"]))
    assert conic.totals()["petzval"] == sphere.totals()["petzval"]


def test_asphere_r4_term_equals_conic_at_third_order() -> None:
    """A4 = k c^3 / 8 on a sphere gives the conic's Seidel sums; an r^2 term shifts the paraxial curvature."""
    glass = ModelGlass(1.55, 55.0)
    r2, k = -90.0, -2.5
    conic = seidel_sums(_thin_lens(glass, 60.0, r2, conic2=k))
    asph = seidel_sums(_thin_lens(glass, 60.0, r2, asphere2=(0.0, k / r2 ** 3 / 8.0)))
    np.testing.assert_allclose(asph.table(), conic.table(), rtol=1e-12, atol=1e-16)
    # asphere[0] (r^2) changes the paraxial curvature by 2 A2; its r^4 departure is counted against that sphere
    a2 = 1e-3
    c_par = 1 / r2 + 2 * a2
    with_a2 = seidel_sums(_thin_lens(glass, 60.0, r2, asphere2=(a2,)))
    sphere_same_par = seidel_sums(_thin_lens(glass, 60.0, 1 / c_par, asphere2=(0.0, (1 / r2 ** 3 - c_par ** 3) / 8)))
    np.testing.assert_allclose(with_a2.table(), sphere_same_par.table(), rtol=1e-11, atol=1e-16)


def test_stop_shift_invariants(library_dir) -> None:
    """S_I, S_IV and C_I do not depend on the stop position; a plane dummy surface in air adds nothing."""
    lens = load_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    base = seidel_sums(lens)
    # move the stop from surface 6 to surface 2 (keeping the same entrance pupil diameter)
    surfaces = [replace(sf, is_stop=(i == 1)) for i, sf in enumerate(lens.surfaces)]
    moved = lens.replace(surfaces=tuple(surfaces))
    other = seidel_sums(moved)
    assert other.totals()["spherical"] == pytest.approx(base.totals()["spherical"], rel=1e-12)
    assert other.totals()["petzval"] / other.lagrange_invariant ** 2 == pytest.approx(
        base.totals()["petzval"] / base.lagrange_invariant ** 2, rel=1e-12)
    assert other.totals()["axial_colour"] == pytest.approx(base.totals()["axial_colour"], rel=1e-12)
    assert other.totals()["coma"] != pytest.approx(base.totals()["coma"], rel=1e-3)
    assert np.all(base.table()[lens.stop_index] == 0.0)


def test_names_and_json_form(library_dir) -> None:
    s = seidel_sums(load_lens(library_dir / "codev_dblgauss_100mm_f2.toml"))
    d = s.to_dict()
    assert [f"{k}_mm" for k in SEIDEL_NAMES] == [k for k in d if k.endswith("_mm") and k != "per_surface_mm"]
    assert d["spherical_mm"] == pytest.approx(float(np.sum(d["per_surface_mm"]["spherical"])), rel=1e-14)
    w = s.wavefront_mm()
    assert w["W040"] == pytest.approx(d["spherical_mm"] / 8, rel=1e-15)
