"""Sag and gradient of the surface kinds (lensrt.prescription.shapes) against closed forms and optiland."""
from __future__ import annotations

import math

import numpy as np
import pytest

from shape_cases import anamorphic, freeform, fringe, phone_odd_qcon

from lensrt.errors import PrescriptionError
from lensrt.prescription.model import Surface
from lensrt.prescription.shapes import (MAX_FRINGE_TERMS, SurfaceShape, fringe_nm, noll_nm, profile_of, qbfs_sum,
                                        qbfs_to_p_basis, qcon_sum, sag_grad, vertex_expansion)

XS = np.linspace(0.0, 1.0, 11)


def _qbfs_closed(m: int, x: float) -> float:
    """Forbes (2007) eq. (A.4)-(A.6): the first three Q^bfs polynomials."""
    return [1.0, (13.0 - 16.0 * x) / math.sqrt(19.0),
            math.sqrt(2.0 / 95.0) * (29.0 - 4.0 * x * (25.0 - 19.0 * x))][m]


def _qcon_closed(m: int, x: float) -> float:
    """Forbes (2007) eq. (2.6): the first four Q^con polynomials."""
    return [1.0, -(5.0 - 6.0 * x), 15.0 - 14.0 * x * (3.0 - 2.0 * x),
            -(35.0 - 12.0 * x * (14.0 - x * (21.0 - 10.0 * x)))][m]


@pytest.mark.parametrize("m", [0, 1, 2])
def test_qbfs_polynomials_match_forbes_closed_forms(m: int) -> None:
    b = qbfs_to_p_basis([0.0] * m + [1.0])
    for x in XS:
        assert qbfs_sum(b, x)[0] == pytest.approx(_qbfs_closed(m, x), abs=1e-13)


@pytest.mark.parametrize("m", [0, 1, 2, 3])
def test_qcon_polynomials_match_forbes_closed_forms(m: int) -> None:
    for x in XS:
        assert qcon_sum([0.0] * m + [1.0], x)[0] == pytest.approx(_qcon_closed(m, x), abs=1e-12)


def test_q_sums_match_scipy_and_optiland_at_high_order() -> None:
    from optiland.geometries.forbes.qpoly import clenshaw_qbfs
    from scipy.special import eval_jacobi
    rng = np.random.default_rng(3)
    a = rng.normal(size=13)
    b = qbfs_to_p_basis(a)
    for x in XS:
        assert qbfs_sum(b, x)[0] == pytest.approx(float(clenshaw_qbfs(list(a), np.array(x))), abs=1e-12)
        want = sum(a[m] * eval_jacobi(m, 0, 4, 2 * x - 1) for m in range(13))
        assert qcon_sum(a, x)[0] == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_sags_match_optiland_geometries() -> None:
    from optiland.coordinate_system import CoordinateSystem
    from optiland.geometries.forbes.geometry import ForbesQNormalSlopeGeometry, ForbesSurfaceConfig
    from optiland.geometries.odd_asphere import OddAsphere
    from optiland.geometries.toroidal import ToroidalGeometry
    cs = CoordinateSystem()
    phone, ana = phone_odd_qcon(), anamorphic()
    s0, s2, tor = phone.surfaces[0], phone.surfaces[2], ana.surfaces[1]
    sh = s2.shape
    oracles = [
        (s0, OddAsphere(cs, 1 / s0.curvature_per_mm, s0.conic, coefficients=list(s0.shape.coefficients))),
        (s2, ForbesQNormalSlopeGeometry(cs, ForbesSurfaceConfig(1 / s2.curvature_per_mm, s2.conic, sh.norm_radius_mm,
                                                                dict(enumerate(sh.coefficients))))),
        (tor, ToroidalGeometry(cs, 1 / tor.shape.curvature_x_per_mm, 1 / tor.curvature_per_mm, tor.conic,
                               list(tor.asphere))),
    ]
    for surface, geo in oracles:
        p = profile_of(surface)
        for x, y in ((0.0, 0.0), (0.3, -0.2), (0.7, 0.9), (-1.0, 0.4)):
            assert sag_grad(p, x, y)[0] == pytest.approx(float(geo.sag(x, y)), abs=1e-13)


def _surfaces() -> list[Surface]:
    return list(phone_odd_qcon().surfaces) + list(anamorphic().surfaces) + list(freeform().surfaces) + \
        list(fringe().surfaces)


@pytest.mark.parametrize("k", range(10))
def test_gradient_is_the_derivative_of_the_sag(k: int) -> None:
    p = profile_of(_surfaces()[k])
    h = 1e-6
    for x, y in ((0.31, -0.22), (0.7, 0.5), (-0.9, 0.1)):
        z, zx, zy = sag_grad(p, x, y)
        assert zx == pytest.approx((sag_grad(p, x + h, y)[0] - sag_grad(p, x - h, y)[0]) / (2 * h), abs=1e-8)
        assert zy == pytest.approx((sag_grad(p, x, y + h)[0] - sag_grad(p, x, y - h)[0]) / (2 * h), abs=1e-8)


def test_biconic_and_toroid_reduce_to_closed_forms() -> None:
    c, k = 1 / 12.0, -0.5
    conic = Surface(c, conic=k)
    equal = Surface(c, conic=k, shape=SurfaceShape("biconic", curvature_x_per_mm=c, conic_x=k))
    sphere_torus = Surface(c, shape=SurfaceShape("toroidal", curvature_x_per_mm=c))
    cylinder = Surface(c, conic=k, shape=SurfaceShape("biconic"))
    for x, y in ((0.0, 1.0), (2.0, 3.0), (-4.0, 1.5)):
        r = math.hypot(x, y)
        assert sag_grad(profile_of(equal), x, y)[0] == pytest.approx(conic.sag(r), abs=1e-14)
        assert sag_grad(profile_of(sphere_torus), x, y)[0] == pytest.approx(Surface(c).sag(r), abs=1e-14)
        assert sag_grad(profile_of(cylinder), x, y)[0] == pytest.approx(conic.sag(y), abs=1e-14)


def test_vertex_expansion_and_paraxial_curvature() -> None:
    xy_even = Surface(1 / 15.0, conic=-0.4, shape=SurfaceShape("xy", (0.0,) * 4 + (0.02,) + (0.0,) * 8 + (0.004,), 5.0))
    for s in [s for s in _surfaces() if s.shape.kind not in ("xy", "zernike", "zernike_fringe")] + [xy_even]:
        p = profile_of(s)
        a2, a4 = vertex_expansion(p)
        odd = s.shape.kind == "odd"
        if odd:  # the odd powers are left out of the expansion: compare with them removed
            terms = tuple(v if i % 2 == 1 else 0.0 for i, v in enumerate(s.shape.coefficients))
            p = profile_of(Surface(s.curvature_per_mm, conic=s.conic, shape=SurfaceShape("odd", terms, 1.0)))
        ys = np.array([1e-2, 2e-2, 3e-2])
        z = np.array([sag_grad(p, 0.0, y)[0] for y in ys])
        fit = np.linalg.solve(np.stack([ys ** 2, ys ** 4, ys ** 6], axis=1), z)
        assert fit[0] == pytest.approx(a2, rel=1e-9)
        assert fit[1] == pytest.approx(a4, rel=1e-4)
        assert s.paraxial_curvature_per_mm == pytest.approx(2 * a2, rel=1e-15)


@pytest.mark.parametrize("kw,match", [
    ({"shape": SurfaceShape("odd", (1e-3,)), "asphere": (0.0, 1e-4)}, "even asphere terms on a odd"),
])
def test_surface_refuses_mixed_terms(kw: dict, match: str) -> None:
    with pytest.raises(PrescriptionError, match=match):
        Surface(0.1, **kw)


@pytest.mark.parametrize("kw,match", [
    ({"kind": "zernikey"}, "unknown surface shape"),
    ({"kind": "qbfs", "norm_radius_mm": 0.0}, "must be positive"),
    ({"kind": "qcon", "coefficients": (float("nan"),)}, "qcon coefficient is nan"),
    ({"kind": "odd", "curvature_x_per_mm": 0.1}, "x curvature on a odd"),
    ({"kind": "toroidal", "conic_x": 0.1}, "x conic on a toroidal"),
    ({"kind": "biconic", "coefficients": (1.0,)}, "no polynomial coefficients"),
    ({"kind": "odd", "coefficients": (1.0,) * 67}, "at most 66"),
    ({"kind": "xy", "coefficients": (1.0,) * 66}, "at most 65"),
])
def test_shape_validation_is_one_clear_error(kw: dict, match: str) -> None:
    with pytest.raises(PrescriptionError, match=match):
        SurfaceShape(**kw)


def test_default_surface_is_unchanged() -> None:
    s = Surface(0.1, 1.0, conic=-0.5, asphere=(0.0, 1e-4))
    assert s.shape is None and s == Surface(0.1, 1.0, conic=-0.5, asphere=(0.0, 1e-4), shape=None)
    assert s.paraxial_curvature_per_mm == 0.1


def _noll_closed(j: int, rho: float, th: float) -> float:
    """Noll (1976) Table I, Z_1 .. Z_11."""
    s3, s6, s8 = math.sqrt(3), math.sqrt(6), math.sqrt(8)
    return {1: 1.0, 2: 2 * rho * math.cos(th), 3: 2 * rho * math.sin(th), 4: s3 * (2 * rho ** 2 - 1),
            5: s6 * rho ** 2 * math.sin(2 * th), 6: s6 * rho ** 2 * math.cos(2 * th),
            7: s8 * (3 * rho ** 3 - 2 * rho) * math.sin(th), 8: s8 * (3 * rho ** 3 - 2 * rho) * math.cos(th),
            9: s8 * rho ** 3 * math.sin(3 * th), 10: s8 * rho ** 3 * math.cos(3 * th),
            11: math.sqrt(5) * (6 * rho ** 4 - 6 * rho ** 2 + 1)}[j]


@pytest.mark.parametrize("j", range(1, 12))
def test_zernike_terms_match_noll(j: int) -> None:
    s = Surface(0.0, shape=SurfaceShape("zernike", (0.0,) * (j - 1) + (1.0,), 2.0))
    p = profile_of(s)
    for x, y in ((0.3, 0.1), (-1.2, 0.7), (0.0, -1.9), (1.5, 1.1)):
        assert sag_grad(p, x, y)[0] == pytest.approx(_noll_closed(j, math.hypot(x, y) / 2.0, math.atan2(y, x)),
                                                     abs=1e-13)


def test_noll_indices() -> None:
    assert [noll_nm(j) for j in range(1, 12)] == [(0, 0), (1, 1), (1, -1), (2, 0), (2, -2), (2, 2), (3, -1), (3, 1),
                                                  (3, -3), (3, 3), (4, 0)]
    assert noll_nm(22) == (6, 0) and noll_nm(37) == (8, 0)


def test_xy_terms_are_zemax_extended_polynomial_order() -> None:
    coef = (0.1, -0.2, 0.3, 0.4, -0.5, 0.6, 0.7, -0.8, 0.9)  # x y x2 xy y2 x3 x2y xy2 y3
    p = profile_of(Surface(0.0, shape=SurfaceShape("xy", coef, 3.0)))
    for x, y in ((0.3, 0.1), (-1.2, 0.7), (2.0, -2.5)):
        u, v = x / 3.0, y / 3.0
        mono = (u, v, u * u, u * v, v * v, u ** 3, u * u * v, u * v * v, v ** 3)
        assert sag_grad(p, x, y)[0] == pytest.approx(sum(a * m for a, m in zip(coef, mono)), abs=1e-15)


def _fringe_closed(j: int, rho: float, th: float) -> float:
    """Wyant & Creath (1992) Table 2 (OpticStudio's Zernike Fringe table), F_1 .. F_16 and F_37: not normalised."""
    r2 = rho * rho
    table = {1: 1.0, 2: rho * math.cos(th), 3: rho * math.sin(th), 4: 2 * r2 - 1, 5: r2 * math.cos(2 * th),
             6: r2 * math.sin(2 * th), 7: (3 * r2 - 2) * rho * math.cos(th), 8: (3 * r2 - 2) * rho * math.sin(th),
             9: 6 * r2 * r2 - 6 * r2 + 1, 10: rho ** 3 * math.cos(3 * th), 11: rho ** 3 * math.sin(3 * th),
             12: (4 * r2 - 3) * r2 * math.cos(2 * th), 13: (4 * r2 - 3) * r2 * math.sin(2 * th),
             14: (10 * r2 * r2 - 12 * r2 + 3) * rho * math.cos(th), 15: (10 * r2 * r2 - 12 * r2 + 3) * rho * math.sin(th),
             16: 20 * r2 ** 3 - 30 * r2 ** 2 + 12 * r2 - 1,
             37: 924 * r2 ** 6 - 2772 * r2 ** 5 + 3150 * r2 ** 4 - 1680 * r2 ** 3 + 420 * r2 ** 2 - 42 * r2 + 1}
    return table[j]


@pytest.mark.parametrize("j", list(range(1, 17)) + [37])
def test_fringe_terms_match_the_fringe_table(j: int) -> None:
    s = Surface(0.0, shape=SurfaceShape("zernike_fringe", (0.0,) * (j - 1) + (1.0,), 2.0))
    p = profile_of(s)
    for x, y in ((0.3, 0.1), (-1.2, 0.7), (0.0, -1.9), (1.5, 1.1)):
        want = _fringe_closed(j, math.hypot(x, y) / 2.0, math.atan2(y, x))
        assert sag_grad(p, x, y)[0] == pytest.approx(want, abs=1e-12 * max(1.0, abs(want)))


def test_fringe_indices_match_optiland_and_end_with_the_12th_order_spherical() -> None:
    from optiland.zernike.fringe import ZernikeFringe
    peer = [tuple(int(v) for v in nm) for nm in ZernikeFringe(num_terms=36).indices[:36]]
    assert [fringe_nm(j) for j in range(1, 37)] == peer
    assert fringe_nm(MAX_FRINGE_TERMS) == (12, 0)  # the set's last term (optiland's 37th would be (6, 6))
    with pytest.raises(PrescriptionError, match="outside 1..37"):
        fringe_nm(38)
    with pytest.raises(PrescriptionError, match="the fringe set has 37"):
        SurfaceShape("zernike_fringe", (1e-3,) * 38, 5.0)


def test_fringe_sag_matches_optiland() -> None:
    """A surface with 36 fringe terms over a conic against optiland's ZernikePolynomialGeometry("fringe")."""
    from optiland.coordinate_system import CoordinateSystem
    from optiland.geometries.zernike import ZernikePolynomialGeometry
    coef = tuple(float(v) for v in np.random.default_rng(3).normal(0.0, 1e-3, 36))
    s = Surface(1 / 40.0, conic=-0.6, shape=SurfaceShape("zernike_fringe", coef, 6.0))
    geo = ZernikePolynomialGeometry(CoordinateSystem(), 40.0, -0.6, coefficients=list(coef), zernike_type="fringe",
                                    norm_radius=6.0)
    p = profile_of(s)
    for x, y in ((0.0, 0.0), (1.3, -2.2), (-4.0, 3.1), (0.5, 5.6), (-5.9, -0.4)):
        assert sag_grad(p, x, y)[0] == pytest.approx(float(geo.sag(x, y)), abs=1e-13)
