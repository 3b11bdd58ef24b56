"""The library's phone camera lens (US 7,535,658, eight odd-polynomial aspheres) against rayoptics' own model of it.

rayoptics ships the same prescription as ``cell_phone_camera.roa``: lensrt's library file must hold the same
surfaces (radius, conic, r^1 .. r^10 terms, thickness, glass), give the same first-order data, and trace the same
real rays -- every surface intersection within 1e-9 mm of rayoptics' (float64, both) on skew rays up to the full
field -- so the odd asphere and its steep high-order terms are read and traced as rayoptics does.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from lensrt.library import library_dir
from lensrt.loading import load_lens
from lensrt.paraxial.first_order import first_order
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

LENS = library_dir() / "phone_us7535658_f3.5_odd_asph.toml"
WL_NM = 587.5618


@pytest.fixture(scope="module")
def rayoptics_model():
    ro = pytest.importorskip("rayoptics")
    from rayoptics.environment import open_model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        opm = open_model(Path(ro.__file__).parent / "optical" / "tests" / "cell_phone_camera.roa")
    return opm


def test_same_prescription_and_first_order(rayoptics_model) -> None:
    lens = load_lens(LENS)
    sm = rayoptics_model["seq_model"]
    ifcs, gaps = sm.ifcs[1:-1], sm.gaps[1:-1]
    assert len(ifcs) == lens.n_surfaces
    for s, ifc, gap in zip(lens.surfaces, ifcs, gaps):
        pr = ifc.profile
        assert s.thickness_mm == gap.thi
        assert s.curvature_per_mm == pytest.approx(pr.cv, rel=1e-15, abs=0.0)
        if type(pr).__name__ == "RadialPolynomial":
            assert s.shape.kind == "odd" and s.shape.norm_radius_mm == 1.0 and s.conic == pytest.approx(pr.cc)
            assert s.shape.coefficients == tuple(c for c in pr.coefs)[:len(s.shape.coefficients)]
            assert not any(pr.coefs[len(s.shape.coefficients):])
        else:
            assert s.shape is None
        if not s.material.is_air:
            assert float(s.material.index(WL_NM)) == pytest.approx(float(gap.medium.rindex(WL_NM)), abs=1e-12)
    fo = first_order(lens)
    fod = rayoptics_model["analysis_results"]["parax_data"].fod
    assert fo.efl_mm == pytest.approx(fod.efl, rel=1e-9)
    assert fo.bfl_mm == pytest.approx(fod.bfl, rel=1e-9)
    assert fo.f_number == pytest.approx(3.5, rel=1e-9)


def test_real_rays_match_rayoptics(rayoptics_model) -> None:
    from rayoptics.raytr import raytrace
    lens = load_lens(LENS)
    sm = rayoptics_model["seq_model"]
    sm.gaps[0].thi = 10.0  # a near object plane 10 mm before the stop, so both start the ray at the same point
    rayoptics_model.update_model()
    half = np.tan(lens.fields.y[-1])  # the full field, 31.76 deg (fields are held in radians)
    checked = 0
    for px, py in [(0.0, 0.0), (0.0, 0.7), (0.5, -0.5), (-0.7, 0.2), (0.2, 0.75)]:
        for hx, hy in [(0.0, 0.0), (0.0, 0.7), (0.3, 1.0), (0.0, -1.0)]:
            d = np.array([hx * half, hy * half, 1.0])
            d /= np.linalg.norm(d)
            x, y = px * 0.79, py * 0.79  # across the stop (semi-diameter 0.7936 mm)
            start = np.array([x, y, 0.0]) - 10.0 * d / d[2]
            ray, _, _ = raytrace.trace(sm, start * np.array([1.0, 1.0, 0.0]), d, WL_NM)
            ref = trace_reference(lens, (start[0], start[1], -10.0), tuple(d), WL_NM, clip=False)
            assert ref.status == OK and len(ref.hits) == len(ray) - 1 == lens.n_surfaces + 1
            for hit, seg in zip(ref.hits, ray[1:]):
                assert abs(hit.x_mm - seg[0][0]) < 1e-9 and abs(hit.y_mm - seg[0][1]) < 1e-9
                assert np.max(np.abs(np.array([hit.L, hit.M, hit.N]) - seg[1])) < 1e-12
            checked += 1
    assert checked == 20
