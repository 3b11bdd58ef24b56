"""CODE V .seq reader: the sample double Gauss against its listing, syntax, units, aspheres, the unsupported list."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import LensrtError, PrescriptionError
from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.codev import loads_seq, tokenize_seq
from lensrt.prescription.materials import ModelGlass
from lensrt.paraxial.first_order import first_order

BASE = """RDM N
TITLE 'test lens'
EPD 10
DIM M
WL 587.6
YAN 0 5
SO 0 1e10
S 0.02 5 NBK7_SCHOTT
  STO
S -0.02 45
SI 0 0
GO
"""


def test_double_gauss_against_the_listing(data_dir: Path) -> None:
    lens = read_lens(data_dir / "ag_dblgauss.seq")
    # RDY column of the listing (radius mode there; the .seq is in curvature mode)
    rdy = [56.20238, 152.28580, 37.68262, math.inf, 24.23130, math.inf, -28.37731, math.inf, -37.92546,
           177.41176, -79.41143]
    assert [s.radius_mm for s in lens.surfaces] == pytest.approx(rdy, rel=1e-6)
    thi = [8.75, 0.5, 12.5, 3.8, 16.369445, 13.747957, 3.8, 11.0, 0.5, 7.0]
    assert [s.thickness_mm for s in lens.surfaces[:-1]] == pytest.approx(thi, abs=1e-6)
    # SI's thickness is a defocus: IMG DIS 61.0873 = 61.4875 - 0.4003 (listing)
    assert lens.surfaces[-1].thickness_mm == 61.4875364179821 - 0.4002686453541377
    assert lens.stop_index == 5
    assert [s.material.describe() for s in lens.surfaces if not s.material.is_air] == [
        "N-SSK2 (Schott)", "N-SK2 (Schott)", "F5 (Schott)", "F5 (Schott)", "N-SK16 (Schott)", "N-SK16 (Schott)"]
    assert (lens.aperture.kind, lens.aperture.value) == ("epd", 50.0)
    assert lens.wavelengths.nm == (656.3, 587.6, 486.1) and lens.wavelengths.primary_nm == 587.6
    assert [math.degrees(v) for v in lens.fields.y] == pytest.approx([0.0, 10.0, 14.0], abs=1e-8)
    assert math.isinf(lens.object_distance_mm)  # SO thickness 9.9e11 >= 1e10
    assert lens.meta["vignetting_vuy"] == "0 0.2 0.4" and lens.meta["vignetting_vly"] == "0 0.25 0.4"
    assert lens.name == "Double Gauss F/2 -  Available Glasses"


def test_double_gauss_listing_indices_and_first_order(data_dir: Path) -> None:
    """REFRACTIVE INDICES and INFINITE CONJUGATES of ag_dblgauss.lis."""
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    lens = load_lens(data_dir / "ag_dblgauss.seq")
    listing = {"NSSK2": (1.618769, 1.622292, 1.630455), "NSK2": (1.604134, 1.607379, 1.614860),
               "F5": (1.598744, 1.603417, 1.614617), "NSK16": (1.617271, 1.620408, 1.627559)}
    for s in lens.surfaces:
        if not s.material.is_air:
            n = s.material.index(np.array(lens.wavelengths.nm))
            assert n == pytest.approx(listing[s.material.name.replace("-", "")], abs=6e-7)
    fo = first_order(lens)
    assert fo.efl_mm == pytest.approx(100.0038, abs=6e-5)
    assert fo.bfl_mm == pytest.approx(61.4875, abs=6e-5)
    assert fo.f_number == pytest.approx(2.0001, abs=6e-5)
    assert fo.image_z_mm - lens.vertex_z_mm()[-2] == pytest.approx(61.4875, abs=6e-5)
    assert lens.image_z_mm - lens.vertex_z_mm()[-2] == pytest.approx(61.0873, abs=6e-5)  # IMG DIS


def test_tokenizer() -> None:
    text = "RDM N;LEN \"a;b\" ! comment ; not a command\nS 1 &\n 2 NBK7\nyan 0, 10\n"
    assert tokenize_seq(text) == [(1, ["RDM", "N"]), (1, ["LEN", '"a;b"']), (2, ["S", "1", "2", "NBK7"]),
                                  (4, ["yan", "0", "10"])]


def test_lowercase_semicolons_comments_and_long_names() -> None:
    text = ("rdm; tit 'x'; dim m\nepd 10 ! the pupil\nwl 587.6\nyan 0 5\nso 0 1e10\ns 50 5 nbk7_schott; stop\n"
            "s -50 45\nsi 0 0\ngo\n")
    lens = loads_seq(text)
    assert lens.surfaces[0].radius_mm == 50.0  # RDM: radius mode
    assert lens.surfaces[0].is_stop and lens.name == "x"
    assert lens == loads_seq(BASE.replace("'test lens'", "'x'"))


@pytest.mark.parametrize("dim,scale", [("M", 1.0), ("C", 10.0), ("I", 25.4)])
def test_dimensions_and_aspheres(dim: str, scale: float) -> None:
    text = BASE.replace("DIM M", f"DIM {dim}").replace("  STO", "  STO\n  ASP\n  K -1\n  A 1e-5; B -2e-8\n  CIR 4")
    lens = loads_seq(text)
    s = lens.surfaces[0]
    assert s.curvature_per_mm == pytest.approx(0.02 / scale, rel=1e-15)
    assert s.thickness_mm == pytest.approx(5 * scale, rel=1e-15)
    assert s.semi_diameter_mm == pytest.approx(4 * scale, rel=1e-15)
    assert s.conic == -1.0
    # A is the r^4 coefficient: asphere[1]; B the r^6: asphere[2]; no r^2 term
    assert s.asphere == pytest.approx((0.0, 1e-5 / scale ** 3, -2e-8 / scale ** 5), rel=1e-14)
    assert lens.aperture.value == pytest.approx(10 * scale)


def test_specification_commands() -> None:
    text = BASE.replace("WL 587.6", "WL 486.1 587.6 656.3\nREF 3\nWTW 1 2 1").replace(
        "YAN 0 5", "YOB 0 3 4\nXOB 0 0 1\nWTF 1 1 .5\nVUY 0 .1 .2\nVLY 0 .1 .3").replace(
        "SO 0 1e10", "SO 0 250").replace("EPD 10", "NAO 0.05")
    lens = loads_seq(text)
    assert lens.wavelengths.primary_nm == 656.3 and lens.wavelengths.weights == (1.0, 2.0, 1.0)
    assert lens.fields.kind == "object_height" and lens.fields.y == (0.0, 3.0, 4.0)
    assert lens.fields.x == (0.0, 0.0, 1.0) and lens.fields.weights == (1.0, 1.0, 0.5)
    assert lens.object_distance_mm == 250.0
    assert (lens.aperture.kind, lens.aperture.value) == ("object_na", 0.05)
    assert lens.meta["vignetting_vly"] == "0 0.1 0.3"


def test_fictitious_glass_and_image_defocus() -> None:
    lens = loads_seq(BASE.replace("NBK7_SCHOTT", "517.642").replace("SI 0 0", "SI 0 -0.5"))
    assert lens.surfaces[0].material == ModelGlass(1.517, 64.2, name="517.642")
    assert lens.surfaces[-1].thickness_mm == 44.5
    assert lens.meta["image_defocus_mm"].startswith("-0.5")


def test_variable_codes_are_ignored_and_pim_is_solved() -> None:
    """Variable codes change nothing; PIM (a paraxial image solve) now moves the written 45 mm to the paraxial
    focus (lensrt.paraxial's BFL of the same lens: an independent ynu), with a ``solve`` warning."""
    assert loads_seq(BASE.replace("S -0.02 45", "S -0.02 45\n  CCY 0; THC 0; GLC 100\nDER VAL I1 1e-5")) == \
        loads_seq(BASE)
    with pytest.warns(UserWarning, match="the solve gives thickness"):
        a = loads_seq(BASE.replace("S -0.02 45", "S -0.02 45\n  PIM"))
    assert a.surfaces[-1].thickness_mm == pytest.approx(first_order(loads_seq(BASE)).bfl_mm, rel=1e-12)
    assert [w.code for w in a.warnings] == ["solve"]


@pytest.mark.parametrize("edit,needle", [
    (("SI 0 0", "SI 0 0 REFL"), "cannot be mirrors"),
    (("  STO", "  STO\n  REFL"), "REFL on a line of its own"),  # not the 3-letter REF (reference wavelength)
    (("  STO", "  STO\n  RET S1"), "RET S1 on surface 1: surface 1 is not an earlier S surface"),
    (("  STO", "  STO\n  ADE"), "ADE without a value"),
    (("SI 0 0", "SI 0 0\nDAR"), "DAR without a surface"),
    (("  STO", "  STO\n  XTO"), "toroidal"),
    (("  STO", "  STO\n  DIF DOE"), "diffractive"),
    (("  STO", "  STO\n  REX 3"), "rectangle aperture without REY"),
    (("  STO", "  STO\n  REX 3; ELY 2"), "mixes a rectangular and an elliptical"),
    (("EPD 10", "EPD 10\nZOO XYZ 1 2 3"), "zooming XYZ is not supported"),  # ZOO 3 alone: 3 positions
    (("EPD 10", "EPD 10\nPRV"), "close the private catalog with END"),
    (("EPD 10", "EPD 10\nNA 0.1"), "image-space NA"),
    (("EPD 10", "EPD 10\nFNO 2"), "two system apertures"),
    (("EPD 10\n", ""), "no system aperture"),
    (("WL 587.6\n", ""), "no wavelengths"),
    (("  STO", "  STO\n  2.5377"), "not a command"),
    (("SO 0 1e10", "SO 0.01 1e10"), "curved object"),
    (("SI 0 0", "SI 0 0\n  K -1"), "K without a surface"),  # a spherical SI reads (test_curved_image); no conic
    (("S 0.02 5 NBK7_SCHOTT", "S 0.02 5 NBK7_SCHOTT EXTRA"), "unexpected"),
    (("S 0.02 5 NBK7_SCHOTT", "S 0.02 nan NBK7_SCHOTT"), "thickness is 'nan'"),
    (("S 0.02 5 NBK7_SCHOTT", "S 0.02 5 NBK77_SCHOTT"), "no catalog"),
    (("YAN 0 5", "YAN 0 5\nYIM 0 3"), "two field definitions"),
    (("REF", "REF"), None),
])
def test_unsupported_constructs(edit: tuple[str, str], needle: str | None) -> None:
    text = BASE.replace(*edit) if edit[0] != "REF" else BASE.replace("WL 587.6", "WL 587.6\nREF 2")
    needle = needle or "REF 2"
    with pytest.raises(PrescriptionError) as err:
        loads_seq(text, "bad.seq")
    msg = str(err.value)
    assert needle in msg and msg.startswith("bad.seq") and "\n" not in msg


def test_error_points_at_the_line() -> None:
    text = BASE.replace("  STO", "  STO\n  XTO 3")
    with pytest.raises(PrescriptionError) as err:
        loads_seq(text, "bad.seq")
    assert text.splitlines()[err.value.line - 1].strip() == "XTO 3"


def test_real_codev_files_load_or_fail_cleanly() -> None:
    ro = pytest.importorskip("rayoptics")
    files = sorted(Path(ro.__file__).parent.joinpath("codev", "tests").glob("*.seq"))
    assert len(files) >= 20
    loaded = []
    for path in files:
        try:
            loaded.append(read_lens(path).n_surfaces)
        except LensrtError as err:
            assert str(path) in str(err) and "\n" not in str(err)
    assert len(loaded) >= 5


@pytest.mark.parametrize("code,nd,vd", [("1.55:55.8", 1.55, 55.8), ("517642", 1.517, 64.2), ("517.642", 1.517, 64.2),
                                        ("'1.6:40'", 1.6, 40.0)])
def test_fictitious_glass_forms(code: str, nd: float, vd: float) -> None:
    with pytest.warns(UserWarning, match="fictitious glass"):
        lens = loads_seq(BASE.replace("NBK7_SCHOTT", code))
    m = lens.surfaces[0].material
    assert isinstance(m, ModelGlass) and (m.nd, m.vd) == (nd, vd)
    assert [w.code for w in lens.warnings] == ["glass_model"]


def test_continuation_glued_to_a_number() -> None:
    """'650.0&' continues the command as '650.0 &' does (rayoptics' CODV_65988.seq writes it so)."""
    text = BASE.replace("WL 587.6", "WL 486.1 587.6&\n 656.3\nREF 2")
    assert loads_seq(text).wavelengths.nm == (486.1, 587.6, 656.3)
    assert tokenize_seq("PWL 1 2&\n 3\n") == [(1, ["PWL", "1", "2", "3"])]


def test_private_catalog_fitted_to_its_indices() -> None:
    """A PRV glass whose indices come from N-BK7 (opticalglass) at the PWL wavelengths: the fit reproduces
    them, and N-BK7 between them, to the data's own digits."""
    from lensrt.prescription.materials import find_glass
    bk7 = find_glass("N-BK7")
    pwl = [1014.0, 852.1, 706.5, 656.3, 587.6, 546.1, 486.1, 435.8, 404.7]
    idx = " ".join(f"{bk7.index(w):.6f}" for w in pwl)
    text = BASE.replace("SO 0 1e10", f"PRV\n  PWL {' '.join(map(str, pwl))}\n  'MY-BK7' {idx}\nEND\nSO 0 1e10")
    with pytest.warns(UserWarning, match="private catalog"):
        lens = loads_seq(text.replace("NBK7_SCHOTT", "'MY-BK7'"))
    m = lens.surfaces[0].material
    assert m.catalog == "PRV" and m.valid_range_nm == (404.7, 1014.0)
    w = np.linspace(410.0, 1000.0, 31)
    assert np.max(np.abs(m.index(w) - bk7.index(w))) < 2e-6
    assert [x.code for x in lens.warnings] == ["glass_private"]
    with pytest.raises(PrescriptionError, match="8 indices for 9 PWL"):
        loads_seq(text.replace(f"{bk7.index(404.7):.6f}", "").replace("NBK7_SCHOTT", "'MY-BK7'"))


def test_rayoptics_private_catalog_file() -> None:
    """CODV_65988_noDOE.seq: its PRV glass E48, '&' lines and 'CUF 0.0' read; the lens's glass is the PRV one."""
    ro = pytest.importorskip("rayoptics")
    path = Path(ro.__file__).parent / "codev" / "tests" / "CODV_65988_noDOE.seq"
    with pytest.warns(UserWarning, match="private catalog"):
        lens = read_lens(path)
    assert lens.surfaces[0].material.catalog == "PRV" and lens.surfaces[0].asphere[1] == -0.1581980090969e-4


def test_non_optical_and_unknown_commands() -> None:
    with pytest.warns(UserWarning, match="'XYZQ'"):
        lens = loads_seq(BASE.replace("EPD 10", "EPD 10\nDOR 1\nUID 'me'\nXYZQ 3"))
    assert [w.text.split("'")[1] for w in lens.warnings if w.code == "keyword_unknown"] == ["XYZQ"]
    assert lens.surfaces == loads_seq(BASE).surfaces


def test_documented_defaults() -> None:
    """No STO: the stop is surface 1; no RDM: curvatures; short VUY lists: the rest 0. Each is warned."""
    text = BASE.replace("RDM N\n", "").replace("  STO\n", "").replace("YAN 0 5", "YAN 0 5 7\nVUY 0.1")
    with pytest.warns(UserWarning):
        lens = loads_seq(text)
    assert lens.stop_index == 0 and lens.surfaces[0].curvature_per_mm == 0.02
    assert lens.meta["vignetting_vuy"] == "0.1 0 0"
    assert sorted(w.code for w in lens.warnings) == ["assumed_default"] * 3


def test_landscape_lens_reads_as_rayoptics_does() -> None:
    """rayoptics' landscape_lens.seq has no RDM: read as curvatures its EFL is ~10 mm, the 10.15 mm image
    distance the file itself gives; as radii it would be -1.33 mm (a lens that images nothing there)."""
    ro = pytest.importorskip("rayoptics")
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    from rayoptics.environment import open_model
    path = Path(ro.__file__).parent / "codev" / "tests" / "landscape_lens.seq"
    with pytest.warns(UserWarning, match="no RDM"):
        lens = load_lens(path)
    opm = open_model(str(path))
    theirs = opm["analysis_results"]["parax_data"].fod.efl
    assert first_order(lens, lens.wavelengths.primary_nm).efl_mm == pytest.approx(theirs, rel=1e-6)
