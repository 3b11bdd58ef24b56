"""Zemax surface types beyond STANDARD/EVENASPH: ODDASPHE, XOSPHERE, XASPHERE, QED_TYPE, BICONICX, TOROIDAL,
XPOLYNOM, SZERNSAG, FZERNSAG."""
from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from test_zemax import zmx

from lensrt.errors import PrescriptionError
from lensrt.paraxial.first_order import first_order
from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.formats.zemax import loads_zmx
from lensrt.prescription.shapes import SurfaceShape


def _rayoptics_file(name: str) -> Path:
    ro = pytest.importorskip("rayoptics")
    return Path(ro.__file__).parent / "zemax" / "tests" / name


def _read(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_lens(path)


@pytest.mark.parametrize("unit,f", [("MM", 1.0), ("IN", 25.4)])
def test_types_read_with_units(unit: str, f: float) -> None:
    odd = loads_zmx(zmx(unit, "ODDASPHE", "PARM 1 1e-3\n  PARM 3 2e-4\n  PARM 8 -1e-9"))
    s = odd.surfaces[0]
    assert s.shape.kind == "odd" and s.shape.norm_radius_mm == 1.0
    want = [1e-3, 0.0, 2e-4 * f ** -2, 0, 0, 0, 0, -1e-9 * f ** -7]
    assert s.shape.coefficients == pytest.approx(want, rel=1e-15)
    q = loads_zmx(zmx(unit, "QED_TYPE", "XDAT 1 1\n  XDAT 2 3\n  XDAT 3 12\n  XDAT 4 0.1\n  XDAT 5 -0.02\n"
                                        "  XDAT 6 0.003")).surfaces[0].shape
    assert q == SurfaceShape("qcon", tuple(v * f for v in (0.1, -0.02, 0.003)), 12 * f)
    x = loads_zmx(zmx(unit, "XASPHERE", "XDAT 1 2\n  XDAT 2 10\n  XDAT 3 0.5\n  XDAT 4 -0.1")).surfaces[0].shape
    assert x == SurfaceShape("odd", (0.0, 0.5 * f, 0.0, -0.1 * f), 10 * f)
    xo = loads_zmx(zmx(unit, "XOSPHERE", "XDAT 1 3\n  XDAT 2 10\n  XDAT 5 0.25")).surfaces[0].shape
    assert xo == SurfaceShape("odd", (0.0, 0.0, 0.25 * f), 10 * f)
    b = loads_zmx(zmx(unit, "BICONICX", "PARM 1 40\n  PARM 2 -0.5")).surfaces[0].shape
    assert b.curvature_x_per_mm == pytest.approx(1 / (40 * f), rel=1e-15) and b.conic_x == -0.5
    with pytest.warns(UserWarning, match="not rotationally symmetric"):
        t = loads_zmx(zmx(unit, "TOROIDAL", "PARM 0 0\n  PARM 1 -80\n  PARM 2 1e-3\n  PARM 3 1e-5")).surfaces[0]
    assert t.shape.curvature_x_per_mm == pytest.approx(-1 / (80 * f), rel=1e-15)
    assert t.asphere == pytest.approx((1e-3 / f, 1e-5 * f ** -3), rel=1e-15)
    with pytest.warns(UserWarning, match="not rotationally symmetric"):
        xy = loads_zmx(zmx(unit, "XPOLYNOM", "XDAT 1 5\n  XDAT 2 8\n  XDAT 3 1e-3\n  XDAT 7 -2e-3")).surfaces[0]
    assert xy.shape == SurfaceShape("xy", (1e-3 * f, 0.0, 0.0, 0.0, -2e-3 * f), 8 * f)
    with pytest.warns(UserWarning, match="not rotationally symmetric"):
        z = loads_zmx(zmx(unit, "SZERNSAG", "PARM 2 1e-6\n  XDAT 1 4\n  XDAT 2 8\n  XDAT 6 0.01")).surfaces[0]
    assert z.shape == SurfaceShape("zernike", (0.0, 0.0, 0.0, 0.01 * f), 8 * f)
    assert z.asphere == pytest.approx((0.0, 1e-6 * f ** -3), rel=1e-15)
    with pytest.warns(UserWarning, match="not rotationally symmetric"):
        fz = loads_zmx(zmx(unit, "FZERNSAG", "PARM 3 2e-9\n  XDAT 1 9\n  XDAT 2 75\n  XDAT 3 1e-6\n"
                                             "  XDAT 11 -3e-7")).surfaces[0]
    assert fz.shape == SurfaceShape("zernike_fringe", (1e-6 * f,) + (0.0,) * 7 + (-3e-7 * f,), 75 * f)
    assert fz.asphere == pytest.approx((0.0, 0.0, 2e-9 * f ** -5), rel=1e-15)


@pytest.mark.parametrize("type1,extra,needle", [
    ("QED_TYPE", "XDAT 1 2", "type 0 \\(Qbfs\\) or 1 \\(Qcon\\)"),
    ("QED_TYPE", "XDAT 2 2\n  XDAT 3 10\n  XDAT 7 0.1", "XDAT 7 = 0.1 on a QED_TYPE surface"),
    ("QED_TYPE", "XDAT 2 2.5", "whole number"),
    ("QED_TYPE", "XDAT 2 2\n  XDAT 3 0\n  XDAT 4 1", "normalisation radius"),
    ("ODDASPHE", "PARM 9 1e-3", "PARM 9 = 0.001 on a ODDASPHE"),
    ("TOROIDAL", "PARM 1 50\n  XDAT 1 1\n  XDAT 2 5\n  XDAT 3 0.2", "XDAT 3 = 0.2 on a TOROIDAL"),
    ("BICONICX", "PARM 3 1", "PARM 3 = 1 on a BICONICX"),
    ("XASPHERE", "XDAT 1 1\n  XDAT 2 10\n  XDAT 3 1e308\n  XDAT 400 1", "extra data numbers"),
    ("STANDARD", "XDAT 1 1", "not supported for STANDARD"),
    ("SZERNSAG", "PARM 9 0.5", "PARM 9 = 0.5 on a SZERNSAG"),
    ("FZERNSAG", "PARM 10 0.5", "PARM 10 = 0.5 on a FZERNSAG"),
    ("FZERNSAG", "XDAT 1 38\n  XDAT 2 10", "at most 37 fringe Zernike terms"),
    ("XPOLYNOM", "XDAT 1 70\n  XDAT 2 1", "whole number 0..66"),
])
def test_bad_shape_data_is_one_error(type1: str, extra: str, needle: str) -> None:
    with pytest.raises(PrescriptionError, match=needle) as err:
        loads_zmx(zmx("MM", type1, extra), "bad.zmx")
    assert str(err.value).startswith("bad.zmx:") and "\n" not in str(err.value)


def test_thorlabs_qbfs_asphere_has_its_catalogue_focal_length() -> None:
    """Thorlabs ASL5040-UV (the vendor's own .zmx, shipped with rayoptics): a Q^bfs asphere (QED_TYPE 0) with a
    conic. Its catalogue focal length is 40 mm (at the file's 405 nm); the vertex curvature includes the Q^bfs
    r^2 part -- the base conic alone gives 37.0 mm, which is what a reader that drops the Q terms reports."""
    lens = _read(_rayoptics_file("ASL5040-UV-Zemax(ZMX).zmx"))
    s = lens.surfaces[0]
    assert s.shape.kind == "qbfs" and len(s.shape.coefficients) == 6 and s.shape.norm_radius_mm == 27.0
    assert first_order(lens).efl_mm == pytest.approx(40.0, rel=1e-4)
    assert first_order(lens.replace_surface(0, shape=None)).efl_mm == pytest.approx(37.0, rel=1e-3)
    again = loads_native(dumps_native(lens))
    assert again.surfaces == lens.surfaces


def test_toroidal_mirror_first_order_matches_rayoptics(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Handbook of Optics V2 C18 Ex46: a toroidal mirror behind tilted mirrors; rayoptics' paraxial EFL (its
    y-toroid's y-section) equals lensrt's, and lensrt warns that first-order data are the y-section's."""
    path = _rayoptics_file("HoO-V2C18Ex46.zmx")
    monkeypatch.chdir(tmp_path)  # rayoptics writes its reader log into the working folder
    from rayoptics.environment import open_model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        efl_ro = open_model(str(path))["analysis_results"]["parax_data"].fod.efl
    lens = _read(path)
    tor = [s for s in lens.surfaces if s.shape is not None]
    assert len(tor) == 1 and tor[0].shape.kind == "toroidal" and tor[0].mirror
    assert tor[0].shape.curvature_x_per_mm == pytest.approx(1 / 1035.0, rel=1e-15)
    assert "first_order_y_section" in [w.code for w in lens.warnings]
    assert first_order(lens).efl_mm == pytest.approx(efl_ro, rel=1e-9)


def test_fringe_telescope_reads_the_fringe_terms_the_surface_tilt_and_the_dummy() -> None:
    """tests/data/fringe_telescope.zmx: a FZERNSAG parabolic mirror (F_5 = 1e-4 mm astigmatism, F_9 = -5e-5 mm
    spherical over R_n = 30 mm) with ``SCBD 1 0 0 0 0 0.01 0.005 0`` (tilts in degrees), a plane dummy 0 mm after
    it (inside the mirror's sag: a warning) and a lens in ``SF12?``. The y-section's paraxial curvature is the
    closed form c + 2 a_2 with a_2 = (-A_5 - 6 A_9) / R_n^2 (F_5 = rho^2 cos 2 theta is -rho^2 on the y axis,
    F_9 = 6 rho^4 - 6 rho^2 + 1)."""
    import math
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from lensrt.loading import load_lens
        lens = load_lens(Path(__file__).resolve().parents[1] / "data" / "fringe_telescope.zmx")
    m = lens.surfaces[0]
    assert m.mirror and m.shape == SurfaceShape("zernike_fringe", (0.0,) * 4 + (1e-4, 0.0, 0.0, 0.0, -5e-5), 30.0)
    t = m.transform_before
    assert (t.tilt_x_rad, t.tilt_y_rad, t.tilt_z_rad, t.order) == (math.radians(0.01), math.radians(0.005), 0.0, 0)
    assert m.paraxial_curvature_per_mm == pytest.approx(-0.0025 + 2 * (-1e-4 + 6 * 5e-5) / 900.0, rel=1e-12)
    codes = {w.code for w in lens.warnings}
    assert {"dummy_crossing", "glass_uncertain_name", "first_order_y_section"} <= codes
    assert lens.surfaces[2].material.name == "SF12"


def test_fringe_telescope_round_trips_through_the_native_format() -> None:
    """``lensrt lens convert`` writes the fringe shape, the surface tilt, the mirror and the dummy exactly."""
    lens = _read(Path(__file__).resolve().parents[1] / "data" / "fringe_telescope.zmx")
    again = loads_native(dumps_native(lens))
    assert again.surfaces == lens.surfaces
