"""``lensrt sweep`` and lensrt.studies.sweep: lens variants as work items, checked against the Field Guide's formulas
and against ``lensrt info`` for the same variant."""
from __future__ import annotations

import csv
import io
import json
import math

import pytest

from lensrt import load_lens
from lensrt.cli import main
from lensrt.commands.sweep import parse_values
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order
from lensrt.parallel import LocalExecutor
from lensrt.studies.sweep import QUANTITIES, SweepSetup, Variant, sweep_job, variant_lens, variant_row


@pytest.fixture(scope="module")
def lens():
    from conftest import LIBRARY
    return load_lens(LIBRARY / "codev_dblgauss_100mm_f2.toml")


def test_a_row_follows_the_field_guide_formulas(lens) -> None:
    row = variant_row(SweepSetup(lens), Variant(3000.0, 8.0))
    fo = first_order(variant_lens(lens, Variant(3000.0, 8.0)))
    f, c, N = fo.front_focal_length_mm, 0.030, 8.0
    assert row["f_number"] == pytest.approx(N, rel=1e-12)
    assert row["entrance_pupil_diameter_mm"] == pytest.approx(f / N, rel=1e-12)
    # p. 31: Nw = (1 + |m| / mp) N
    assert row["working_f_number"] == pytest.approx((1 + abs(row["magnification"]) / fo.pupil_magnification) * N)
    # p. 24: H = f^2/(cN) - s_EP + f from the entrance pupil; the row puts it in front of the first vertex
    H_ep = f * f / (c * N) - fo.entrance_pupil_distance_mm + f
    assert row["hyperfocal_mm"] == pytest.approx(H_ep - fo.entrance_pupil_z_mm, rel=1e-12)
    # p. 23: near/far from the pupil with h = f^2/(cN), s = u + s_EP
    h, u = f * f / (c * N), 3000.0 + fo.entrance_pupil_z_mm
    s = u + fo.entrance_pupil_distance_mm
    assert row["dof_near_mm"] == pytest.approx(h * u / (h + s - f) - fo.entrance_pupil_z_mm, rel=1e-12)
    assert row["dof_far_mm"] == pytest.approx(h * u / (h - (s - f)) - fo.entrance_pupil_z_mm, rel=1e-12)
    assert row["dof_near_mm"] < 3000.0 < row["dof_far_mm"]
    assert row["airy_diameter_um"] == pytest.approx(2.44 * fo.wavelength_nm * 1e-3 * row["working_f_number"])
    # p. 12: unit-focus extension e = f f' / (s - f) with s from the front principal plane
    s_p = 3000.0 + fo.front_principal_z_mm
    assert row["extension_mm"] == pytest.approx(f * fo.rear_focal_length_mm / (s_p - f), rel=1e-9)
    assert set(QUANTITIES) <= set(row)


def test_rows_agree_with_lensrt_info_for_the_same_variant(lens, capsys, library_dir) -> None:
    path = str(library_dir / "codev_dblgauss_100mm_f2.toml")
    assert main(["info", path, "--object-distance-mm", "2000", "--sensor", "aps-c", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    row = variant_row(SweepSetup(lens, sensor="aps-c"), Variant(2000.0, None))
    dof = info["sensor"]["depth_of_field"]
    assert row["dof_near_mm"] == pytest.approx(-dof["near_z_mm"], rel=1e-12)
    assert row["dof_far_mm"] == pytest.approx(-dof["far_z_mm"], rel=1e-12)
    assert row["hyperfocal_mm"] == pytest.approx(-dof["hyperfocal_z_mm"], rel=1e-12)
    assert row["working_f_number"] == pytest.approx(info["working_f_number"], rel=1e-12)
    assert row["afov_diagonal_deg"] == pytest.approx(info["sensor"]["afov_deg"]["diagonal"], rel=1e-12)


def test_job_has_one_item_per_variant_in_focus_major_order(lens) -> None:
    job = sweep_job(SweepSetup(lens), [1000.0, math.inf], [2.0, 4.0, 8.0])
    assert [(it.params.focus_distance_mm, it.params.f_number) for it in job.items] == [
        (1000.0, 2.0), (1000.0, 4.0), (1000.0, 8.0), (math.inf, 2.0), (math.inf, 4.0), (math.inf, 8.0)]
    rows = LocalExecutor("cpu").run(job).value
    assert [r["f_number"] for r in rows] == pytest.approx([2, 4, 8, 2, 4, 8])
    assert rows[3]["dof_far_mm"] == math.inf and rows[3]["magnification"] == 0.0
    with pytest.raises(LensrtError, match="must be positive"):
        sweep_job(SweepSetup(lens), [-5.0], [2.0])
    with pytest.raises(LensrtError, match=">= 0.5"):
        sweep_job(SweepSetup(lens), [1000.0], [0.1])


def test_a_variant_inside_the_focal_length_is_a_named_error(lens) -> None:
    job = sweep_job(SweepSetup(lens), [1000.0, 10.0], [4.0])
    with pytest.raises(LensrtError, match="variant focus 10 mm, f/4.0"):
        LocalExecutor("cpu").run(job)


def test_parse_values() -> None:
    assert parse_values("1000, 2000,inf", "x") == [1000.0, 2000.0, math.inf]
    assert parse_values("2:8:3", "x") == pytest.approx([2.0, 4.0, 8.0])
    assert parse_values("5:5:1", "x") == [5.0]
    for bad in ("a,b", "1:2", "0:4:3", "", "2:8:0"):
        with pytest.raises(LensrtError):
            parse_values(bad, "--f-number")


def test_cli_table_csv_json_and_file(capsys, tmp_path, library_dir) -> None:
    path = str(library_dir / "codev_dblgauss_100mm_f2.toml")
    base = ["sweep", path, "--focus-distance-mm", "1500,inf", "--f-number", "2.8,11"]
    assert main(base) == 0
    out = capsys.readouterr().out
    assert "focus_distance_mm" in out and "dof_near_mm" in out and "4 items in" in out
    assert main(base + ["--format", "csv", "--quantity", "hyperfocal_mm,airy_diameter_um"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert len(rows) == 4 and list(rows[0]) == ["focus_distance_mm", "f_number", "hyperfocal_mm", "airy_diameter_um"]
    assert rows[2]["focus_distance_mm"] == "inf" and float(rows[1]["f_number"]) == pytest.approx(11.0)
    assert main(base + ["--quantity", "all", "-o", str(tmp_path / "s.json")]) == 0
    assert "wrote" in capsys.readouterr().out
    doc = json.loads((tmp_path / "s.json").read_text())
    assert len(doc["rows"]) == 4 and doc["rows"][2]["dof_far_mm"] is None  # inf -> null in strict JSON
    assert doc["columns"]["hyperfocal_mm"] == "mm" and doc["run"]["n_items"] == 4
    assert main(["sweep", path, "--focus-distance-mm", "inf"]) == 0  # default f-numbers: f/2 .. f/16
    out = capsys.readouterr().out
    assert "7 items in" in out


def test_cli_errors_are_one_line(capsys, library_dir) -> None:
    path = str(library_dir / "codev_dblgauss_100mm_f2.toml")
    assert main(["sweep", path, "--quantity", "bogus"]) == 2
    assert "unknown quantity bogus" in capsys.readouterr().err
    assert main(["sweep", path, "--f-number", "x"]) == 2
    assert "lensrt: error: --f-number 'x'" in capsys.readouterr().err
    assert main(["sweep", path, "--list-quantities"]) == 0
    assert "airy_diameter_um" in capsys.readouterr().out
