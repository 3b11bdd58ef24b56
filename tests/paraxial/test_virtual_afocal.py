"""Virtual images and afocal lenses (issue 25, item 3): what loads, what first-order data say, what is refused.

Oracles: the thick-lens closed form (Field Guide p. 4-6) for a plano-concave singlet whose file puts the image
surface at its virtual focus; the float64 reference tracer, whose near-axis rays extended backwards meet the
axis at the paraxial virtual image; the Keplerian telescope's angular magnification -f1/f2; Thorlabs' stated
focal lengths of the corpus's negative achromats.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lensrt.cli import main
from lensrt.errors import LensrtError, PrescriptionError
from lensrt.loading import load_lens
from lensrt.paraxial import first_order
from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.trace.reference import trace_reference

CORPUS = Path(__file__).resolve().parents[1] / "data" / "corpus"
N_GLASS = 1.5
R_MM = -40.0  # concave front, plane back: f = R / (n - 1) = -80 mm
T_MM = 3.0


def _plano_concave(last_thickness_mm: float) -> Lens:
    surfaces = (Surface(curvature_per_mm=1.0 / R_MM, thickness_mm=T_MM, material=ConstantIndex(N_GLASS),
                        is_stop=True, semi_diameter_mm=6.0),
                Surface(curvature_per_mm=0.0, thickness_mm=last_thickness_mm, semi_diameter_mm=6.0))
    return Lens(surfaces=surfaces, aperture=Aperture("epd", 8.0), fields=Fields("angle", (0.0, math.radians(2.0))),
                wavelengths=Wavelengths((587.5618,)), name="plano-concave")


def _closed_form() -> tuple[float, float]:
    """EFL and BFL of the singlet: Phi = Phi1 (a plane back has no power), BFL = f - t/n (p. 4-6)."""
    f = R_MM / (N_GLASS - 1.0)
    return f, f - T_MM / N_GLASS


def test_image_surface_at_the_virtual_focus_loads_with_the_closed_form() -> None:
    f, bfl = _closed_form()
    lens = load_lens(_plano_concave(bfl))
    fo = first_order(lens)
    assert fo.efl_mm == pytest.approx(f, rel=1e-14)
    assert fo.bfl_mm == pytest.approx(bfl, rel=1e-14)
    assert fo.image_virtual and fo.image_distance_mm == pytest.approx(bfl, rel=1e-14)
    assert fo.image_z_mm == pytest.approx(T_MM + bfl, rel=1e-14)


def test_real_rays_extended_backwards_meet_at_the_virtual_image() -> None:
    """Rays reach the image plane in front of the last surface (a backward transfer) and land on the axis
    there, to third order in the ray height (spherical aberration ~ h^2)."""
    f, bfl = _closed_form()
    lens = load_lens(_plano_concave(bfl))
    z_img = lens.image_z_mm
    spots = []
    for h in (0.05, 0.1):
        ray = trace_reference(lens, (0.0, h, -10.0), (0.0, 0.0, 1.0), 587.5618)
        assert ray.status == 0 and ray.z_mm == pytest.approx(z_img, abs=1e-12)
        spots.append(ray.y_mm)
    # the transverse aberration at the paraxial focus grows as h^3 and is far below the ray height
    assert abs(spots[0]) < 1e-5 and spots[1] / spots[0] == pytest.approx(8.0, rel=0.01)


def test_negative_last_thickness_with_a_real_image_is_refused() -> None:
    """A converging lens whose last thickness is negative: the image is real, so the file is wrong."""
    surfaces = (Surface(curvature_per_mm=1.0 / 40.0, thickness_mm=T_MM, material=ConstantIndex(N_GLASS),
                        is_stop=True, semi_diameter_mm=6.0),
                Surface(curvature_per_mm=0.0, thickness_mm=-20.0, semi_diameter_mm=6.0))
    lens = Lens(surfaces=surfaces, aperture=Aperture("epd", 8.0))
    with pytest.raises(PrescriptionError, match=r"in front of the last surface, but the paraxial image is real"):
        load_lens(lens)


@pytest.mark.parametrize("name, stated_mm", [("ACN127-050-A.zmx", -50.0), ("ACN254-050-A.zmx", -50.0),
                                             ("ACN254-100-B.zmx", -100.0)])
def test_thorlabs_negative_achromats_load_as_virtual_images(name: str, stated_mm: float) -> None:
    fo = first_order(load_lens(CORPUS / name))
    assert fo.efl_mm == pytest.approx(stated_mm, rel=0.01)
    assert fo.image_virtual and fo.image_distance_mm < 0.0


def test_info_says_virtual_image_and_psf_refuses_in_one_line(capsys) -> None:
    path = str(CORPUS / "ACN127-050-A.zmx")
    assert main(["info", path]) == 0
    out = capsys.readouterr().out
    assert "virtual image" in out and "diverging lens, EFL -50.01 mm" in out
    assert main(["info", path, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["image_virtual"] is True and d["efl_mm"] == pytest.approx(-50.0, rel=0.01)
    assert main(["psf", path, "--out", "unused-dir-never-written"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "virtual image" in err[0] and "not defined" in err[0]
    assert not Path("unused-dir-never-written").exists()


def _kepler(f1_mm: float, f2_mm: float) -> Lens:
    """Two plano-convex lenses (n = 1.5, curved side first, so each one's power sits at its front vertex):
    afocal when the first's rear focal point F1' (f1 - t/n behind its plane face) is the second's front
    focal point (f2 in front of its curved face); angular magnification -f1/f2."""
    def plano_convex(f: float, gap: float, stop: bool) -> tuple[Surface, Surface]:
        return (Surface(curvature_per_mm=1.0 / ((N_GLASS - 1.0) * f), thickness_mm=T_MM,
                        material=ConstantIndex(N_GLASS), is_stop=stop, semi_diameter_mm=8.0),
                Surface(curvature_per_mm=0.0, thickness_mm=gap, semi_diameter_mm=8.0))
    gap = f1_mm - T_MM / N_GLASS + f2_mm
    return Lens(surfaces=plano_convex(f1_mm, gap, True) + plano_convex(f2_mm, 30.0, False),
                aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0, math.radians(1.0))),
                wavelengths=Wavelengths((587.5618,)), name="Kepler")


def test_afocal_telescope_reports_angular_magnification(tmp_path: Path, capsys) -> None:
    lens = _kepler(100.0, 25.0)
    fo = first_order(lens)
    assert fo.afocal and math.isinf(fo.efl_mm)
    assert fo.angular_magnification == pytest.approx(-4.0, rel=1e-6)
    assert fo.pupil_magnification == pytest.approx(0.25, rel=1e-6)
    from lensrt.prescription.formats.native import dumps_native
    path = tmp_path / "kepler.toml"
    path.write_text(dumps_native(lens))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "afocal: angular magnification -4" in out
    assert main(["info", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["afocal"] is True and d["angular_magnification"] == pytest.approx(-4.0, rel=1e-6)
    assert d["efl_mm"] is None and d["warnings"] == []  # inf is null in JSON
    assert np.isfinite(d["exit_pupil_z_mm"])


def test_image_plane_analyses_refuse_an_afocal_lens_in_one_line(tmp_path: Path, capsys) -> None:
    from lensrt.prescription.formats.native import dumps_native
    path = tmp_path / "kepler.toml"
    path.write_text(dumps_native(_kepler(100.0, 25.0)))
    for argv in (["psf", str(path), "--out", str(tmp_path / "o")], ["bokeh", str(path), "--out", str(tmp_path / "o")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "afocal (angular magnification -4)" in err[0], err
    assert not (tmp_path / "o").exists()


def _ideal_pair(f1_mm: float, f2_mm: float) -> Lens:
    """Two ideal lenses f1 + f2 apart: a perfect afocal system of angular magnification -f1/f2."""
    return Lens(surfaces=(Surface(thickness_mm=f1_mm + f2_mm, ideal_focal_mm=f1_mm, is_stop=True, semi_diameter_mm=8.0),
                          Surface(thickness_mm=20.0, ideal_focal_mm=f2_mm, semi_diameter_mm=8.0)),
                aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0, math.radians(2.0))),
                wavelengths=Wavelengths((587.5618,)), name="ideal pair")


def test_angular_spots_of_a_perfect_afocal_pair_vanish() -> None:
    from lensrt.analysis.compare.afocal import angular_spots
    lens = load_lens(_ideal_pair(100.0, 25.0))
    assert first_order(lens).angular_magnification == pytest.approx(-4.0, rel=1e-15)
    spots = angular_spots(lens, device="cpu")
    assert [s.rays for s in spots] == [spots[0].rays] * 2 and spots[0].rays > 300
    for s in spots:
        assert s.max_mrad < 1e-9  # every ray of a field leaves parallel to its chief ray
        assert s.chief_exit_deg == pytest.approx(s.paraxial_exit_deg, abs=1e-12)  # tan theta' = M tan theta exactly


def test_compare_prints_angular_spots_for_a_real_telescope(tmp_path: Path, capsys) -> None:
    from lensrt.prescription.formats.native import dumps_native
    small = math.radians(0.01)
    path = tmp_path / "kepler.toml"
    path.write_text(dumps_native(_kepler(100.0, 25.0).replace(fields=Fields("angle", (0.0, small)))))
    assert main(["compare", str(path), "--json", "--device", "cpu"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["afocal"] is True and d["angular_magnification"] == pytest.approx(-4.0, rel=1e-6)
    axial, off = d["angular_spots"]
    assert axial["rms_mrad"] > 0.0  # the singlets' spherical aberration: a real telescope is not perfect
    # near the axis the real chief ray follows the paraxial angular magnification
    assert math.tan(math.radians(off["chief_exit_deg"])) / math.tan(small) == pytest.approx(-4.0, rel=1e-3)
    assert main(["compare", str(path), "--device", "cpu"]) == 0
    assert "spots in angle space" in capsys.readouterr().out


def test_afocal_lens_images_a_finite_object_with_magnification_one_over_m() -> None:
    """An afocal system has the same lateral magnification 1/M at every conjugate; real rays through the
    perfect ideal pair meet at the paraxial image point (float64 reference tracer)."""
    d_obj = 500.0
    lens = load_lens(_ideal_pair(100.0, 25.0).replace(object_distance_mm=d_obj,
                                                     fields=Fields("object_height", (0.0, 10.0))))
    fo = first_order(lens)
    assert fo.afocal and fo.magnification == pytest.approx(-0.25, rel=1e-14)
    assert math.isfinite(fo.image_z_mm) and fo.field_image_heights_mm[1] == pytest.approx(-2.5, rel=1e-12)
    at_image = lens.replace_surface(lens.n_surfaces - 1, thickness_mm=fo.image_distance_mm)
    for y0 in (0.0, 10.0):
        for py in (-4.0, 0.5, 4.5):
            d = np.array([0.0, py - y0, d_obj])
            ray = trace_reference(at_image, (0.0, y0, -d_obj), d / np.linalg.norm(d), 587.5618, clip=False)
            assert ray.status == 0 and abs(ray.y_mm + 0.25 * y0) < 1e-9
