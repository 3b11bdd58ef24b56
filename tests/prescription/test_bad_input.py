"""Bad lens files: one PrescriptionError naming the file (and line), exit status 2 from the CLI, no traceback."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lensrt.cli import main
from lensrt.errors import PrescriptionError
from lensrt.loading import load_lens

NATIVE = """[aperture]
type = "epd"
value = 10.0
[fields]
y = [0.0, 5.0]
[wavelengths]
nm = [587.6]
[[surface]]
radius_mm = 50.0
thickness_mm = 5.0
material = "N-BK7"
semi_diameter_mm = 8.0
stop = true
[[surface]]
radius_mm = -50.0
thickness_mm = 47.0
semi_diameter_mm = 8.0
"""
ZMX = """VERS 1 0 0
MODE SEQ
UNIT MM
ENPD 10
FTYP 0 0 1 1
YFLN 0
WAVM 1 0.55 1
GCAT SCHOTT
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  CURV 0.02
  DISZ 5
  GLAS N-BK7 0 0 1.5168 64.17
SURF 2
  CURV -0.02
  DISZ 47
SURF 3
"""
SEQ = """RDM Y
EPD 10
WL 587.6
YAN 0
SO 0 1e10
S 50 5 NBK7_SCHOTT
  STO
S -50 47
SI 0 0
GO
"""
DAT = """# test lens
50 5 1.5 16
0 1 0 15
-50 0 1 16
"""


def _case(name: str, text: str | bytes, tmp_path: Path) -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


CASES = {
    # id: (file name, content, words the message must contain)
    "missing": ("nope.zmx", None, "file not found"),
    "empty": ("empty.seq", "", "file is empty"),
    "blank": ("blank.toml", "  \n\n", "file is empty"),
    "binary": ("garbage.zmx", bytes(np.random.default_rng(7).integers(0, 256, 3000, dtype=np.uint8)), "binary data"),
    "toml_in_zmx": ("lens.zmx", NATIVE, "holds a lensrt TOML lens"),
    "zemax_in_seq": ("lens.seq", ZMX, "holds a Zemax .zmx lens"),
    "codev_in_dat": ("lens.dat", SEQ, "holds a CODE V sequence"),
    "toml_in_dat": ("lens.dat", NATIVE, "holds a lensrt TOML lens"),
    "text_in_zmx": ("notes.zmx", "just some words\nand more\n", "no SURF lines"),
    "nan_zmx": ("nan.zmx", ZMX.replace("CURV 0.02", "CURV nan"), "curvature is 'nan'"),
    "inf_seq": ("inf.seq", SEQ.replace("S 50 5", "S 50 inf"), "thickness is 'inf'"),
    "nan_toml": ("nan.toml", NATIVE.replace("value = 10.0", "value = nan"), "aperture"),
    "inf_dat": ("inf.dat", DAT.replace("50 5 1.5", "50 inf 1.5"), "thickness is 'inf'"),
    "neg_glass_thickness": ("neg.toml", NATIVE.replace("thickness_mm = 5.0", "thickness_mm = -5.0"), "cross"),
    "neg_glass_thickness_nosd": ("neg2.seq", SEQ.replace("S 50 5", "S 50 -5"), "negative thickness"),
    "neg_image_distance": ("negimg.toml", NATIVE.replace("thickness_mm = 47.0", "thickness_mm = -47.0"),
                           "image surface lies"),
    "no_stop": ("nostop.zmx", ZMX.replace("  STOP\n", ""), "no aperture stop"),
    "two_stops": ("twostops.seq", SEQ.replace("S -50 47", "S -50 47\n  STO"), "2 aperture stops"),
    "two_stops_dat": ("twostops.dat", DAT.replace("-50 0 1 16", "0 2 0 15\n-50 0 1 16"), "2 aperture stops"),
    "sd_beyond_radius": ("bigsd.toml", NATIVE.replace("semi_diameter_mm = 8.0\nstop", "semi_diameter_mm = 60.0\nstop"),
                         "exceeds"),
    "sd_beyond_radius_zmx": ("bigsd.zmx", ZMX.replace("DISZ 5", "DISZ 5\n  DIAM 51"), "exceeds"),
    "crossing_sags": ("cross.toml", NATIVE.replace("thickness_mm = 5.0", "thickness_mm = 0.5"), "cross"),
    "fno_below_half_zmx": ("fast.zmx", ZMX.replace("ENPD 10", "FNUM 0.3"), "below 0.5"),
    "fno_below_half_seq": ("fast.seq", SEQ.replace("EPD 10", "FNO 0.4"), "below 0.5"),
    "fno_below_half_toml": ("fast.toml", NATIVE.replace('type = "epd"\nvalue = 10.0', 'type = "image_fno"\nvalue = 0.2'),
                            "below 0.5"),
    "unknown_glass": ("glass.seq", SEQ.replace("NBK7_SCHOTT", "NOSUCHGLASS"), "no catalog"),
    # the ideal paraxial lens (TYPE PARAXIAL: PARM 1 focal length, PARM 2 OPD mode; issue 22)
    "paraxial_focal_zero": ("p0.zmx", ZMX.replace("SURF 2\n  CURV -0.02", "SURF 2\n  TYPE PARAXIAL\n  PARM 1 0"),
                            "focal length 0"),
    "paraxial_parm3": ("p3.zmx", ZMX.replace("SURF 2\n  CURV -0.02",
                                             "SURF 2\n  TYPE PARAXIAL\n  PARM 1 50\n  PARM 3 1"), "PARM 3"),
    "paraxial_opd_mode": ("p2.zmx", ZMX.replace("SURF 2\n  CURV -0.02",
                                                "SURF 2\n  TYPE PARAXIAL\n  PARM 1 50\n  PARM 2 7"), "OPD mode 7"),
    "ideal_curved_toml": ("ideal.toml", NATIVE.replace("radius_mm = -50.0", "radius_mm = -50.0\nideal_focal_mm = 40.0"),
                          "ideal paraxial lens is a plane"),
    "unknown_extension": ("lens.txt", ZMX, None),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_reader_raises_one_error(case: str, tmp_path: Path) -> None:
    name, text, needle = CASES[case]
    path = tmp_path / name if text is None else _case(name, text, tmp_path)
    if case == "unknown_extension":
        # a file without a known extension is sniffed from its content
        assert load_lens(path).n_surfaces == 2
        return
    with pytest.raises(PrescriptionError) as err:
        load_lens(path)
    msg = str(err.value)
    assert needle in msg, msg
    assert msg.startswith(str(path)), msg
    assert "\n" not in msg


@pytest.mark.parametrize("case", sorted(c for c in CASES if c != "unknown_extension"))
def test_cli_exits_2_with_one_line(case: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    name, text, needle = CASES[case]
    path = tmp_path / name if text is None else _case(name, text, tmp_path)
    for argv in (["lens", "show", str(path)], ["lens", "convert", str(path), str(tmp_path / "out.toml")]):
        rc = main(argv)
        out, err = capsys.readouterr()
        assert rc == 2
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith("lensrt: error: ") and str(path) in lines[0] and needle in lines[0]
        assert "Traceback" not in err + out
        assert not (tmp_path / "out.toml").exists()  # nothing half-written


def test_line_numbers_are_reported(tmp_path: Path) -> None:
    p = _case("bad.zmx", ZMX.replace("CURV -0.02", "CURV x"), tmp_path)
    with pytest.raises(PrescriptionError) as err:
        load_lens(p)
    assert err.value.line == ZMX.splitlines().index("  CURV -0.02") + 1
    assert f"{p}:{err.value.line}:" in str(err.value)


def test_unknown_extension_and_content(tmp_path: Path) -> None:
    p = _case("lens.txt", "hello world\n", tmp_path)
    with pytest.raises(PrescriptionError, match="unknown lens file type"):
        load_lens(p)


def test_option_for_another_format(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    p = _case("lens.zmx", ZMX, tmp_path)
    assert main(["lens", "show", str(p), "--pbrt-thickness", "next"]) == 2
    assert "does not apply to a zemax file" in capsys.readouterr().err
