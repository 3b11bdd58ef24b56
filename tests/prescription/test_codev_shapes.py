"""CODE V special surfaces (``SPS ODD``, ``XYP``, ``QBF`` + ``SCO``): the same surface written in Zemax form and
CODE V form loads to the same shape and traces identically; the QBF numbering against CODE V's own listing."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import PrescriptionError
from lensrt.prescription.formats.codev import loads_seq
from lensrt.prescription.formats.zemax import loads_zmx
from lensrt.prescription.shapes import profile_of, sag_grad
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

ZMX = """VERS 1 0 0
MODE SEQ
UNIT {unit} X W X CM MR CPMM
ENPD 6
FTYP 0 0 1 1 0 0 0
YFLN 0
XFLN 0
WAVM 1 0.5876 1
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  TYPE {ztype}
  CURV 0.05
{zdata}
  DISZ 3
  GLAS ___BLANK 1 0 1.5168 64.17 0 0 0 0 0 0
SURF 2
  CURV -0.02
  DISZ 20
SURF 3
"""
SEQ = """RDM NO
DIM {dim}
EPD 6
YAN 0
WL 587.6
SO 0 1e11
S 0.05 3 1.5168:64.17
  STO
{cdata}
S -0.02 20
SI 0 0
GO
"""
# (Zemax type, Zemax lines, CODE V lines): the same surface
CASES = {
    "odd": ("ODDASPHE", "  CONI -0.5\n  PARM 1 1e-3\n  PARM 3 2e-4\n  PARM 5 -3e-6\n  PARM 8 -1e-9",
            "  SPS ODD 0\n  SCO K -0.5; SCO AR1 1e-3\n  SCO AR3 2e-4 C6 -3e-6\n  SCO AR8 -1e-9\n  SCC C1 100"),
    "xy": ("XPOLYNOM", "  CONI 0.3\n  XDAT 1 12\n  XDAT 2 4\n  XDAT 4 2e-3\n  XDAT 5 -1e-2\n  XDAT 7 4e-3\n"
                       "  XDAT 9 -2e-3\n  XDAT 14 5e-4",
           "  SPS XYP 4\n  SCO K 0.3\n  SCO C3 2e-3; SCO C4 -1e-2\n  SCO C6 4e-3 C8 -2e-3\n  SCO C13 5e-4\n"
           "  SCO NRADIUS 4"),
    "qbfs": ("QED_TYPE", "  XDAT 1 0\n  XDAT 2 4\n  XDAT 3 3.5\n  XDAT 4 0.02\n  XDAT 5 -0.004\n  XDAT 6 1e-3\n"
                         "  XDAT 7 -2e-4",
             "  SPS QBF\n  SCO NRADIUS 3.5 QB4 0.02\n  SCO QB6 -0.004; SCO C5 1e-3\n  SCO QB10 -2e-4"),
}


def _load(text: str, reader):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the y-section first-order warning of the XY surface
        return reader(text, "case")


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("unit,dim", [("MM", "M"), ("IN", "I")])
def test_codev_and_zemax_forms_trace_identically(name: str, unit: str, dim: str) -> None:
    ztype, zdata, cdata = CASES[name]
    z = _load(ZMX.format(unit=unit, ztype=ztype, zdata=zdata), loads_zmx)
    c = _load(SEQ.format(dim=dim, cdata=cdata), loads_seq)
    sz, sc = z.surfaces[0], c.surfaces[0]
    assert sc.shape is not None and sc.shape.kind == name
    assert sc.conic == sz.conic and sc.asphere == sz.asphere
    assert sc.shape.coefficients == pytest.approx(sz.shape.coefficients, rel=1e-15, abs=0.0)
    assert sc.shape.norm_radius_mm == pytest.approx(sz.shape.norm_radius_mm, rel=1e-15)
    # skew rays over the aperture, float64 reference tracer: the same intersections to 1e-12 mm
    f = 25.4 if unit == "IN" else 1.0
    n = 0
    for x in np.linspace(-2.8, 2.8, 7) * f:
        for y in np.linspace(-2.8, 2.8, 7) * f:
            o, d = (float(x), float(y), -1.0), (0.03, -0.05, float(np.sqrt(1 - 0.03 ** 2 - 0.05 ** 2)))
            rz, rc = trace_reference(z, o, d, 587.6, clip=False), trace_reference(c, o, d, 587.6, clip=False)
            assert (rz.status, rz.surface) == (rc.status, rc.surface)
            if rz.status != OK:
                continue
            n += 1
            hz = np.array([[h.x_mm, h.y_mm, h.z_mm, h.L, h.M, h.N] for h in rz.hits])
            hc = np.array([[h.x_mm, h.y_mm, h.z_mm, h.L, h.M, h.N] for h in rc.hits])
            assert np.max(np.abs(hz - hc)) < 1e-12
    assert n >= 30


def _listing(name: str) -> str:
    ro = pytest.importorskip("rayoptics")
    return (Path(ro.__file__).parent / "codev" / "tests" / name).read_text()


def test_qbf_numbering_matches_codev_listing_of_the_same_mirror() -> None:
    """CODE V 10.8 lists one mirror of a three-mirror telescope twice: as SPS QBF (NRADIUS, QB4 .. QB14) and as a
    conic + ASP surface. Read through lensrt's SPS QBF (QB4 = a_0, ...), the two sags agree to the listing's 5
    significant figures over the mirror's off-axis footprint (r <= 185 mm); QB4 read as a_1, or with the other
    sign, misses by more than 0.04 mm."""
    qbf, asp = _listing("threemrc_qbfs.lis"), _listing("threemrc.lis")
    radius = float(re.search(r"5:\s+(-?[\d.]+)\s+-321", qbf).group(1))
    vals = dict(re.findall(r"(NRADIUS|QB\d+):\s*(-?[\d.E+-]+)", qbf))
    block = re.search(r"5:\s+(-?[\d.]+)\s+-321.*?K\s*:\s*(-?[\d.]+).*?A\s*:\s*(-?[\d.E+-]+)", asp, re.S)
    c, k, a4 = 1.0 / float(block.group(1)), float(block.group(2)), float(block.group(3))

    def worst_sag_difference(coefficients: dict[str, str]) -> float:
        sco = "\n".join(f"  SCO {name} {v}" for name, v in coefficients.items())
        seq = f"RDM\nEPD 100\nYAN 0\nWL 500\nSO 0 1e11\nS {radius} -300 REFL\n  STO\n  SPS QBF\n{sco}\nSI 0 0\nGO\n"
        surf = loads_seq(seq, "qbf.seq").surfaces[0]
        assert surf.shape.kind == "qbfs"
        prof = profile_of(surf)
        r = np.linspace(0.0, 185.0, 38)
        z_asp = c * r * r / (1 + np.sqrt(1 - (1 + k) * c * c * r * r)) + a4 * r ** 4
        return max(abs(sag_grad(prof, float(ri), 0.0)[0] - zi) for ri, zi in zip(r, z_asp))

    assert len(vals) == 7
    assert worst_sag_difference(vals) < 3e-5
    shifted = {(f"QB{int(n[2:]) + 2}" if n.startswith("QB") else n): v for n, v in vals.items()}
    flipped = {n: (v if n == "NRADIUS" else str(-float(v))) for n, v in vals.items()}
    assert worst_sag_difference(shifted) > 0.04 and worst_sag_difference(flipped) > 0.04


@pytest.mark.parametrize("cdata,needle", [
    ("  SPS QCN 0", "SPS QCN: a Forbes Q\\^con asphere is not supported"),
    ("  SPS ZRN", "SPS ZRN: a Zernike polynomial surface is not supported"),
    ("  SPS FOO", "special surface type 'FOO' is not supported"),
    ("  SCO C3 1", "SCO before SPS"),
    ("  SPS ODD 0\n  SCO C40 1", "SCO C40: not a coefficient"),
    ("  SPS ODD 0\n  SCO C32 1", "SCO C32: not a coefficient"),
    ("  SPS XYP 0\n  SCO C67 1", "SCO C67: not a coefficient"),
    ("  SPS ODD 5\n  SCO AR3 1e-4", "only 0 or 1"),
    ("  SPS QBF\n  SCO NRADIUS 3 C2 0.1", "SCO C2 = 0.1 on an SPS QBF"),
    ("  SPS QBF\n  SCO K 0.1", "SCO K: not a coefficient"),
    ("  SPS QBF\n  SCO QB4 0.1", "NRADIUS 0"),
    ("  SPS XYP 4\n  SCO NRADIUS 5", "gave NRADIUS 4"),
    ("  SPS XYP\n  SCO C3", "cannot read SCO C3"),
    ("  SPS XYP\n  SCO C3 abc", "'abc': not a number"),
    ("  K -1\n  SPS ODD 0\n  SCO AR3 1e-4", "also has ASP/CON"),
    ("  SPS ODD 0\n  SPS XYP 0", "a second SPS"),
])
def test_bad_special_surface_is_one_error(cdata: str, needle: str) -> None:
    with pytest.raises(PrescriptionError, match=needle) as err:
        loads_seq(SEQ.format(dim="M", cdata=cdata), "bad.seq")
    assert str(err.value).startswith("bad.seq:") and "\n" not in str(err.value)


@pytest.mark.parametrize("after,needle", [("SI 0 0", "SPS without a surface"), ("SO 0 1e11", "SPS on the object")])
def test_special_surface_on_object_or_image_is_refused(after: str, needle: str) -> None:
    with pytest.raises(PrescriptionError, match=needle):
        loads_seq(SEQ.format(dim="M", cdata="").replace(after, after + "\n  SPS ODD 0"), "bad.seq")
