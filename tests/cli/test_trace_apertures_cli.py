"""Real-ray clear apertures (the loader's automatic mode) and the ``lensrt ray`` command."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from trace_cases import LIBRARY

from lensrt.cli import main
from lensrt.loading import complete_lens
from lensrt.prescription.formats import read_lens
from lensrt.prescription.model import Fields
from lensrt.trace import make_rays, trace
from lensrt.trace.apertures import METHOD_REAL, compute_clear_apertures, real_ray_heights

DG_PATH = LIBRARY / "codev_dblgauss_100mm_f2.toml"


def test_real_clear_apertures_of_the_double_gauss(device):
    raw = read_lens(DG_PATH)
    assert all(s.semi_diameter_mm is None for s in raw.surfaces)
    lens = complete_lens(raw)
    assert lens.meta["clear_apertures"] == METHOD_REAL
    sd = np.array([s.semi_diameter_mm for s in lens.surfaces])
    assert all(s.semi_diameter_auto for s in lens.surfaces)
    assert sd[lens.stop_index] == pytest.approx(15.702464, abs=5e-7)  # CODE V's real axial marginal height
    # every marginal and chief ray of the specification passes the apertures it defined
    fields, wls = lens.fields.y, lens.wavelengths.nm
    hy = np.repeat([f / max(fields) for f in fields], 5)
    px = np.tile([0, 0, 0, 1, -1], len(fields))
    py = np.tile([0, 1, -1, 0, 0], len(fields))
    for wl in wls:
        res = trace(lens, make_rays(lens, 0.0, hy, px, py, wl, aim="real"), "float64", device)
        assert res.ok.all()
    # and at each surface one of them touches the edge
    heights, failed, tried = real_ray_heights(raw)
    assert failed == 0 and tried == 3 * 3 * 5
    np.testing.assert_allclose(heights, sd, rtol=0, atol=1e-12)


def test_paraxial_fallback_is_recorded():
    raw = read_lens(DG_PATH)
    wide = raw.replace(fields=Fields("angle", (0.0, math.radians(50.0))))  # far beyond what the lens passes
    lens = compute_clear_apertures(wide)
    assert "paraxial" in lens.meta["clear_apertures"] and "failed" in lens.meta["clear_apertures"]
    assert all(s.semi_diameter_mm > 0 for s in lens.surfaces)


def _run(capsys, *args: str) -> tuple[int, str, str]:
    rc = main(list(args))
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_ray_cli_json(capsys):
    rc, out, _ = _run(capsys, "ray", str(DG_PATH), "--hx", "0", "--hy", "1", "--px", "0", "--py", "1",
                      "--aim", "real", "--device", "cpu", "--json")
    assert rc == 0
    rep = json.loads(out)
    for key in ("status", "image_x_mm", "image_y_mm", "image_z_mm", "direction", "opl_mm", "surfaces"):
        assert key in rep
    assert rep["status"] == "OK"
    assert len(rep["surfaces"]) == 12 and rep["surfaces"][-1]["surface"] == "IMG"
    assert rep["surfaces"][5]["y_mm"] == pytest.approx(15.702464, abs=1e-6)  # real aim: the stop edge
    L, M, N = rep["direction"]
    assert L * L + M * M + N * N == pytest.approx(1.0, abs=1e-12)
    assert rep["image_z_mm"] == pytest.approx(139.05466966, abs=1e-6)
    for s in rep["surfaces"]:
        assert {"x_mm", "y_mm", "z_mm", "L", "M", "N", "incidence_deg", "refraction_deg"} <= set(s)


def test_ray_cli_text_and_float32(capsys):
    rc, out, _ = _run(capsys, "ray", str(DG_PATH), "--hy", "0.5", "--py", "-0.5", "--precision", "float32",
                      "--device", "cpu")
    assert rc == 0
    assert "status OK" in out and "AOI_deg" in out and "float32" in out


def test_ray_cli_vignetted_and_errors(capsys):
    rc, out, _ = _run(capsys, "ray", str(DG_PATH), "--hy", "1", "--py", "1.3", "--device", "cpu", "--json")
    assert rc == 0
    rep = json.loads(out)
    assert rep["status"] == "VIGNETTED" and isinstance(rep["failed_surface"], int)
    assert rep["image_x_mm"] is None
    rc, _, err = _run(capsys, "ray", str(DG_PATH), "--device", "cuda:7")
    assert rc == 2 and err.startswith("lensrt: error:")
    rc, _, err = _run(capsys, "ray", str(DG_PATH), "--wavelength-nm", "50", "--device", "cpu")
    assert rc == 2 and "wavelength" in err
