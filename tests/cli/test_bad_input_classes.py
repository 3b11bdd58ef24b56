"""Issue 26: one test per class of bad input -- each ends in ONE clear error line, in seconds, before any allocation.

Out of memory or hung on a typo; impossible lenses traced as if valid; ``render --plan`` saying yes to
what ``render`` refuses; internal errors instead of messages; and the smaller ones (BOM in scenes,
``CURV`` without a value, ``--name`` escaping ``--out``, the afocal message). The memory refusals run
under a fixed ``--max-memory`` or the default limit; the tests assert on the refusal, never on timing.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from lensrt.core.budget import (MemoryEstimate, check_count, check_memory, estimate_psf_bytes, estimate_render_bytes,
                           format_bytes, parse_memory)
from lensrt.cli import main
from lensrt.errors import LensrtError, PrescriptionError
from lensrt.loading import load_lens

ROOT = Path(__file__).resolve().parents[2]
COOKE = (ROOT / "lens_prescriptions" / "cooke_triplet_50mm_f5.toml").read_text()
ZMX = (ROOT / "tests" / "data" / "cooke_triplet.zmx").read_text()
SCENE = (ROOT / "scenes" / "default.toml").read_text()


def one_line(argv: list, capsys: pytest.CaptureFixture, *needles: str) -> str:
    """Run ``lensrt argv`` in-process: status 2 and one error line holding every needle."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own one-line errors (after its usage lines)
        rc = exc.code
    out, err = capsys.readouterr()
    assert rc == 2, (argv, rc, out[-500:], err)
    assert "Traceback" not in err and "internal error" not in err, err
    lines = err.strip().splitlines()
    if lines[-1].startswith("lensrt: error: "):
        assert len(lines) == 1, err
    for n in needles:
        assert n in lines[-1], (n, lines[-1])
    return lines[-1]


def lens_file(tmp_path: Path, name: str, old: str, new: str, text: str = COOKE) -> Path:
    assert old in text, old
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return p


def refused(path: Path, *needles: str) -> str:
    with pytest.raises(PrescriptionError) as err:
        load_lens(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)), msg
    for n in needles:
        assert n in msg, (n, msg)
    return msg


# ------------------------------------------------------------------ the budget module itself


def test_budget_parse_check_and_format() -> None:
    assert parse_memory("8G") == 8 << 30 and parse_memory("512MiB") == 512 << 20 and parse_memory("1e9") == 10 ** 9
    for bad in ("x", "-1G", "0", "nan", "8Q"):
        with pytest.raises(LensrtError, match="--max-memory"):
            parse_memory(bad)
    est = MemoryEstimate("a job", 3 << 30, "detail")
    check_memory(est, 4 << 30)  # under the limit: nothing
    with pytest.raises(LensrtError) as err:
        check_memory(est, 1 << 30)
    msg = str(err.value)
    assert "3 GiB" in msg and "1 GiB" in msg and "--max-memory 3G" in msg and "\n" not in msg
    with pytest.raises(LensrtError, match="--max-rays"):
        check_count(1e15, 1e10, "--rays 1e15", "--max-rays")
    assert format_bytes(1536) == "1.5 KiB"
    # the render estimate is linear in pixels and bands (the arithmetic, not a measurement)
    a, b = estimate_render_bytes(100, 100, 40).bytes, estimate_render_bytes(200, 100, 40).bytes
    assert b == 2 * a
    assert estimate_psf_bytes(1, 128, 32, 20000, True).bytes > 1e10  # 4e8 pupil samples a line


# ------------------------------------------------------------------ out of memory or hung, on a typo


def test_render_width_and_scene_pixels_refused_before_allocation(tmp_path: Path, capsys) -> None:
    one_line(["render", "--width", "30000", "--spp", "2", "--max-memory", "8G"], capsys, "needs about",
             "--max-memory")
    scene = tmp_path / "big.toml"
    scene.write_text(SCENE.replace("pixels = [720, 480]", "pixels = [20000, 13333]"))
    one_line(["render", scene, "--spp", "2", "--max-memory", "4G"], capsys, "20000 x 13333 px", "--max-memory")
    one_line(["render", "--width", "70000"], capsys, "--width 70000")
    # the same limit, raised, lets --plan through and shows the estimate
    assert main(["render", "--width", "30000", "--plan", "--max-memory", "2T"]) == 0
    assert "memory       about" in capsys.readouterr().out


def test_bokeh_map_and_pixels_refused(capsys) -> None:
    one_line(["bokeh", "--map", "3x2", "--pixels", "40000x26667", "--rays", "1e4", "--no-files", "--max-memory", "8G"],
             capsys, "40000 x 26667 px", "--max-memory")
    one_line(["bokeh", "--map", "10000x10000", "--rays", "1e4", "--no-files", "--max-memory", "8G"], capsys,
             "100000000 sources", "--max-memory")
    one_line(["bokeh", "--map", "100x100", "--rays", "1e7", "--no-files"], capsys, "--max-rays")


def test_psf_pupil_pixels_and_rays_refused(capsys) -> None:
    one_line(["psf", "--method", "diffraction", "--pupil-samples", "100000"], capsys, "--pupil-samples 100000")
    one_line(["psf", "--method", "diffraction", "--pupil-samples", "20000", "--max-memory", "8G"], capsys,
             "pupil grids", "--max-memory")
    one_line(["psf", "--pixels", "100000"], capsys, "--pixels 100000")
    one_line(["psf", "--rays", "1e15"], capsys, "--rays 1e+15", "--max-rays")
    one_line(["mtf", "--rays", "1e15"], capsys, "--max-rays")


def test_sensor_sizes_refused(capsys) -> None:
    for sub in (["characterize"], ["expose", "--flat", "100"]):
        one_line(["sensor", *sub, "--size", "100000x100000"], capsys, "--size 100000x100000")
        one_line(["sensor", *sub, "--size", "30000x30000", "--max-memory", "4G"], capsys, "--size 30000x30000",
                 "--max-memory")
    one_line(["sensor", "expose", "--colorchecker", "--patch-px", "100000"], capsys, "--patch-px")


def test_sweep_length_capped(capsys) -> None:
    one_line(["sweep", "--focus-distance-mm", "100:1e9:1000000"], capsys, "--focus-distance-mm", "--max-rows")
    one_line(["sweep", "--focus-distance-mm", "100:1e9:1e300"], capsys, "--max-rows")
    one_line(["sweep", "--focus-distance-mm", "100:200:3", "--f-number", "2.8,4", "--max-rows", "5"], capsys,
             "6 variants")


def test_aspheric_index_bounded_while_parsing(tmp_path: Path) -> None:
    toml = lens_file(tmp_path, "asph.toml", "radius_mm = 79.6836", "radius_mm = 79.6836\nasphere = { A100000000 = 1e-30 }")
    refused(toml, "A100000000", "r^40")
    zmx = lens_file(tmp_path, "parm.zmx", "SURF 1\n  TYPE STANDARD", "SURF 1\n  TYPE EVENASPH\n  PARM 100000000 1e-5",
                    ZMX)
    refused(zmx, "PARM 100000000")


# ------------------------------------------------------------------ impossible lenses


def test_index_below_one_needs_opt_in(tmp_path: Path) -> None:
    old = 'material = { glass = "F2", catalog = "Schott" }'
    refused(lens_file(tmp_path, "n07.toml", old, "material = { index = 0.7 }"), "refractive index 0.7", "exotic")
    lens = load_lens(lens_file(tmp_path, "n07x.toml", old, "material = { index = 0.7, exotic = true }"))
    assert min(float(v) for v in lens.indices([550.0]).ravel()) == pytest.approx(0.7)


def test_glass_element_crossing_with_computed_apertures(tmp_path: Path) -> None:
    # the Cooke file gives no semi-diameters: a 0.1 mm centre on a biconvex element crosses inside the beam
    refused(lens_file(tmp_path, "thin.toml", "thickness_mm = 3.25896", "thickness_mm = 0.1"),
            "surfaces 1 and 2", "cross inside the axial beam")


def test_failed_clear_aperture_computation_is_an_error(tmp_path: Path) -> None:
    # a plano-concave "lens" whose real rays miss at every field: 0.05 mm radius after a 10 mm EPD is refused
    # as an f-number below 0.5; a lens with a sane f-number whose rays fail is refused by the computation
    refused(lens_file(tmp_path, "r1um.toml", "radius_mm = 22.01359", "radius_mm = 0.001"), "below f/0.5")
    from lensrt.prescription.formats import read_lens
    from lensrt.trace.apertures import compute_clear_apertures
    text = COOKE.replace("y = [0.0, 14.0, 20.0]", "y = [60.0, 70.0, 80.0]").replace(
        "nm = [480.0, 550.0, 650.0]\nweights = [1.0, 1.0, 1.0]", "nm = [550.0]\nweights = [1.0]")
    lens = read_lens(lens_file(tmp_path, "wide.toml", COOKE, text))
    with pytest.raises(PrescriptionError, match="clear apertures cannot be computed"):
        compute_clear_apertures(lens)


def test_epd_beyond_f_half(tmp_path: Path) -> None:
    refused(lens_file(tmp_path, "epd.toml", "value = 10.0", "value = 1e9"), "f/5e-08", "below f/0.5")


def test_wavelength_weights_all_zero(tmp_path: Path) -> None:
    refused(lens_file(tmp_path, "w0.toml", "weights = [1.0, 1.0, 1.0]\nprimary", "weights = [0.0, 0.0, 0.0]\nprimary"),
            "all zero")


def test_negative_diam_and_curv_without_value(tmp_path: Path) -> None:
    refused(lens_file(tmp_path, "diam.zmx", "  DISZ 6.0075500000000002E+00",
                      "  DISZ 6.0075500000000002E+00\n  DIAM -5", ZMX), "DIAM -5", "negative semi-diameter")
    refused(lens_file(tmp_path, "curv.zmx", "  CURV -2.2948388798212154E-03", "  CURV", ZMX), "CURV without a value")


def test_unknown_catalog_name(tmp_path: Path) -> None:
    refused(lens_file(tmp_path, "cat.toml", "[system]", '[system]\ncatalogs = ["Schott", "NOSUCH"]'),
            "unknown glass catalog 'NOSUCH'")


def test_f_number_wider_than_the_lens_refused_alike(tmp_path: Path, capsys) -> None:
    line = one_line(["bokeh", "--f-number", "0.5", "--rays", "1e4", "--no-files"], capsys, "f/0.5 is wider")
    assert "--f-number" in line
    one_line(["sweep", "--f-number", "0.5"], capsys, "f/0.5 is wider")
    scene = tmp_path / "fast.toml"
    scene.write_text(SCENE.replace("[camera]", "[camera]\nf_number = 0.5"))
    one_line(["render", scene, "--plan"], capsys, "f/0.5 is wider")
    one_line(["render", scene, "--width", "16", "--spp", "2"], capsys, "f/0.5 is wider")


def test_table_cells_never_print_nan() -> None:
    from lensrt.io.table import format_table
    text = format_table([[1.0, math.nan, None]], ["a", "b", "c"])
    assert "nan" not in text and text.splitlines()[-1].split() == ["1.0000", "-", "-"]


# ------------------------------------------------------------------ render --plan refuses what render refuses


@pytest.mark.parametrize("edit,needle", [
    (('lens = "dgauss_50mm_f2"', 'lens = "no_such_lens"'), "no_such_lens"),
    (('lens = "dgauss_50mm_f2"', 'lens = "DIR"'), "does not exist"),
    (('format = "full-frame"', 'format = "full-frame"\npreset = "nope"'), "unknown sensor preset"),
    (("focus_distance = 2.0", "focus_distance = 1e-9"), "focus distance"),
    (("pixels = [720, 480]", "pixels = [64000, 43000]"), "needs about"),
])
def test_plan_refuses_what_render_refuses(edit, needle: str, tmp_path: Path, capsys) -> None:
    old, new = edit
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.replace(old, new.replace("DIR", str(tmp_path))))
    one_line(["render", scene, "--plan", "--max-memory", "8G"], capsys, needle)


def test_plan_refuses_a_lens_path_that_is_a_directory(tmp_path: Path, capsys) -> None:
    one_line(["render", "--plan", "--lens", tmp_path], capsys, "is a directory")


# ------------------------------------------------------------------ internal errors that became messages


def test_arguments_checked_where_parsed(tmp_path: Path, capsys) -> None:
    one_line(["render", "--seed", "-1"], capsys, "--seed", "0 .. 2^63-1")
    one_line(["sensor", "characterize", "--stack", "0", "--size", "16x16"], capsys, "--stack 0")
    junk = tmp_path / "junk.npz"
    junk.write_text("not a zip")
    one_line(["sensor", "expose", "--irradiance", junk], capsys, str(junk), "not a readable .npz")
    one_line(["sensor", "expose", "--flat", "100", "--size", "16x16", "--exposure-s", "1e300"], capsys,
             "--exposure-s", "1e+300")


def test_poisson_of_an_absurd_mean_is_clipped_not_an_error() -> None:
    import numpy as np
    from lensrt.sensor import electrons_to_raw, get_preset
    sensor = get_preset("fullframe_24mp")
    raw = electrons_to_raw(sensor, np.full((8, 8), 1e30, dtype=np.float32), 1.0, rng=np.random.default_rng(0))
    assert np.isfinite(raw.dn).all() and raw.dn.max() > 0


# ------------------------------------------------------------------ the smaller ones


def test_utf8_bom_in_scene_file(tmp_path: Path, capsys) -> None:
    scene = tmp_path / "bom.toml"
    scene.write_bytes(b"\xef\xbb\xbf" + SCENE.encode("utf-8"))
    from lensrt.render.scene import load_scene
    assert load_scene(scene).name == "default"


def test_output_name_cannot_escape_out(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    for name in ("../../x", "/etc/x", "..", "a/b"):
        one_line(["bokeh", "--rays", "1e4", "--batches", "8", "--out", out, "--name", name], capsys, "--name")
    assert not any(tmp_path.rglob("x.*"))
    # a plain stem is written inside --out
    assert main(["bokeh", "--rays", "1e4", "--batches", "8", "--out", str(out), "--name", "ok", "--device", "cpu"]) == 0
    capsys.readouterr()
    assert (out / "ok.png").is_file() and not any(p.parent != out for p in tmp_path.rglob("ok.*"))


def test_no_finite_image_message_does_not_contradict_itself(tmp_path: Path) -> None:
    # an object at infinity whose image falls more than 1e9 focal lengths away (a 1.5e11 mm element, found by
    # the long Hypothesis profile): never "the object is at the front focal point"; refused at load, naming
    # the file. (A lens of exactly zero power is afocal and reported with its angular magnification.)
    text = COOKE.replace("thickness_mm = 3.25896", "thickness_mm = 146427852046.0")
    msg = refused(lens_file(tmp_path, "long.toml", COOKE, text))
    assert "front focal point" not in msg and ("no finite image" in msg or "cross" in msg or "clear apertures" in msg)
