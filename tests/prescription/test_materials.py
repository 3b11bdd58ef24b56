"""Materials: catalog glasses against opticalglass and the CODE V listing; name matching; model glass."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.errors import PrescriptionError, UnknownGlassError
from lensrt.prescription.materials import (AIR, CATALOGS, ConstantIndex, ModelGlass, check_wavelength_range,
                                           find_glass, glass_names, index_from_packed, parse_material)
from lensrt.units import FRAUNHOFER_NM

# CODE V listing ag_dblgauss.lis, REFRACTIVE INDICES at 656.3 / 587.6 / 486.1 nm
CODEV_INDICES = {
    "NSSK2_SCHOTT": (1.618769, 1.622292, 1.630455),
    "NSK2_SCHOTT": (1.604134, 1.607379, 1.614860),
    "F5_SCHOTT": (1.598744, 1.603417, 1.614617),
    "NSK16_SCHOTT": (1.617271, 1.620408, 1.627559),
}


@pytest.mark.parametrize("name", sorted(CODEV_INDICES))
def test_codev_listing_indices(name: str) -> None:
    glass = find_glass(name)
    n = glass.index(np.array([656.3, 587.6, 486.1]))
    assert np.max(np.abs(n - np.array(CODEV_INDICES[name]))) < 1e-5 * 0.5 + 5e-7


@pytest.mark.parametrize("catalog", CATALOGS)
def test_packed_formula_equals_opticalglass(catalog: str) -> None:
    import opticalglass.glassfactory as gf
    names = glass_names(catalog)
    w = np.linspace(380.0, 1000.0, 23)
    for name in names[:: max(1, len(names) // 12)]:
        mine = find_glass(f"{name}_{catalog}")
        theirs = gf.create_glass(name, catalog).calc_rindex(w)
        assert np.max(np.abs(mine.index(w) - theirs)) < 1e-12, name


@pytest.mark.parametrize("spelling,expected", [
    ("N-BK7", ("N-BK7", "Schott")), ("NBK7", ("N-BK7", "Schott")), ("n-bk7", ("N-BK7", "Schott")),
    ("N-BK7_SCHOTT", ("N-BK7", "Schott")), ("S-LAH66", ("S-LAH66", "Ohara")),
    ("SLAH66", ("S-LAH66", "Ohara")), ("J-SK16", ("J-SK16", "Hikari")),
])
def test_name_matching(spelling: str, expected: tuple[str, str]) -> None:
    g = find_glass(spelling)
    assert (g.name, g.catalog) == expected


def test_prefixless_names() -> None:
    # an old Schott name goes to Schott's lead-free successor when Schott is searched ...
    assert find_glass("SK16", ["Hikari", "Schott"]).name == "N-SK16"
    assert find_glass("SK16", ["Schott"]).name == "N-SK16"
    # ... else to the first named catalog's equivalent
    assert find_glass("SK16", ["Hikari"]).name == "J-SK16"
    assert find_glass("SK16", ["Sumita", "Hikari"]).name == "K-SK16"


def test_unknown_glass_suggests_names() -> None:
    with pytest.raises(UnknownGlassError) as err:
        find_glass("N-BK8")
    assert "N-BK7" in str(err.value)


def test_model_glass_reproduces_nd_vd() -> None:
    g = ModelGlass(1.6204, 60.3)
    nd, nf, nc = (g.index(FRAUNHOFER_NM[k]) for k in "dFC")
    assert nd == pytest.approx(1.6204, abs=1e-12)
    assert (nd - 1) / (nf - nc) == pytest.approx(60.3, rel=1e-12)
    assert g.abbe_number() == pytest.approx(60.3, rel=1e-12)


def test_constant_and_air() -> None:
    assert AIR.index(550.0) == 1.0
    assert ConstantIndex(1.67).index(np.array([400.0, 700.0])) == pytest.approx([1.67, 1.67])
    assert math.isinf(ConstantIndex(1.5).abbe_number())
    assert index_from_packed(AIR.packed(), 500.0) == 1.0


@pytest.mark.parametrize("spec", [{"glass": "N-BK7", "catalog": "Schott"}, "N-BK7", {"nd": 1.5, "vd": 60},
                                  {"index": 1.5}, 1.5, "air", None])
def test_parse_material(spec: object) -> None:
    m = parse_material(spec)
    assert 1.0 <= m.index(587.6) < 2.0


@pytest.mark.parametrize("bad", [{"glass": "N-BK7", "catalog": "Nowhere"}, {"foo": 1}, True, ["N-BK7"],
                                 {"nd": float("nan"), "vd": 50}, {"index": -1.0}])
def test_parse_material_rejects(bad: object) -> None:
    with pytest.raises(PrescriptionError):
        parse_material(bad)


def test_extrapolation_is_reported() -> None:
    g = find_glass("N-BK7")
    lo, hi = g.valid_range_nm
    with pytest.warns(UserWarning, match="extrapolated"):
        msgs = check_wavelength_range([g], [lo - 50.0, 550.0])
    assert len(msgs) == 1
    assert check_wavelength_range([g], [550.0]) == []
