"""Focusing with the lens's own mechanism (unit, focus group, floating groups), solved with real
rays, focus breathing, and the ``--config`` / ``info --config all`` / ``info --breathing`` CLI.

Oracles: the real best focus (analysis.focus.best_focus, an independent closed-form
minimum over a ray grid) of the focused lens lies on its image surface; a floating
table built from two solved focus-group positions is solved back to the tabulated
distance (the object distance in focus within 1e-6 relative); the unit-focus
formula column equals the Field Guide formula; gaps move by exactly sign x travel.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from lensrt.analysis.compare.focus import best_focus
from lensrt.analysis.focusing import focus_at, focus_breathing, move_mechanism
from lensrt.cli import main
from lensrt.errors import PrescriptionError
from lensrt.loading import load_lens
from lensrt.paraxial import first_order
from lensrt.paraxial.photographic import focus_breathing_afov_rad
from lensrt.prescription.focusing import FocusMechanism
from lensrt.prescription.formats.native import dumps_native, loads_native

SEQ = Path(__file__).resolve().parents[1] / "data" / "ag_dblgauss_zoom.seq"


@pytest.fixture(scope="module")
def lens():
    return load_lens()


def _rear_group(lens):
    """The default double Gauss focused by its rear group (the gap after the stop and the image gap)."""
    return lens.replace(focus=FocusMechanism("group", (lens.stop_index, lens.n_surfaces - 1), (1.0, -1.0)))


def _on_sensor(sol) -> float:
    return best_focus(sol.lens, [sol.lens.wavelengths.primary_nm], [1.0], 0.0).z_mm - sol.lens.image_z_mm


def test_unit_focus_puts_the_real_best_focus_on_the_sensor(lens) -> None:
    sol = focus_at(lens, 1000.0)
    assert abs(_on_sensor(sol)) < 1e-9
    inf = focus_at(lens, math.inf)
    # the extra extension for 1 m against the paraxial unit-focus extension (p. 12): the real best-focus offset
    # from the paraxial focus barely changes with distance
    e_par = first_order(lens, None, 1000.0).unit_focus_extension_mm - first_order(lens).unit_focus_extension_mm
    assert sol.travel - inf.travel == pytest.approx(e_par, rel=0.02)


def test_focus_group_moves_only_its_gaps(lens) -> None:
    g = _rear_group(lens)
    sol = focus_at(g, 1000.0)
    efl = first_order(lens).efl_mm
    assert abs(_on_sensor(sol)) < 1e-6 * efl
    k, last = lens.stop_index, lens.n_surfaces - 1
    for i, (a, b) in enumerate(zip(g.surfaces, sol.lens.surfaces)):
        if i == k:
            assert b.thickness_mm == pytest.approx(a.thickness_mm + sol.travel, abs=1e-12)
        elif i == last:
            assert b.thickness_mm == pytest.approx(a.thickness_mm - sol.travel, abs=1e-12)
        else:
            assert b.thickness_mm == a.thickness_mm
    assert sol.lens.image_z_mm == pytest.approx(g.image_z_mm, abs=1e-12)  # the sensor stays


def test_floating_table_solves_back_to_its_distance(lens) -> None:
    g = _rear_group(lens)
    far, near = focus_at(g, math.inf), focus_at(g, 1000.0)
    gaps = g.focus.gaps
    table = tuple(tuple(s.lens.surfaces[i].thickness_mm for i in gaps) for s in (far, near))
    fl = lens.replace(focus=FocusMechanism("floating", gaps, distances_mm=(math.inf, 1000.0), thickness_mm=table))
    sol = focus_at(fl, 1000.0)
    assert 1.0 / sol.travel == pytest.approx(1000.0, rel=1e-6)
    assert abs(_on_sensor(sol)) < 1e-9


def test_mechanism_errors_are_clear(lens) -> None:
    with pytest.raises(PrescriptionError, match="does not exist"):
        lens.replace(focus=FocusMechanism("group", (40,), (1.0,)))
    with pytest.raises(PrescriptionError, match="one non-zero sign per gap"):
        FocusMechanism("group", (3, 5), (1.0,))
    with pytest.raises(PrescriptionError, match="from far to near"):
        FocusMechanism("floating", (3,), distances_mm=(1000.0, math.inf), thickness_mm=((1.0,), (2.0,)))
    from lensrt.errors import LensrtError
    with pytest.raises(LensrtError, match="close the gap"):
        move_mechanism(_rear_group(lens), -10.0)


def test_native_focus_table_round_trip(lens) -> None:
    g = _rear_group(lens)
    again = loads_native(dumps_native(g))
    assert again.focus == g.focus


def test_breathing_real_beside_the_formula(lens) -> None:
    d = [math.inf, 2000.0, 1000.0]
    unit = focus_breathing(lens, d, 43.27)
    fo = first_order(lens)
    for s, a in zip(d, unit.afov_unit_formula_deg):
        assert a == pytest.approx(math.degrees(focus_breathing_afov_rad(s, fo.efl_mm, 43.27, fo.pupil_magnification)))
    real_change = unit.afov_real_deg[-1] - unit.afov_real_deg[0]
    formula_change = unit.afov_unit_formula_deg[-1] - unit.afov_unit_formula_deg[0]
    assert real_change < 0 and real_change == pytest.approx(formula_change, rel=0.1)
    group = focus_breathing(_rear_group(lens), d, 43.27)
    assert abs(group.afov_real_deg[-1] - group.afov_real_deg[0]) < abs(real_change)  # this group breathes less


def test_cli_config_all_breathing_and_bad_config(tmp_path: Path, capsys) -> None:
    assert main(["info", str(SEQ), "--config", "all", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in data["configurations"]] == ["Z1", "Z2", "Z3"] and data["current"] == "Z2"
    assert data["configurations"][1]["entrance_pupil_diameter_mm"] == pytest.approx(45.0, rel=1e-12)
    assert main(["info", str(SEQ), "--config", "Z3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["entrance_pupil_diameter_mm"] == pytest.approx(50.0)
    assert main(["info", "--breathing", "--distances-m", "inf,1", "--out", str(tmp_path), "--json"]) == 0
    capsys.readouterr()
    assert (tmp_path / "breathing.png").exists()
    assert len(json.loads((tmp_path / "breathing.json").read_text())["afov_real_deg"]) == 2
    for argv, words in ((["info", str(SEQ), "--config", "7"], "configuration 7 does not exist"),
                        (["ray", str(SEQ), "--config", "all"], "--config all is not available"),
                        (["info", "--config", "2"], "configuration 2 does not exist")):
        assert main(argv) == 2
        err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("lensrt: warning:")]
        assert len(err) == 1 and words in err[0]  # one error line (the fixture's PIM solve may add a warning)


def test_report_config_all_tabulates_every_configuration(tmp_path: Path) -> None:
    from lensrt.loading import load_configurations
    from lensrt.report import ReportOptions, build_report, section_keys
    family = load_configurations(SEQ)
    report = build_report(family, tmp_path, ReportOptions(quality="draft"),
                          skip=[k for k in section_keys() if k != "zoom"], quiet=True)
    assert not report.failed
    data = json.loads((tmp_path / "report.json").read_text())
    zoom = next(s for s in data["sections"] if s["key"] == "zoom")
    rows = zoom["data"]["configurations"]
    assert [r["name"] for r in rows] == ["Z1", "Z2", "Z3"]
    for r, lens in zip(rows, family.configurations()):
        assert r["efl_mm"] == pytest.approx(first_order(lens).efl_mm, rel=1e-12)
    assert (tmp_path / "zoom.png").exists() and (tmp_path / "breathing.png").exists()
    page = (tmp_path / "index.html").read_text()
    assert "zoom.png" in page and "breathing.png" in page



def test_cli_report_config_all_writes_one_page_with_per_configuration_mtf(tmp_path: Path) -> None:
    """``lensrt report ZOOM --config all`` (draft): exit 0, one page with the per-configuration tables (first order,
    MTF) and plots (zoom curve, MTF per configuration, breathing). Oracles: on the axis of a rotationally symmetric
    lens the sagittal and tangential MTF agree within their standard errors (z < 4.5), and each configuration's MTF
    is the one ``configuration_mtf`` (behind ``info --config all --mtf``) gives for the same seed (bit for bit)."""
    from lensrt.report import section_keys
    out = tmp_path / "rep"
    skip = [a for k in section_keys() if k not in ("lens", "zoom") for a in ("--skip", k)]
    assert main(["report", str(SEQ), "--config", "all", "--out", str(out), "--quality", "draft", "--device", "cpu",
                 "--precision", "float64", "--quiet"] + skip) == 0
    data = json.loads((out / "report.json").read_text())
    zoom = next(s for s in data["sections"] if s["key"] == "zoom")
    mtf = zoom["data"]["mtf"]
    assert [m["name"] for m in mtf] == ["Z1", "Z2", "Z3"] and mtf[1]["current"]
    for m in mtf:
        s, t = m["sagittal"][0], m["tangential"][0]  # Hy 0
        for k in range(len(m["freqs_cpmm"])):
            se = math.hypot(m["sagittal_stderr"][0][k], m["tangential_stderr"][0][k])
            assert abs(s[k] - t[k]) <= 4.5 * se + 1e-12, (m["name"], k, s[k], t[k], se)
        assert all(0.0 <= v <= 1.0 + 1e-9 for row in m["sagittal"] + m["tangential"] for v in row if v == v)
    for png in ("zoom.png", "zoom_mtf.png", "breathing.png"):
        assert (out / png).stat().st_size > 0
    page = (out / "index.html").read_text()
    assert page.count("<html") == 1 and "zoom_mtf.png" in page and "S/T" in page
    rec = next(m for m in data["monte_carlo"] if m["figure"] == "zoom_mtf.png")
    assert rec["samples"] == sum(m["samples"] for m in mtf) > 0 and rec["stderr_max"] > 0
    from lensrt.analysis.configurations import configuration_mtf
    from lensrt.loading import load_configurations
    family = load_configurations(SEQ)
    one = configuration_mtf(family, mtf[0]["freqs_cpmm"], rays=mtf[0]["rays"], device="cpu", seed=0)
    for a, b in zip(one, mtf):
        assert a["sagittal"].tolist() == b["sagittal"] and a["tangential"].tolist() == b["tangential"]


def test_info_config_all_mtf(capsys) -> None:
    """``info --config all --mtf --json``: a reference-frequency MTF block per configuration (frequencies
    10/20/40 lp/mm scaled to the format, p. 114); too few rays is one clear error."""
    assert main(["info", str(SEQ), "--config", "all", "--mtf", "--mtf-rays", "2000", "--sensor", "aps-c",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    from lensrt.analysis.psf.otf import reference_frequencies_cpmm
    from lensrt.paraxial.photographic import sensor_format
    ref = reference_frequencies_cpmm(sensor_format("aps-c").diagonal_mm)
    assert [m["name"] for m in doc["mtf"]] == ["Z1", "Z2", "Z3"]
    for m in doc["mtf"]:
        assert m["freqs_cpmm"] == pytest.approx(ref, rel=1e-15) and m["fields"] == [0.0, 0.7, 1.0]
        assert len(m["sagittal"]) == 3 and len(m["sagittal"][0]) == 3
    assert main(["info", str(SEQ), "--config", "all", "--mtf", "--mtf-rays", "10"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("lensrt: warning:")]
    assert len(err) == 1 and "--mtf-rays 10" in err[0]


def test_info_config_all_breathing_per_configuration(tmp_path: Path, capsys) -> None:
    """``info --config all --breathing``: one breathing curve per zoom position (JSON and one plot), each the
    position's own curve: its infinity AFoV is the position's real full diagonal angle, and it narrows toward 1 m."""
    assert main(["info", str(SEQ), "--config", "all", "--breathing", "--distances-m", "inf,1", "--json",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in doc["configurations"]] == ["Z1", "Z2", "Z3"]
    from lensrt.loading import load_configurations
    for c, lens in zip(doc["configurations"], load_configurations(SEQ).configurations()):
        d = c["sensor_diagonal_mm"]
        assert c["afov_unit_focus_formula_deg"][0] == pytest.approx(
            2 * math.degrees(math.atan(d / (2 * first_order(lens).efl_mm))), rel=1e-9)
        assert c["afov_real_deg"][1] < c["afov_real_deg"][0]
    assert json.loads((tmp_path / "breathing.json").read_text())["configurations"] == doc["configurations"]
    assert (tmp_path / "breathing.png").stat().st_size > 0

def test_sweep_config_all_has_a_row_per_configuration(capsys) -> None:
    assert main(["sweep", str(SEQ), "--config", "all", "--focus-distance-mm", "inf", "--f-number", "2.8",
                 "--quantity", "efl_mm", "--format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["configuration"] for r in doc["rows"]] == ["Z1", "Z2", "Z3"]
    from lensrt.loading import load_configurations
    for r, lens in zip(doc["rows"], load_configurations(SEQ).configurations()):
        assert r["efl_mm"] == pytest.approx(first_order(lens).efl_mm, rel=1e-12)


def test_render_camera_moves_the_focus_group(lens) -> None:
    """A scene's focus distance moves a declared focus group (the sensor stays), to the renderer's best focus."""
    from lensrt.render.camera import best_focus_z_mm, setup_camera
    from lensrt.render.scene.load import loads_scene
    scene = loads_scene("""
[scene]
name = "focus"
[camera]
lens = "dgauss_50mm_f2"
focus_distance = 1.0
[sensor]
format = "full-frame"
pixels = 64
[[plane]]
name = "chart"
center = [0.0, 0.0, -1.0]
size = [0.1, 0.1]
texture = "slanted_edge"
emission = { spectrum = { line_nm = 550.0 }, radiance_scale = 1.0 }
""")
    g = _rear_group(lens)
    cam = setup_camera(scene, g)
    assert cam.sensor_z_mm == pytest.approx(g.image_z_mm, abs=1e-12)
    moved = [b.thickness_mm - a.thickness_mm for a, b in zip(g.surfaces, cam.lens.surfaces)]
    assert moved[g.stop_index] == pytest.approx(-moved[-1], abs=1e-12) and moved[g.stop_index] != 0.0
    best = best_focus_z_mm(cam.lens, 1000.0, (550.0,), (1.0,))
    assert best == pytest.approx(cam.sensor_z_mm, abs=1e-6)
    unit = setup_camera(scene, lens)
    assert unit.lens == lens and unit.sensor_z_mm != pytest.approx(lens.image_z_mm, abs=1e-3)


def test_library_floating_macro_from_its_patent() -> None:
    """AF-S Micro-Nikkor 105 mm f/2.8G (US 7,218,457 B2 Example 3): the patent's infinity and 1:1 states as two
    configurations, f = 104.00 (printed to 0.01 mm) at infinity and 1:1 at close focus, and its floating table
    focusing real rays at any distance in between."""
    from lensrt.loading import load_configurations
    family = load_configurations("micro_nikkor_105mm_f2.8_floating")
    inf, close = family.configuration("infinity"), family.configuration("1:1")
    assert first_order(inf).efl_mm == pytest.approx(104.00, abs=0.005)
    assert first_order(close).magnification == pytest.approx(-1.0, abs=0.02)
    lens = family.configuration()
    assert lens.focus.kind == "floating" and [g + 1 for g in lens.focus.gaps] == [8, 13, 14, 20, 27]
    at_inf = focus_at(lens, math.inf)
    assert abs(at_inf.travel) < 1e-5  # the patent's infinity gaps are (very nearly) at the real best focus
    sol = focus_at(lens, 300.0)
    assert abs(_on_sensor(sol)) < 1e-9
    expect = lens.focus.floating_thickness_mm(sol.travel)
    assert [sol.lens.surfaces[g].thickness_mm for g in lens.focus.gaps] == pytest.approx(list(expect), abs=1e-12)
    curve = focus_breathing(lens, [math.inf, 1000.0, 300.0], 43.27)
    assert all(b < a for a, b in zip(curve.afov_real_deg, curve.afov_real_deg[1:]))  # it narrows closer in


def _rounding_sigma_mm(lens, gap_step_mm: float = 0.01, radius_step_mm: float = 0.001) -> float:
    """Standard deviation of the EFL from rounding every printed thickness and radius to its last digit
    (uniform errors of +-step/2, sigma = step / sqrt(12) each, first-order sensitivities added in quadrature):
    how closely a patent's printed data can reproduce its printed focal length."""
    e0 = first_order(lens).efl_mm
    var = 0.0
    for i, s in enumerate(lens.surfaces[:-1]):
        d = first_order(lens.replace_surface(i, thickness_mm=s.thickness_mm + 1e-4)).efl_mm - e0
        var += (d / 1e-4 * gap_step_mm) ** 2 / 12.0
        if s.curvature_per_mm:
            r = 1.0 / s.curvature_per_mm + 1e-4
            d = first_order(lens.replace_surface(i, curvature_per_mm=1.0 / r)).efl_mm - e0
            var += (d / 1e-4 * radius_step_mm) ** 2 / 12.0
    return math.sqrt(var)


def _check_stated_efl(lens, stated_mm: float) -> None:
    """|EFL - stated| within the printed f's half digit plus 3 sigma of the printed data's rounding."""
    efl = first_order(lens).efl_mm
    assert abs(efl - stated_mm) <= 0.005 + 3.0 * _rounding_sigma_mm(lens), (stated_mm, efl)


def test_library_standard_zoom_from_its_patent() -> None:
    """Canon RF 24-70 mm f/2.8 (US 2019/0278068 A1 Example 5): f = 24.72 / 44.86 / 67.89 mm and 2w = 82.4 / 35.4 deg
    at the patent's printed precision (0.005 mm on f plus 3 sigma of the printed gaps' and radii's rounding), and its focus
    group (L6, rearward) focusing real rays at 1 m in every zoom position with the sensor fixed."""
    from lensrt.loading import load_configurations
    family = load_configurations("canon_rf_24-70mm_f2.8")
    assert family.names == ("24.72mm", "44.86mm", "67.89mm")
    for stated, lens in zip((24.72, 44.86, 67.89), family.configurations()):
        _check_stated_efl(lens, stated)
        assert first_order(lens).f_number == pytest.approx(2.91, rel=1e-9)
        sol = focus_at(lens, 1000.0)
        assert sol.travel > 0 and abs(_on_sensor(sol)) < 1e-9  # L6 moves toward the image
        assert sol.lens.image_z_mm == pytest.approx(lens.image_z_mm, abs=1e-12)
    wide, tele = family.configuration("24.72mm"), family.configuration("67.89mm")
    assert 2 * first_order(wide).half_field_deg == pytest.approx(82.4, abs=0.05)
    assert 2 * first_order(tele).half_field_deg == pytest.approx(35.4, abs=0.05)


def test_library_tele_zoom_from_its_patent() -> None:
    """Canon RF 70-200 mm f/2.8 (JP 2021-056407 A Example 3): f = 72.13 / 100.00 / 194.06 mm and 2w = 33.4 / 12.7 deg
    at the patent's printed precision, and its focus group A (L15) focusing real rays at 1.5 m, moving to the image."""
    from lensrt.loading import load_configurations
    family = load_configurations("canon_rf_70-200mm_f2.8")
    for stated, lens in zip((72.13, 100.00, 194.06), family.configurations()):
        _check_stated_efl(lens, stated)
        sol = focus_at(lens, 1500.0)
        assert sol.travel > 0 and abs(_on_sensor(sol)) < 1e-9
    assert 2 * first_order(family.configuration(1)).half_field_deg == pytest.approx(33.4, abs=0.05)
    assert 2 * first_order(family.configuration(3)).half_field_deg == pytest.approx(12.7, abs=0.05)
    assert [first_order(c).f_number for c in family.configurations()] == pytest.approx([2.89, 2.90, 2.91])


def _polar_best_focus_z(lens, rings: int = 48, spokes: int = 96) -> float:
    """Independent oracle: the RMS-minimising plane of axial rays on a polar grid filling |p| <= 1 of the
    f-number's pupil (real aiming, equal-area cells), z* = z0 - cov(p, t) / var(t) (closed form)."""
    import numpy as np
    from lensrt.trace import rays_from_pupil, trace
    r = np.sqrt((np.arange(rings) + 0.5) / rings)
    phi = 2 * np.pi * (np.arange(spokes) + 0.5) / spokes
    px, py = (r[:, None] * np.cos(phi)[None, :]).ravel(), (r[:, None] * np.sin(phi)[None, :]).ravel()
    res = trace(lens, rays_from_pupil(lens, 0.0, 0.0, px, py, aim="real"), precision="float64", device="cpu",
                plane_z_mm=lens.image_z_mm)
    assert res.ok.all()
    p, t = res.position_mm[:, :2], res.direction[:, :2] / res.direction[:, 2:3]
    p, t = p - p.mean(axis=0), t - t.mean(axis=0)
    return lens.image_z_mm - float(np.sum(p * t) / np.sum(t * t))


def test_library_wide_zoom_from_its_patent() -> None:
    """Canon RF 15-35 mm f/2.8 (US 2020/0257181 A1 Example 1): f = 15.45 / 24.00 / 33.95 mm at the patent's printed
    precision; its focus group B2 focusing real rays at 1 m in every zoom position. At 15.45 mm the stop is the iris
    of f/2.91 (8.27 mm, not the 13.34 mm of the tele end: the marginal ray of |p| = 1 passes and |p| = 1.02 stops
    there), and the real best focus ignores the ring of axial rays that the large aspheric front bends through the
    stop 20 mm off axis (no flare-cut stop in the transcription): it equals the independent polar-grid minimum."""
    from lensrt.loading import load_configurations
    from lensrt.trace import rays_from_pupil, trace
    family = load_configurations("canon_rf_15-35mm_f2.8")
    for stated, lens in zip((15.45, 24.00, 33.95), family.configurations()):
        _check_stated_efl(lens, stated)
        assert first_order(lens).f_number == pytest.approx(2.91, rel=1e-9)
        res = trace(lens, rays_from_pupil(lens, 0.0, 0.0, 0.0, [0.999, 1.02], aim="real"), precision="float64",
                    device="cpu")
        assert res.status.tolist() == [0, 2] and res.surface[1] == lens.stop_index  # OK, VIGNETTED at the stop
    wide = family.configuration("15.45mm")
    bf = best_focus(wide, [wide.wavelengths.primary_nm], [1.0], 0.0)
    assert bf.z_mm == pytest.approx(_polar_best_focus_z(wide), abs=2e-3) and bf.rms_radius_mm < 0.01
    for lens in family.configurations():
        sol = focus_at(lens, 1000.0)
        assert sol.travel > 0 and abs(_on_sensor(sol)) < 1e-9



def _object_distance_in_focus(lens, lo_mm: float, hi_mm: float, tol_mm: float = 1e-10) -> float:
    """The axial object distance (from the first vertex) whose real best focus lies on ``lens``'s image surface,
    the lens as it is (secant on the distance; ``focus_residual_mm`` is the independent best-focus minimum)."""
    from lensrt.analysis.focusing import focus_residual_mm
    a, b = lo_mm, hi_mm
    ra, rb = focus_residual_mm(lens, a), focus_residual_mm(lens, b)
    for _ in range(40):
        if abs(rb) < tol_mm or rb == ra:
            break
        a, ra, b = b, rb, b - rb * (b - a) / (rb - ra)
        rb = focus_residual_mm(lens, b)
    assert abs(rb) < 1e-8
    return b


def test_library_inner_focus_prime_from_its_patent() -> None:
    """FUJINON XF 90 mm f/2 (US 2016/0274335 A1 Example 1): f = 87.495 mm at the patent's printed precision, the
    patent's infinity and close-focus gaps as two configurations (D8 + D11 constant: G2 moves, nothing else), the
    infinity gaps at the real best focus for infinity, and the declared focus group reaching the patent's close-focus
    gaps: the object distance at which the close configuration is in focus (solved with real rays) focuses the
    infinity configuration by exactly the patent's G2 travel 8.096 mm (1e-6 relative). That distance is 0.81 m from
    the image plane (m = -0.136), not the 0.6 m the transcription quotes (docs/guide/zoom.md)."""
    from lensrt.loading import load_configurations
    family = load_configurations("fujinon_xf_90mm_f2_inner_focus")
    inf, close = family.configuration("infinity"), family.configuration("close")
    _check_stated_efl(inf, 87.495)
    assert first_order(inf).f_number == pytest.approx(2.06, abs=5e-5)  # the fitted stop: F/2.06 at infinity
    assert inf.focus.kind == "group" and [g + 1 for g in inf.focus.gaps] == [8, 11]
    gaps = [(c.surfaces[7].thickness_mm, c.surfaces[10].thickness_mm) for c in (inf, close)]
    assert sum(gaps[0]) == pytest.approx(sum(gaps[1]), abs=1e-12) and gaps[1][0] - gaps[0][0] == pytest.approx(8.096)
    assert inf.image_z_mm == pytest.approx(close.image_z_mm, abs=1e-12)
    assert abs(focus_at(inf, math.inf).travel) < 0.01  # the patent's infinity gaps: real best focus within 10 um
    d_close = _object_distance_in_focus(close, 600.0, 800.0)
    sol = focus_at(inf, d_close)
    assert sol.travel == pytest.approx(8.096, rel=1e-6)
    assert [sol.lens.surfaces[g].thickness_mm for g in (7, 10)] == pytest.approx(list(gaps[1]), rel=1e-6)
    assert d_close + inf.image_z_mm == pytest.approx(813.6, abs=0.5)
