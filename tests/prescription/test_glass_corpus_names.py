"""Glass names of real lens files that no current vendor catalog lists (issue 25): obsolete 1980 glasses (Robb &
Mercado 1983), tabulated database pages (Schott B 270), a four-pole Sellmeier page (Hikari NICF-A), vendor
variant names (Ohara S-LAL7Q), CODE V vendor suffixes and lower-case names -- each taken with a warning that
names its source, or refused with one clear error."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import UnknownGlassError
from lensrt.loading import load_lens
from lensrt.prescription.glass_lookup import GlassRequest, resolve_glass
from lensrt.prescription.materials import find_exact_vendor_glass
from lensrt.prescription.rii import TABLE_FIT_TOLERANCE, database_root, find_rii_glass
from lensrt.prescription.robb1983 import BAND_NM, find_robb_glass, robb_index, robb_table
from lensrt.units import FRAUNHOFER_NM

CORPUS = Path(__file__).resolve().parents[1] / "data" / "corpus"
LINES = ("F", "d", "C")


def _codes(out) -> list[str]:
    return [w.code for w in out]


@pytest.mark.parametrize("old,current", [("F2", "F2"), ("SF5", "SF5"), ("SF11", "SF11"), ("BK7", "N-BK7"),
                                         ("SK16", "N-SK16")])
def test_robb_glasses_match_the_current_catalog_where_the_glass_is_unchanged(old: str, current: str) -> None:
    """The 1980 model at Robb's base wavelength 0.574 um reproduces today's Schott data of the same glass at F, d
    and C within the paper's stated fit errors (a few 1e-5), which fixes the base wavelength (with 587.6 nm,
    BK7's n_d would be off by 1.2e-4)."""
    g = find_robb_glass(old, ("Schott",))
    ref = find_exact_vendor_glass(current, "Schott")
    assert g is not None and ref is not None
    w = np.array([FRAUNHOFER_NM[k] for k in LINES])
    assert np.max(np.abs(g.index(w) - ref.index(w))) < 6e-5
    assert g.catalog == "Schott 1980" and g.range_nm == BAND_NM


def test_robb_packing_follows_the_buchdahl_model() -> None:
    """The packed power series equals the paper's quadratic model over the band within the recorded residual."""
    name, n0, nu1, nu2 = robb_table()["Schott"]["KZFSN5"]
    g = find_robb_glass("kzfsn5")
    w = np.linspace(*BAND_NM, 57)
    assert np.max(np.abs(g.index(w) - robb_index(n0, nu1, nu2, w))) < 1e-6
    assert abs(float(g.index(574.0)) - n0) < 1e-6  # the model's N0 is the index at the base wavelength
    assert find_robb_glass("NBFD10", ("Hoya",)).name == "NBFD10"  # the data file prints NBFD1O


def test_tabulated_page_fitted_within_its_table() -> None:
    """Schott B 270 (a datasheet table of n only): the fit passes every tabulated index within the tolerance."""
    import yaml
    g = find_rii_glass("B270")
    doc = yaml.safe_load((database_root() / "data" / "specs/schott/misc/B270.yml").read_text(encoding="utf-8"))
    rows = np.array([[float(x) for x in ln.split()] for ln in doc["DATA"][0]["data"].splitlines() if ln.strip()])
    assert np.max(np.abs(g.index(rows[:, 0] * 1000.0) - rows[:, 1])) <= TABLE_FIT_TOLERANCE
    assert g.range_nm == pytest.approx((rows[0, 0] * 1000.0, rows[-1, 0] * 1000.0))
    assert "fitted" in g.formula


def test_four_pole_page_folded_exactly_enough() -> None:
    """Hikari NICF-A (CaF2, four Sellmeier poles, one at 27 um): folded into power terms, it equals the page's
    formula, evaluated here term by term, within 1e-6 over its range and 1e-9 in the visible."""
    g = find_rii_glass("NICF-A")
    c = [0, 0.581797965, 0.002477442, 0.373232342, 0.01032026, 0.083677196, 0.010323473, 2.36293749, 738.225998]
    assert "folded" in g.formula
    for lo, hi, tol in ((g.range_nm[0], g.range_nm[1], 1e-6), (400.0, 700.0, 1e-9)):
        w_um = np.linspace(lo, hi, 41) / 1000.0
        n = np.sqrt(1 + sum(c[i] * w_um ** 2 / (w_um ** 2 - c[i + 1]) for i in (1, 3, 5, 7)))
        assert np.max(np.abs(g.index(w_um * 1000.0) - n)) < tol


@pytest.mark.parametrize("name,cats,nd,vd,found,code", [
    ("KZFSN5", ("SCHOTT", "HOYA"), 1.65416, 39.63, "KZFSN5", "glass_obsolete"),     # US 2007/0236805
    ("BK7", ("SCHOTT", "INFRARED", "MISC"), None, None, "BK7", "glass_obsolete"),   # rayoptics zmax_55278
    ("bk7", None, None, None, "BK7", "glass_obsolete"),                             # rayoptics test.seq
    ("SK19_Schott", None, None, None, "SK19", "glass_obsolete"),                    # rayoptics achroMangin.seq
    ("B270", ("SCHOTT",), 1.5, 40.0, "B270", "glass_fitted"),                        # Thorlabs ACL2520-A
    ("S-LAL7Q", ("SCHOTT", "OHARA"), 1.6516, 58.54, "S-LAL 7", "glass_variant"),     # US 2025/0155694
    ("LF5HT", ("SCHOTT", "HOYA"), 1.58148, 40.9, "LF5", "glass_variant"),           # Beam42 Noct-Nikkor 58 mm
    ("LZ_K8", ("LZOS", "HIKARI"), None, None, "K8", "glass_fitted"),                # ZemaxUtils (LZOS.AGF's prefix)
    ("SF12?", ("SCHOTT", "HOYA", "HIKARI"), 1.64831, 33.77, "SF12", "glass_uncertain_name"),  # Beam42 Nikkor 50/1.8S
])
def test_corpus_glass_names_resolve_with_a_warning(name, cats, nd, vd, found, code) -> None:
    mat, out = resolve_glass(GlassRequest(name, cats, nd, vd))
    assert mat.name == found
    assert code in _codes(out)
    if nd is not None and abs(float(mat.index(FRAUNHOFER_NM["d"])) - nd) > 1e-3:
        assert "glass_line_disagrees" in _codes(out)  # B270's placeholder line (1.5, 40) is named, not used


def test_nicf_a_found_in_the_files_catalog() -> None:
    """US 3,868,174 names Nikon/Hikari's NICF-A; its catalog list includes HIKARI; the line agrees (no warning)."""
    mat, out = resolve_glass(GlassRequest("NICF-A", ("SCHOTT", "HOYA", "OHARA", "NIKON-HIKARI", "HIKARI"),
                                          1.43387, 95.1))
    assert mat.catalog == "Hikari" and abs(float(mat.index(FRAUNHOFER_NM["d"])) - 1.43387) < 1e-4
    assert out == []


def test_lzos_prefix_without_its_catalog() -> None:
    """LZ_K8 with no GCAT: still LZOS's K8, with a warning that names the database page it came from."""
    mat, out = resolve_glass(GlassRequest("LZ_K8", None))
    assert (mat.name, mat.catalog) == ("K8", "LZOS")
    assert {"glass_other_catalog", "glass_fitted"} <= set(_codes(out))


def test_variant_needs_the_line_to_confirm() -> None:
    with pytest.raises(UnknownGlassError, match="S-LAL7Q"):
        resolve_glass(GlassRequest("S-LAL7Q", ("OHARA",)))            # no n_d/V_d on the line
    with pytest.raises(UnknownGlassError, match="S-LAL7Q"):
        resolve_glass(GlassRequest("S-LAL7Q", ("OHARA",), 1.70, 58.5))  # a line that names another glass


def test_uncertain_name_needs_the_line_to_confirm() -> None:
    """``SF12?`` (a transcriber's uncertain reading) is SF12 only where the line's n_d/V_d agree with it."""
    with pytest.raises(UnknownGlassError, match="SF12\\?"):
        resolve_glass(GlassRequest("SF12?", ("HIKARI",)))                 # no n_d/V_d on the line
    with pytest.raises(UnknownGlassError, match="SF12\\?"):
        resolve_glass(GlassRequest("SF12?", ("HIKARI",), 1.6600, 33.8))  # a line that names another glass
    mat, _ = resolve_glass(GlassRequest("SF12?", ("HIKARI",), 1.6483, 33.8))
    assert mat.name == "SF12"


@pytest.mark.parametrize("name,cats,nd,vd", [("FDS30_hoya", None, None, None),       # opticspy microscope.seq
                                              ("NBFD25", ("HOYA", "OHARA"), 1.85451, 25.15),  # Beam42 Sigma 50/35 mm
                                              ("FD270", ("HOYA", "HIKARI"), 1.6843, 26.81),   # Beam42 Noct-Nikkor v8
                                              ("D-ZK3M", ("LIGHTPATH", "SCHOTT"), 1.601, 50.277746),  # 354710-C
                                              ("NBFD29", ("HOYA",), 1.77047, 29.74)])  # US 2025/0155694
def test_glasses_in_no_catalog_are_one_clear_error(name, cats, nd, vd) -> None:
    """Hoya FDS30 (obsolete after 1980), LightPath's moldable D-ZK3M and Hoya's NBFD29, NBFD25 and FD270 are in none
    of the catalogs lensrt has (opticalglass, the refractiveindex.info database, Robb 1983): an error that names the
    glass and, where the line has data, offers --glass-model-fallback."""
    with pytest.raises(UnknownGlassError, match=name) as err:
        resolve_glass(GlassRequest(name, cats, nd, vd))
    if nd is not None:
        assert "--glass-model-fallback" in str(err.value)


def test_corpus_files_with_these_glasses_load() -> None:
    for f in ("ACL2520-A.zmx", "US003868174_Example01P.zmx", "US20070236805_Example01.zmx"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            load_lens(CORPUS / f)



@pytest.mark.parametrize("name", ["BK7", "SK1", "SK19", "F15", "SSK4", "KZFSN5"])
def test_robb_data_read_as_opticalglass_reads_them(name: str) -> None:
    """The same Table V row as opticalglass's own Robb1983Catalog (rayoptics' source for these glasses): its
    Buchdahl object puts N0 at 587.56 nm, lensrt at the paper's 0.574 um, so n_lensrt(574 nm) = n_theirs(d) = N0.
    (With their base, every index above is ~7e-4..1.2e-3 high against Schott's published n_d, e.g. SK1 1.611029
    against 1.61025; lensrt's n_d of SK1 is 1.61025.)"""
    from opticalglass.glass import Robb1983Catalog
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        theirs = Robb1983Catalog().create_glass(name, "Schott")
    mine = find_robb_glass(name, ("Schott",))
    assert abs(float(mine.index(574.0)) - float(theirs.rindex(FRAUNHOFER_NM["d"]))) < 1e-6


def test_obsolete_glass_patent_loads_in_1980_glasses() -> None:
    """DiffOptics' US 2,532,751 double Gauss names Schott SSK4, SK1, F15, SK16 with placeholder lines (1.5, 40):
    all six glasses now come from the 1980 tables, each with a warning; issue 25 saw it load as 22.9 mm."""
    from lensrt.paraxial import first_order
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lens = load_lens(CORPUS / "US02532751-1.zmx")
    assert [s.material.catalog for s in lens.surfaces if not s.material.is_air] == ["Schott 1980"] * 6
    assert sum(w.code == "glass_obsolete" for w in lens.warnings) == 6
    assert abs(float(lens.surfaces[3].material.index(FRAUNHOFER_NM["d"])) - 1.61025) < 2e-5  # Schott SK1's n_d
    assert 27.0 < first_order(lens).efl_mm < 28.0
