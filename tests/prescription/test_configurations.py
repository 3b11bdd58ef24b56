"""Multi-configuration lenses: the model, the native/Zemax/CODE V readers, and bad input.

Oracles: each configuration equals the base lens with exactly the file's values
changed; rayoptics (test-only peer) reads each CODE V zoom position written out
as its own sequence and gives the same EFL; a round trip through the native
writer gives back an equal family.

The fixtures ``cooke_triplet_mce.zmx`` and ``ag_dblgauss_zoom.seq`` are lensrt
test data (public single-configuration lenses with multi-configuration rows
added by hand, following the format the Zemax/CODE V documentation and public
exporters show). The public multi-configuration file is the corpus's
``US20250155694_Example01P.zmx`` (see tests/data/corpus/SOURCES.md); no public
zoom .seq was found.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from lensrt.errors import PrescriptionError
from lensrt.paraxial import first_order
from lensrt.prescription.configurations import ConfigOperand, MultiConfigLens
from lensrt.prescription.formats import read_configurations, read_lens
from lensrt.prescription.formats.codev import loads_seq
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.formats.zemax import loads_zmx

DATA = Path(__file__).resolve().parents[1] / "data"
ZMX = DATA / "cooke_triplet_mce.zmx"
SEQ = DATA / "ag_dblgauss_zoom.seq"


def test_zemax_configurations_apply_exactly_the_operands() -> None:
    fam = read_configurations(ZMX)
    assert fam.names == ("near-gap", "mid", "far-gap") and fam.current == 0
    base = read_lens(ZMX)
    mid = fam.configuration("mid")
    assert mid.surfaces[1].thickness_mm == 5.5 and mid.object_distance_mm == 5000.0
    assert mid.aperture.value == 9.0 and mid.fields.y[2] == pytest.approx(math.radians(19.0), rel=1e-15)
    assert mid.wavelengths.nm[0] == 486.1327 and mid.wavelengths.nm[1] == 587.5618
    assert fam.configuration(1) == fam.configuration("near-gap") == base.replace(notes=mid.notes[:-1] + (
        ("configuration", "1 of 3: near-gap"),))
    # nothing else changes
    for a, b in zip(base.surfaces, mid.surfaces):
        assert a.curvature_per_mm == b.curvature_per_mm and a.material == b.material
    assert math.isinf(fam.configuration(3).object_distance_mm) is False
    assert read_lens(ZMX, config="far-gap").surfaces[1].thickness_mm == 6.5


def test_codev_zoom_positions_and_current_position() -> None:
    fam = read_configurations(SEQ)
    assert fam.count == 3 and fam.current == 1  # POS 2
    assert read_lens(SEQ).surfaces[4].thickness_mm == 15.0
    z3 = fam.configuration("Z3")
    assert z3.surfaces[4].thickness_mm == 18.0 and z3.surfaces[10].thickness_mm == 61.0
    assert fam.configuration(2).aperture.value == 45.0



def test_codev_zoom_as_codev_saves_it() -> None:
    """The rows CODE V writes around zoom data when it saves a lens: ``ZOO n`` (the position count),
    ``ZOO TIT`` with ``TIT Zk`` titles (CODE V doubles the quotes), per-position solve/variable codes
    (``ZOO THC S5 100 100 100``, skipped: no optics). Same positions as the plain fixture, named."""
    text = SEQ.read_text().replace(
        "ZOO THI S5", "ZOO 3\nZOO TIT\nTIT Z1 \"\"wide\"\"\nTIT Z2 'mid'\nTIT Z3 \"\"tele\"\"\n"
        "ZOO THC S5 100 100 100\nZOO THI S5", 1).replace("POS 2", "ZOO CCY S6 100 0 100\nPOS 2")
    fam = loads_seq(text, "saved.seq")
    plain = read_configurations(SEQ)
    assert fam.names == ("wide", "mid", "tele") and fam.current == 1
    for a, b in zip(fam.configurations(), plain.configurations()):
        assert a.surfaces == b.surfaces and a.fields == b.fields and a.aperture == b.aperture
    assert fam.configuration("tele").surfaces[4].thickness_mm == 18.0
    with pytest.raises(PrescriptionError, match="ZOO 4: an earlier ZOO command gives 3"):
        loads_seq(text.replace("ZOO TIT", "ZOO TIT\nZOO 4", 1), "bad.seq")
    with pytest.raises(PrescriptionError, match="gives 3 positions, the first ZOO command 2"):
        loads_seq(text.replace("ZOO 3", "ZOO 2").replace('TIT Z3 ""tele""\n', ""), "bad.seq")
    with pytest.raises(PrescriptionError, match="TIT Z5: position 5 is not one of the 3"):
        loads_seq(text.replace("TIT Z3", "TIT Z5"), "bad.seq")

def test_codev_zoomed_decenter_is_the_sequence_with_that_decenter() -> None:
    """``ZOO YDE S3 0 0.5 -0.5`` (with its code row ``ZOO YDC``): position k is the plain sequence whose surface 3
    carries ``YDE`` of position k (a basic decenter); ``ZOO VUY F2`` that repeats the sequence's VUY is read, one
    that changes it is refused (lensrt keeps one vignetting factor per field)."""
    rows = "ZOO YDE S3 0 0.5 -0.5\nZOO YDC S3 100 100 100\nZOO VUY F2 0.2 0.2 0.2\nZOO VLY F3 0.4 0.4 0.4"
    fam = loads_seq(_seq(rows), "zoom.seq")
    assert fam.configuration(1).surfaces == loads_seq(SEQ.read_text()).configuration(1).surfaces
    for k, dy in ((2, "0.5"), (3, "-0.5")):
        plain = loads_seq(_position_seq(SEQ.read_text(), {}).replace("S     0.02653743294670983 12.5 NSK2_SCHOTT",
                                                                      "S     0.02653743294670983 12.5 NSK2_SCHOTT\n"
                                                                      f"  YDE {dy}"))
        other = read_configurations(SEQ).configuration(k)  # the thicknesses of position k, no decenter
        want = [a if i != 2 else b for i, (a, b) in enumerate(zip(other.surfaces, plain.surfaces))]
        assert list(fam.configuration(k).surfaces) == want
        assert fam.configuration(k).surfaces[2].transform_before.decenter_y_mm == float(dy)
    with pytest.raises(PrescriptionError, match="ZOO VUY F2: a vignetting factor that changes"):
        loads_seq(_seq("ZOO VUY F2 0.2 0.3 0.2"), "bad.seq")
    with pytest.raises(PrescriptionError, match="ZOO YDE S3: the surface's decenter is DAR"):
        loads_seq(_seq("ZOO YDE S3 0 0.5 -0.5").replace("S     0.02653743294670983 12.5 NSK2_SCHOTT",
                                                         "S     0.02653743294670983 12.5 NSK2_SCHOTT\n  DAR"),
                  "bad.seq")


def _position_seq(text: str, values: dict[str, str]) -> str:
    """The zoom sequence as a plain sequence of one position (ZOO/POS lines dropped)."""
    out = [ln for ln in text.splitlines() if not ln.strip().startswith(("ZOO", "POS", "!"))]
    text = "\n".join(out) + "\n"
    for old, new in values.items():
        text = text.replace(old, new)
    return text


def test_codev_zoom_efl_matches_rayoptics_per_position(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("rayoptics")
    monkeypatch.chdir(tmp_path)  # rayoptics writes its reader log into the working folder
    from rayoptics.environment import open_model
    fam = read_configurations(SEQ)
    text = SEQ.read_text()
    gaps = [("15.0", "62.0", "13.0", "45.0"), ("18.0", "61.0", "15.0", "50.0")]
    for k, (g5, g11, yan, epd) in enumerate(gaps, start=2):
        seq = _position_seq(text, {"16.36944492653564": g5, "61.4875364179821": g11,
                                   "14.0000000032": yan, "EPD   50.0": f"EPD   {epd}"})
        p = tmp_path / f"pos{k}.seq"
        p.write_text(seq)
        opm = open_model(str(p))
        efl_ro = opm["analysis_results"]["parax_data"].fod.efl
        fo = first_order(fam.configuration(k))
        assert fo.efl_mm == pytest.approx(efl_ro, rel=1e-9)
        assert fo.entrance_pupil_diameter_mm == pytest.approx(float(epd), rel=1e-12)


def test_zemax_configurations_efl_match_rayoptics(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each configuration written as a plain .zmx (its gap in the lens data, the multi-configuration
    rows dropped) and read by rayoptics gives lensrt's EFL (model glasses: both use the file's n_d at
    the primary d line)."""
    pytest.importorskip("rayoptics")
    monkeypatch.chdir(tmp_path)  # rayoptics writes its reader log into the working folder
    from rayoptics.environment import open_model
    fam = read_configurations(ZMX)
    text = ZMX.read_text()
    plain = text[:text.index("MNUM")]
    for k, gap in enumerate(["6.00755", "5.5", "6.5"], start=1):
        one = plain.replace("DISZ 6.0075500000000002E+00", f"DISZ {gap}")
        p = tmp_path / f"conf{k}.zmx"
        p.write_text(one)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opm = open_model(str(p))
        efl_ro = opm["analysis_results"]["parax_data"].fod.efl
        lens = fam.configuration(k)
        assert lens.surfaces[1].thickness_mm == float(gap)
        assert first_order(lens).efl_mm == pytest.approx(efl_ro, rel=1e-9)


def test_native_round_trip_and_library_zoom_written_by_convert(tmp_path: Path) -> None:
    fam = read_configurations(ZMX)
    again = loads_native(dumps_native(fam))
    assert isinstance(again, MultiConfigLens)
    for a, b in zip(fam.configurations(), again.configurations()):
        assert a.surfaces == b.surfaces and a.fields == b.fields and a.wavelengths == b.wavelengths
        assert a.aperture == b.aperture and a.object_distance_mm == b.object_distance_mm
    from lensrt.cli import main
    out = tmp_path / "seq.toml"
    assert main(["lens", "convert", str(SEQ), str(out)]) == 0
    conv = read_configurations(out)
    assert conv.names == ("Z1", "Z2", "Z3") and conv.current == 1
    assert [c.surfaces[4].thickness_mm for c in conv.configurations()] == [16.36944492653564, 15.0, 18.0]


# ---- bad input: one clear error each -------------------------------------------------

def _zmx(extra_rows: str) -> str:
    text = ZMX.read_text()
    return text[:text.index("MNUM")] + extra_rows


@pytest.mark.parametrize("rows, words", [
    ("MNUM 2 1\nTHIC 9 1 5 0 0 0 1 1 1 0 0 \"\" 0\nTHIC 9 2 6 0 0 0 1 1 1 0 0 \"\" 0\n",
     ["THIC 9", "surface 9", "1..6"]),
    ("MNUM 2 1\nTHIC 2 1 5 0 0 0 1 1 1 0 0 \"\" 0\nTHIC 2 3 6 0 0 0 1 1 1 0 0 \"\" 0\n",
     ["configuration 3 is out of range", "MNUM gives 2"]),
    ("MNUM 2 1\nTHIC 2 1 5 0 0 0 1 1 1 0 0 \"\" 0\n", ["THIC 2", "no value for configuration 2"]),
    ("MNUM 2 1\nPRAM 2 1 5 0 0 0 1 1 1 0 0 \"\" 0\nPRAM 2 2 5 0 0 0 1 1 1 0 0 \"\" 0\n",
     ["PRAM", "not supported"]),
    ("MNUM 2 3\n", ["MNUM 2 3", "current configuration"]),
    ("MNUM 2 1\nYFIE 7 1 5 0 0 0 1 1 1 0 0 \"\" 0\nYFIE 7 2 6 0 0 0 1 1 1 0 0 \"\" 0\n", ["field 7", "has 3"]),
])
def test_zemax_bad_multiconfiguration_rows(rows: str, words: list[str]) -> None:
    with pytest.raises(PrescriptionError) as err:
        loads_zmx(_zmx(rows), "bad.zmx")
    msg = str(err.value)
    assert "bad.zmx" in msg and "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_zemax_thermal_only_configurations_load_as_one_lens_with_a_note() -> None:
    rows = ("MNUM 2 1\nTEMP 0 1 20 0 0 0 1 1 1 0 0 \"\" 0\nTEMP 0 2 40 0 0 0 1 1 1 0 0 \"\" 0\n")
    lens = loads_zmx(_zmx(rows), "thermal.zmx")
    assert not isinstance(lens, MultiConfigLens)
    assert "temperature" in lens.meta["multi_configuration"]


def _seq(extra: str) -> str:
    return SEQ.read_text().replace("ZOO THI S5", extra + "\nZOO THI S5", 1)


@pytest.mark.parametrize("extra, words", [
    ("ZOO THI S40 1 2 3", ["surface 40", "1..11"]),
    ("ZOO THI S3 1 2", ["gives 3 positions", "the first ZOO command 2"]),
    ("ZOO DEC S3 1 2 3", ["ZOO DEC", "not supported"]),
    ("POS 7", ["POS 7", "3 zoom positions"]),
])
def test_codev_bad_zoom_data(extra: str, words: list[str]) -> None:
    text = _seq(extra)
    if extra.startswith("POS"):
        text = text.replace("POS 2\n", "")
    with pytest.raises(PrescriptionError) as err:
        loads_seq(text, "bad.seq")
    msg = str(err.value)
    assert "bad.seq" in msg and "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_native_bad_configurations() -> None:
    text = dumps_native(read_configurations(ZMX))
    with pytest.raises(PrescriptionError, match="configuration 2 has no thickness_mm"):
        loads_native(text.replace("thickness_mm = { 2 = 5.5 }\n", ""), "x.toml")
    with pytest.raises(PrescriptionError, match="surface 12"):
        loads_native(text.replace("thickness_mm = { 2 =", "thickness_mm = { 12 =")
                     .replace("{ 12 = 6.00755", "{ 12 = 6.00755"), "x.toml")
    with pytest.raises(PrescriptionError, match="unknown key 'thicknes_mm'"):
        loads_native(text.replace("thickness_mm = {", "thicknes_mm = {", 1), "x.toml")


def test_model_errors_and_lookup() -> None:
    lens = read_lens(ZMX)
    with pytest.raises(PrescriptionError, match="gives 1 values for 2 configurations"):
        MultiConfigLens(lens, ("a", "b"), (ConfigOperand("thickness", 1, (5.0,)),))
    with pytest.raises(PrescriptionError, match="two configurations are named 'a'"):
        MultiConfigLens(lens, ("a", "a"))
    fam = MultiConfigLens(lens, ("a", "b"), (ConfigOperand("thickness", 1, (5.0, -80.0)),))
    with pytest.raises(PrescriptionError, match="configuration 3 does not exist"):
        fam.configuration(3)
    with pytest.raises(PrescriptionError, match="no configuration named 'tele'"):
        fam.configuration("tele")
    with pytest.raises(PrescriptionError, match="one configuration|configuration 2 does not exist"):
        read_lens(DATA / "ag_dblgauss.seq", config=2)


# ---- a public multi-configuration file: the corpus's Canon RF 70-200 Z (US 2025/0155694 ex. 1) -----

PUBLIC_ZMX = DATA / "corpus" / "US20250155694_Example01P.zmx"
#: glasses of that file that the catalogs rayoptics reads lack or name differently (rayoptics puts
#: n = 1.5 for NBFD29 and another vendor's BACD12): both readers get them as n_d/V_d model glasses
_MODEL_GLASSES = ("S-LAL7Q", "NBFD29", "BACD12")


def _as_model_glasses(text: str) -> str:
    """The ``GLAS NAME 0 0 nd vd ...`` rows of the glasses above as ``___BLANK`` model glasses."""
    out = []
    for ln in text.splitlines():
        f = ln.split()
        if len(f) > 5 and f[0] == "GLAS" and f[1] in _MODEL_GLASSES:
            ln = f"  GLAS ___BLANK 1 0 {f[4]} {f[5]} 0 0 0 0 0 0"
        out.append(ln)
    return "\n".join(out) + "\n"


def test_public_zemax_zoom_loads_and_each_configuration_matches_rayoptics(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """BeamFour's OpticStudio transcription of US 2025/0155694 example 1 (two zoom positions, nine
    zoomed gaps, aspheres, catalog glasses) loads as two configurations (its three non-catalog
    glasses as the file's n_d/V_d); each configuration written as a plain .zmx (its gaps in the
    lens data, the MNUM rows dropped) and read by rayoptics gives lensrt's EFL at the d line."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fam = read_configurations(PUBLIC_ZMX, glass_model_fallback=True)
    assert fam.count == 2 and fam.current == 0
    assert {op.kind for op in fam.operands} == {"thickness"} and len(fam.operands) == 9
    efl = [first_order(c).efl_mm for c in fam.configurations()]
    assert 70.0 < efl[0] < 74.0 and 190.0 < efl[1] < 198.0  # the 70-200 mm zoom's two ends
    pytest.importorskip("rayoptics")
    monkeypatch.chdir(tmp_path)  # rayoptics writes its reader log into the working folder
    from rayoptics.environment import open_model
    text = _as_model_glasses(PUBLIC_ZMX.read_text())
    rows = [ln.split() for ln in text[text.index("MNUM"):].splitlines()[1:] if ln.startswith("THIC")]
    gaps = {(int(r[1]), int(r[2])): r[3] for r in rows}
    surf_blocks = text[:text.index("MNUM")].split("\nSURF ")  # [header, SURF 0, SURF 1, ...]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        family = loads_zmx(text, "model.zmx")
    for k in (1, 2):
        blocks = list(surf_blocks)
        for (s, c), value in gaps.items():
            if c == k:
                head, _, rest = blocks[s + 1].partition("DISZ ")
                blocks[s + 1] = head + "DISZ " + value + "\n" + rest.split("\n", 1)[1]
        p = tmp_path / f"conf{k}.zmx"
        p.write_text("\nSURF ".join(blocks))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opm = open_model(str(p))
        efl_ro = opm["analysis_results"]["parax_data"].fod.efl
        lens = family.configuration(k)
        assert [s.thickness_mm for s in lens.surfaces] == [g.thi for g in opm["seq_model"].gaps[1:]]
        assert first_order(lens).efl_mm == pytest.approx(efl_ro, rel=1e-9)
        # the file as published (model-glass fallback, or a catalog's S-LAL7Q once one is read:
        # n_d differs in the 6th decimal) gives the same EFL to that precision
        assert efl[k - 1] == pytest.approx(efl_ro, rel=1e-5)
