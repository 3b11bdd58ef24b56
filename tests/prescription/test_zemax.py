"""Zemax .zmx reader: the OpticStudio-checked Cooke triplet, encodings, units, glass, the unsupported list."""
from __future__ import annotations

import codecs
import math
import warnings
from pathlib import Path

import pytest

from lensrt.errors import LensrtError, PrescriptionError
from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.zemax import GlassFallbackWarning, loads_zmx
from lensrt.prescription.materials import CatalogGlass, ModelGlass

HEAD = """VERS 1 0 0
MODE SEQ
UNIT {unit} X W X CM MR CPMM
ENPD 10
FTYP 0 0 2 1 0 0 0
YFLN 0 5
WAVM 1 0.55 1
GCAT SCHOTT
"""
SURFS = """SURF 0
  DISZ INFINITY
SURF 1
  TYPE {type1}
  CURV 0.02
  DISZ 5
  GLAS N-BK7 0 0 1.5168 64.17
  {extra1}
SURF 2
  STOP
  CURV -0.02
  DISZ 45
SURF 3
"""


def zmx(unit: str = "MM", type1: str = "STANDARD", extra1: str = "", head_extra: str = "", tail: str = "") -> str:
    return HEAD.format(unit=unit) + head_extra + SURFS.format(type1=type1, extra1=extra1) + tail


def test_cooke_triplet_reference(data_dir: Path) -> None:
    lens = read_lens(data_dir / "cooke_triplet.zmx")
    assert lens.n_surfaces == 6 and lens.stop_index == 3
    assert lens.surfaces[0].curvature_per_mm == 4.5426484276303865e-02
    assert lens.surfaces[-1].thickness_mm == 42.20778
    # GCAT HIKARI SCHOTT: SK16 is Hikari's (refractiveindex.info's Hikari shelf; opticalglass lists only
    # J-SK16), F2 Schott's (opticalglass) -- exact names, no substitution, nothing to warn about
    assert [s.material.describe() for s in lens.surfaces if not s.material.is_air] == \
        ["SK16 (Hikari)", "F2 (Schott)", "SK16 (Hikari)"]
    assert "refractiveindex.info" in lens.surfaces[0].material.source
    assert lens.warnings == () and "glass_substitutions" not in lens.meta
    assert lens.aperture.kind == "epd" and lens.aperture.value == 10.0
    assert lens.fields.kind == "angle"
    assert [math.degrees(v) for v in lens.fields.y] == pytest.approx([0.0, 14.0, 20.0], abs=1e-12)
    assert lens.wavelengths.nm == (480.0, 550.0, 650.0) and lens.wavelengths.primary_nm == 550.0
    assert math.isinf(lens.object_distance_mm)
    assert all(s.semi_diameter_mm is None for s in lens.surfaces)  # no DIAM lines: computed on load
    # the GLAS line's n_d/V_d (written by optiland from its own glass data) agree with the glass
    # chosen to the catalogs' spread: N-SK16 1.62041/60.32, Hikari J-SK16 1.62041/60.25
    sk16 = lens.surfaces[0].material
    assert sk16.index(587.5618) == pytest.approx(1.6204068551301407, abs=5e-6)
    assert sk16.abbe_number() == pytest.approx(60.2565, abs=0.1)
    # a file naming only SCHOTT: SK16 is Schott's obsolete 1980 glass (Robb & Mercado's table), with a warning
    # naming that source and the n_d difference from the line
    text = (data_dir / "cooke_triplet.zmx").read_text(errors="replace").replace("GCAT HIKARI SCHOTT", "GCAT SCHOTT")
    with pytest.warns(UserWarning, match="obsolete glass SK16"):
        lens = loads_zmx(text, "c.zmx")
    assert lens.surfaces[0].material.describe() == "SK16 (Schott 1980)"
    assert [(w.code, w.surface, w.line) for w in lens.warnings] == [("glass_obsolete", 0, 35),
                                                                    ("glass_obsolete", 4, 66)]
    dn = 1.6204068551301407 - lens.surfaces[0].material.index(587.5618)
    assert abs(dn) < 5e-5 and f"differs by {dn:+.2e}" in lens.warnings[0].text


def test_cooke_first_order_against_opticstudio(data_dir: Path) -> None:
    """OpticStudio (optiland issue #710): EFL 49.999783, EP 11.512159 behind surface 1,
    exit pupil 10.233729 at -50.961348 from the image, Lagrange 1.819851, to 1e-5 relative
    (issue 3). OpticStudio found SK16 (obsolete) in its SCHOTT catalog; lensrt's nearest is
    N-SK16 (EFL +4.0e-6 relative); Hikari's J-SK16 would give -1.03e-5."""
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    lens = load_lens(data_dir / "cooke_triplet.zmx")
    fo = first_order(lens)
    assert fo.efl_mm == pytest.approx(49.999783, rel=1e-5)
    assert fo.working_f_number == pytest.approx(4.999978, rel=1e-5)
    assert fo.entrance_pupil_z_mm == pytest.approx(11.512159, rel=1e-5)
    assert fo.exit_pupil_diameter_mm == pytest.approx(10.233729, rel=1e-5)
    assert fo.exit_pupil_z_mm - lens.image_z_mm == pytest.approx(-50.961348, rel=1e-5)
    assert fo.lagrange_invariant == pytest.approx(1.819851, rel=1e-5)


@pytest.mark.parametrize("encoding,bom", [("utf-16-le", codecs.BOM_UTF16_LE), ("utf-16-be", codecs.BOM_UTF16_BE),
                                          ("utf-8", codecs.BOM_UTF8), ("ascii", b"")])
def test_encodings(data_dir: Path, tmp_path: Path, encoding: str, bom: bytes) -> None:
    text = (data_dir / "cooke_triplet.zmx").read_text(encoding="utf-8")
    p = tmp_path / "cooke_triplet.zmx"
    p.write_bytes(bom + text.replace("\n", "\r\n").encode(encoding))
    ref = read_lens(data_dir / "cooke_triplet.zmx")
    assert read_lens(p) == ref


@pytest.mark.parametrize("unit,scale", [("MM", 1.0), ("CM", 10.0), ("IN", 25.4), ("M", 1000.0)])
def test_units_are_converted(unit: str, scale: float) -> None:
    lens = loads_zmx(zmx(unit, "EVENASPH", "PARM 1 1e-3\n  PARM 2 2e-5\n  DIAM 3"))
    s0, s1 = lens.surfaces
    assert s0.curvature_per_mm == pytest.approx(0.02 / scale, rel=1e-15)
    assert s0.thickness_mm == pytest.approx(5 * scale, rel=1e-15)
    assert s1.thickness_mm == pytest.approx(45 * scale, rel=1e-15)
    assert s0.semi_diameter_mm == pytest.approx(3 * scale, rel=1e-15)
    # PARM 1 is the r^2 term (unit^-1), PARM 2 the r^4 term (unit^-3)
    assert s0.asphere == pytest.approx((1e-3 / scale, 2e-5 / scale ** 3), rel=1e-14)
    assert lens.aperture.value == pytest.approx(10 * scale)
    assert lens.fields.y[1] == pytest.approx(math.radians(5.0))  # angles are not lengths
    assert lens.wavelengths.nm == (550.0,)


def test_evenasph_sag_matches_parms() -> None:
    lens = loads_zmx(zmx("MM", "EVENASPH", "CONI -0.5\n  PARM 1 1e-3\n  PARM 2 2e-5\n  PARM 3 -1e-8"))
    s = lens.surfaces[0]
    r = 4.0
    c, k = 0.02, -0.5
    expected = c * r * r / (1 + math.sqrt(1 - (1 + k) * c * c * r * r)) + 1e-3 * r ** 2 + 2e-5 * r ** 4 - 1e-8 * r ** 6
    assert s.sag(r) == pytest.approx(expected, rel=1e-14)
    assert s.conic == -0.5


def test_glass_fallback_only_on_request() -> None:
    from lensrt.prescription.glass_lookup import glass_policy
    text = zmx().replace("GLAS N-BK7 0 0 1.5168 64.17", "GLAS MYGLASS 0 0 1.55 50.5")
    with pytest.raises(PrescriptionError) as err:
        loads_zmx(text, "x.zmx")
    msg = str(err.value)
    assert "'MYGLASS' is in no catalog lensrt reads" in msg and "SCHOTT" in msg and "--glass-catalog" in msg
    assert "--glass-model-fallback takes the line's n_d = 1.55, V_d = 50.5" in msg and "not physical" not in msg
    with glass_policy(model_fallback=True), pytest.warns(GlassFallbackWarning, match="MYGLASS"):
        lens = loads_zmx(text, "x.zmx")
    m = lens.surfaces[0].material
    assert isinstance(m, ModelGlass) and (m.nd, m.vd, m.name) == (1.55, 50.5, "MYGLASS")
    assert [(w.code, w.surface) for w in lens.warnings] == [("glass_model", 0)]
    # a catalog name wins over the line's n_d/V_d, and a disagreement > 1e-3 is said
    with pytest.warns(UserWarning, match="differs"):
        lens = loads_zmx(zmx().replace("1.5168 64.17", "1.9 20"))
    assert isinstance(lens.surfaces[0].material, CatalogGlass)
    assert lens.surfaces[0].material.name == "N-BK7"
    assert [w.code for w in lens.warnings] == ["glass_line_disagrees"]


def test_blank_model_glass_and_old_schott_names() -> None:
    from lensrt.prescription.glass_lookup import glass_policy
    with pytest.warns(GlassFallbackWarning):
        lens = loads_zmx(zmx().replace("GLAS N-BK7 0 0 1.5168 64.17", "GLAS ___BLANK 1 0 1.6 40"))
    assert lens.surfaces[0].material == ModelGlass(1.6, 40.0)
    assert lens.warnings[0].code == "glass_model"
    # OpticStudio's old name BK7: Schott's 1980 BK7 (robb1983), said so, with the line's n_d difference
    with pytest.warns(UserWarning, match="obsolete glass BK7"):
        lens = loads_zmx(zmx().replace("GLAS N-BK7", "GLAS BK7"))
    assert lens.surfaces[0].material.describe() == "BK7 (Schott 1980)"
    assert lens.warnings[0].code == "glass_obsolete" and "differs by" in lens.warnings[0].text
    # an old name in no catalog lensrt has, not even the 1980 tables: its successor only on request
    with pytest.raises(PrescriptionError, match="--glass-substitute takes N-LAK33B"):
        loads_zmx(zmx().replace("GLAS N-BK7", "GLAS LAK33B"))
    with glass_policy(substitute=True), pytest.warns(UserWarning, match="LAK33B substituted by N-LAK33B"):
        lens = loads_zmx(zmx().replace("GLAS N-BK7", "GLAS LAK33B"))
    assert lens.surfaces[0].material.name == "N-LAK33B"
    assert lens.warnings[0].code == "glass_substituted" and "difference" in lens.warnings[0].text


def test_unknown_glass_without_nd_is_an_error() -> None:
    with pytest.raises(PrescriptionError, match="'NOSUCH' is in no catalog lensrt reads") as err:
        loads_zmx(zmx().replace("GLAS N-BK7 0 0 1.5168 64.17", "GLAS NOSUCH"), "x.zmx")
    assert "model-fallback" not in str(err.value)  # the line gives no n_d/V_d to fall back on


def test_system_data() -> None:
    extra = ("XFLN 0 1 0\nFWGN 1 2 0\nWAVM 2 0.6 0.5\nPWAV 2\n"
             "VDYN 0 0.1 0\nVCYN 0 0.3 0\nNOTE 0 hello\n")
    text = zmx(head_extra=extra).replace("FTYP 0 0 2 1", "FTYP 1 0 2 2").replace("DISZ INFINITY", "DISZ 1000")
    lens = loads_zmx(text)
    assert lens.fields.kind == "object_height"
    assert lens.fields.y == (0.0, 5.0) and lens.fields.x == (0.0, 1.0) and lens.fields.weights == (1.0, 2.0)
    assert lens.wavelengths.nm == (550.0, 600.0) and lens.wavelengths.weights == (1.0, 0.5)
    assert lens.wavelengths.primary == 1
    assert lens.object_distance_mm == 1000.0
    assert lens.meta["vignetting_vuy"] == "0 0.2" and lens.meta["vignetting_vly"] == "0 0.4"
    assert lens.meta["zemax_note"] == "hello"


@pytest.mark.parametrize("kw,kind,value", [("FNUM 2.8 0", "image_fno", 2.8), ("FLOA", "float_by_stop", 0.0)])
def test_aperture_types(kw: str, kind: str, value: float) -> None:
    text = zmx().replace("ENPD 10", kw).replace("DISZ 45", "DISZ 45\n  DIAM 4")
    lens = loads_zmx(text)
    assert (lens.aperture.kind, lens.aperture.value) == (kind, value)


def test_object_na_needs_finite_object() -> None:
    assert loads_zmx(zmx().replace("ENPD 10", "OBNA 0.1").replace("DISZ INFINITY", "DISZ 200")
                     ).aperture.kind == "object_na"
    with pytest.raises(PrescriptionError, match="infinity"):
        loads_zmx(zmx().replace("ENPD 10", "OBNA 0.1"))


def test_ignored_keywords_and_merit_operands_are_harmless() -> None:
    extra = "HIDE 0\nSLAB 1\nRAIM 0 0 1\nPUSH 0\nCOFN QF a b\nTOL TOFF 0 0\nMNUM 1 1\nENVD 20 1 0\n"
    tail = "BLNK\nDMFS 0 0\nREAY 3 1 0 1\nTRAC 0 1 0 0 0.1 0.2\n"
    text = zmx(head_extra=extra, extra1="HIDE 0 0\n  MIRR 2 0\n  POPS 0 0\n  MEMA 3 0\n  FLAP 0 3 0\n  COMM front",
               tail=tail)
    lens = loads_zmx(text)
    assert lens.surfaces[0].label == "front"
    assert lens == loads_zmx(zmx(extra1="COMM front"))


@pytest.mark.parametrize("edit,needle", [
    (("TYPE STANDARD", "TYPE COORDBRK"), "coordinate break with a curvature"),
    (("TYPE STANDARD", "TYPE DGRATING"), "grating"),
    (("TYPE STANDARD", "TYPE GRID_SAG"), "grid sag"),
    (("TYPE STANDARD", "TYPE XYZZY"), "surface type XYZZY"),
    (("MODE SEQ", "MODE NSC"), "only sequential"),
    (("DISZ 5", "DISZ 5\n  DECX 1"), "decenter"),
    (("DISZ 5", "DISZ 5\n  TILT 1"), "tilt"),
    (("DISZ 5", "DISZ 5\n  SQAP 2 -2 0"), "SQAP 2 -2: sizes must be finite and not negative"),
    (("DISZ 5", "DISZ 5\n  OBSC 1"), "OBSC needs two sizes"),
    (("DISZ 5", "DISZ 5\n  CLAP 3 1 0"), "inner radius 3 mm"),
    (("DISZ 5", "DISZ 5\n  SPID 1 4"), "spider"),
    (("DISZ 5", "DISZ 5\n  SCBD 2 1 2 0 0 5 0 0"), "tilt/decenter after"),
    (("GCAT SCHOTT", "GCAT SCHOTT\nMNUM 3 1\nPRAM 2 1 0 0 0 0 1 1 1 0 0 \"\" 0"), "multi-configuration operand PRAM"),
    (("GCAT SCHOTT", "GCAT SCHOTT\nVANN 0 10"), "vignetting angle"),
    (("GCAT SCHOTT", "GCAT SCHOTT\nPUPD 1 0.5"), "apodization"),
    (("FTYP 0 0 2 1", "FTYP 4 0 2 1"), "theodolite"),
    (("ENPD 10", "ENPD 10\nFNUM 4"), "two system apertures"),
    (("ENPD 10\n", ""), "no system aperture"),
    (("SURF 0\n  DISZ INFINITY", "SURF 0\n  CURV 0.1\n  DISZ INFINITY"), "curved object"),
    (("SURF 3\n", "SURF 3\n  CURV 0.01\n  CONI -1\n"), "curved image"),  # a sphere reads; a conic does not
    (("SURF 2\n", "SURF 5\n"), "out of order"),
    (("DISZ 5", "DISZ INFINITY"), "INFINITY on a lens surface"),
    (("CURV 0.02", "CURV 0.02\n  PARM 2 1e-5"), "PARM on a STANDARD"),
    (("PWAV", "PWAV"), None),
])
def test_unsupported_constructs_name_file_line_construct(edit: tuple[str, str], needle: str | None) -> None:
    text = zmx().replace(*edit) if edit[0] != "PWAV" else zmx(head_extra="PWAV 3\n")
    needle = needle or "PWAV 3"
    with pytest.raises(PrescriptionError) as err:
        loads_zmx(text, "bad.zmx")
    msg = str(err.value)
    assert needle in msg
    assert msg.startswith("bad.zmx")
    assert "\n" not in msg


def test_error_line_numbers() -> None:
    text = zmx().replace("TYPE STANDARD", "TYPE GRID_SAG")
    with pytest.raises(PrescriptionError) as err:
        loads_zmx(text, "bad.zmx")
    assert text.splitlines()[err.value.line - 1].strip() == "TYPE GRID_SAG"


def _rayoptics_files(sub: str, pattern: str) -> list[Path]:
    ro = pytest.importorskip("rayoptics")
    return sorted(Path(ro.__file__).parent.joinpath(sub).glob(pattern))


def test_real_opticstudio_files_load_or_fail_cleanly() -> None:
    """The .zmx files rayoptics ships (patents, Handbook of Optics, vendor files): each one
    either loads or names the construct lensrt does not model -- never another exception."""
    files = _rayoptics_files("zemax", "**/*.[zZ][mM][xX]")
    assert len(files) >= 10
    outcome = {}
    for path in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", GlassFallbackWarning)
                lens = read_lens(path)
            outcome[path.name] = ("ok", lens.n_surfaces)
        except LensrtError as err:
            msg = str(err)
            assert str(path) in msg and "\n" not in msg
            outcome[path.name] = ("error", msg.split(": ", 1)[1])
    assert outcome["US00583336-2-scaled.zmx"] == ("ok", 12)
    # Ohara L-TIM28_MOLD is in no catalog lensrt reads; the line's 1.5/40 are placeholders (EFL 5 % off)
    assert "L-TIM28_MOLD" in outcome["US08427765-1.ZMX"][1] and "no catalog" in outcome["US08427765-1.ZMX"][1]
    assert outcome["HoO-V2C18Ex27.zmx"][0] == "ok"  # mirrors (read; the loader's checks are tested elsewhere)
    assert outcome["HoO-V2C18Ex66.zmx"][0] == "ok"  # coordinate breaks
    assert outcome["US08011793-1.zmx"][0] == "ok"  # decentred rectangular apertures (SQAP, OBDC)
    assert outcome["zmax_37992.zmx"][0] == "ok"  # SCBD on the image surface (tests/prescription/test_reader_gaps.py)

def test_floating_aperture_without_stop_size() -> None:
    """FLOA floats on the stop's DIAM; a stop without one takes the file's other aperture (warned), else an error."""
    with_diam = zmx().replace("ENPD 10", "FLOA").replace("DISZ 45", "DISZ 45\n  DIAM 4")
    assert loads_zmx(with_diam).aperture.kind == "float_by_stop"
    both = zmx().replace("ENPD 10", "ENPD 10\nFLOA")
    with pytest.warns(UserWarning, match="FLOA without a stop semi-diameter"):
        lens = loads_zmx(both)
    assert (lens.aperture.kind, lens.aperture.value) == ("epd", 10.0)
    assert [w.code for w in lens.warnings] == ["assumed_default"]
    with pytest.raises(PrescriptionError, match="FLOA: .* no DIAM/CLAP"):
        loads_zmx(zmx().replace("ENPD 10", "FLOA"), "f.zmx")


def test_unknown_keywords_warn_and_are_listed() -> None:
    text = zmx(head_extra="IWDP 1 0\nZVCY 0 0\n", extra1="FOOB 1")
    with pytest.warns(UserWarning, match="'IWDP' on line"):
        lens = loads_zmx(text, "k.zmx")
    got = {(w.text.split("'")[1], w.line) for w in lens.warnings if w.code == "keyword_unknown"}
    lines = text.splitlines()
    assert got == {(k, next(i + 1 for i, ln in enumerate(lines) if ln.strip().startswith(k)))
                   for k in ("IWDP", "ZVCY", "FOOB")}
    assert lens.surfaces == loads_zmx(zmx()).surfaces
