"""Zemax constructs of issue 25's independent set: a model glass with V_d = 0 (a constant index, below 1 for a gas
relative to air) and a SURF number that skips some."""
from __future__ import annotations

import warnings

import pytest

from test_zemax import zmx

from lensrt.errors import PrescriptionError
from lensrt.paraxial.first_order import first_order
from lensrt.prescription.formats.zemax import loads_zmx
from lensrt.prescription.materials import ConstantIndex


def _load(text: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return loads_zmx(text, "t.zmx")


def test_model_glass_with_zero_abbe_number_is_a_constant_index() -> None:
    """``GLAS ___BLANK 1 0 1.56029 0``: no dispersion. The EFL of the singlet is then the thick-lens closed form
    at every wavelength; an index below 1 (0.999712: helium relative to air in a 193 nm lithography lens) is taken
    only with V_d = 0, as a relative index."""
    lens = _load(zmx(extra1="").replace("GLAS N-BK7 0 0 1.5168 64.17", "GLAS ___BLANK 1 0 1.56029 0 0 0 0 0 0 0"))
    m = lens.surfaces[0].material
    assert isinstance(m, ConstantIndex) and m.n == 1.56029
    assert {w.code for w in lens.warnings} == {"glass_model"} and "no dispersion" in lens.warnings[0].text
    n, c1, c2, t = 1.56029, 0.02, -0.02, 5.0
    phi = (n - 1) * (c1 - c2) + (n - 1) ** 2 * t * c1 * c2 / n  # thick lens (Hecht 6.2)
    for wl in (450.0, 550.0, 700.0):
        assert first_order(lens, wavelength_nm=wl).efl_mm == pytest.approx(1 / phi, rel=1e-12)
    gas = _load(zmx(extra1="").replace("GLAS N-BK7 0 0 1.5168 64.17", "GLAS ___BLANK 1 0 0.999712 0 0 0 0 0 0 0"))
    assert gas.surfaces[0].material.n == 0.999712 and "relative to air" in gas.warnings[0].text
    for bad in ("GLAS ___BLANK 1 0 0.999712 30 0 0 0 0 0 0", "GLAS ___BLANK 1 0 0.3 0 0 0 0 0 0 0",
                "GLAS ___BLANK 1 0 1.5 -3 0 0 0 0 0 0"):
        with pytest.raises(PrescriptionError, match="a model glass needs n_d >= 1 and V_d > 0"):
            loads_zmx(zmx(extra1="").replace("GLAS N-BK7 0 0 1.5168 64.17", bad), "t.zmx")


def test_a_skipped_surface_number_in_air_reads_as_the_next_surface() -> None:
    """``SURF 3`` -> ``SURF 5`` after a surface in air (the image here): the same lens, with a warning; after a
    surface in glass, or going backwards, an error."""
    plain = _load(zmx())
    gapped = _load(zmx().replace("SURF 3\n", "SURF 5\n"))
    assert gapped.surfaces == plain.surfaces
    assert [w.code for w in gapped.warnings if w.code == "surface_numbering"] == ["surface_numbering"]
    with pytest.raises(PrescriptionError, match="SURF 7 out of order .*medium is not air"):
        loads_zmx(zmx().replace("SURF 2\n", "SURF 7\n"), "t.zmx")  # after SURF 1, which is in N-BK7
    with pytest.raises(PrescriptionError, match="SURF 1 out of order \\(expected SURF 2\\)"):
        loads_zmx(zmx().replace("SURF 2\n", "SURF 1\n"), "t.zmx")


def test_variable_conic_flag_is_ignored_on_purpose() -> None:
    """``VCON`` (the conic is an optimisation variable, in YuryStrelkov/ZemaxUtils' files): no optics, no warning."""
    lens = _load(zmx(extra1="CONI -0.5\n  VCON"))
    assert lens.surfaces[0].conic == -0.5 and lens.warnings == ()


def test_automatic_semi_diameter_inside_an_annular_clap_gives_way_to_the_clap() -> None:
    """``DIAM 3 0`` (automatic) with ``CLAP 4 9``: clipping at 3 mm would stop everything the annulus passes
    (YuryStrelkov/ZemaxUtils' primary mirrors: DIAM 72.5, CLAP 85 180); the semi-diameter is the CLAP's 9 mm, with a
    warning. A user-defined DIAM (flag 1) or one that overlaps the annulus is kept."""
    lens = _load(zmx(extra1="DIAM 3 0 0 0 1 \"\"\n  CLAP 4 9 0"))
    s = lens.surfaces[0]
    assert s.semi_diameter_mm == 9.0 and (s.apertures[0].shape, s.apertures[0].a, s.apertures[0].b) == ("annulus", 9.0, 4.0)
    assert [w.code for w in lens.warnings] == ["semi_diameter_from_clap"]
    for diam, want in (("DIAM 3 1 0 0 1 \"\"", 3.0), ("DIAM 6 0 0 0 1 \"\"", 6.0)):
        other = _load(zmx(extra1=f"{diam}\n  CLAP 4 9 0"))
        assert other.surfaces[0].semi_diameter_mm == want and other.warnings == ()
