"""colour-science's tables on disk (lensrt.colour.datacache): written on first use, read back bit for bit,
rebuilt when missing or corrupt, and read without importing colour-science."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import colour
import numpy as np
import pytest

from lensrt.colour import datacache
from lensrt.colour.cmfs import CIE_1931_2DEG, cie_xyz_cmfs, photopic_v
from lensrt.colour.illuminants import cie_illuminant, illuminant_names
from lensrt.colour.rgb import srgb_encode, srgb_encode8, srgb_matrices, srgb_white_xy

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder, nothing in memory."""
    monkeypatch.setenv("LENSRT_CACHE", str(tmp_path))
    datacache.clear_memo()
    yield tmp_path / "colour"
    datacache.clear_memo()


def _same(a: np.ndarray, b) -> bool:
    b = np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _observer_from_colour_science() -> dict[str, np.ndarray]:
    cmfs, lef = colour.MSDS_CMFS[CIE_1931_2DEG], colour.SDS_LEFS["CIE 1924 Photopic Standard Observer"]
    return {"cmfs_nm": cmfs.wavelengths, "cmfs": cmfs.values, "v_nm": lef.wavelengths, "v": lef.values}


def _tables(name: str) -> dict[str, np.ndarray]:
    """The public functions fill the memo; this returns what they hold for ``name``."""
    cie_xyz_cmfs(np.array([550.0]))
    cie_illuminant("D65")
    srgb_encode8([0.5])
    return datacache.cached_tables(name, lambda: pytest.fail(f"{name} not in memory"))


def test_first_use_writes_the_file_and_second_reads_the_same_arrays_as_colour_science(cache):
    path = datacache.cache_path("observer")
    assert path.parent == cache and colour.__version__ in path.name and not path.exists()
    first = _tables("observer")
    assert path.exists()
    expected = _observer_from_colour_science()
    assert set(first) == set(expected) and all(_same(first[k], expected[k]) for k in expected)
    # a new process reads the file: nothing in memory, and a build would fail the test
    datacache.clear_memo()
    second = datacache.cached_tables("observer", lambda: pytest.fail("rebuilt although the file was there"))
    assert all(_same(second[k], expected[k]) for k in expected)
    assert not second["cmfs"].flags.writeable


def test_every_cie_illuminant_and_the_srgb_colourspace_equal_colour_science(cache):
    _tables("cie_illuminants")
    datacache.clear_memo()  # from the file from now on
    names = illuminant_names()
    assert names == tuple(colour.SDS_ILLUMINANTS.keys())
    for name in names:
        sd = colour.SDS_ILLUMINANTS[name]
        ill = cie_illuminant(name)
        assert _same(ill.table_nm, sd.wavelengths) and _same(ill.table_values, sd.values), name
    cs = colour.RGB_COLOURSPACES["sRGB"]
    to_rgb, to_xyz = srgb_matrices()
    assert _same(srgb_white_xy(), cs.whitepoint)
    assert _same(datacache.cached_tables("srgb", lambda: pytest.fail("rebuilt"))["xyz_to_rgb"], cs.matrix_XYZ_to_RGB)
    assert _same(to_xyz, cs.matrix_RGB_to_XYZ) and _same(to_rgb, cs.matrix_XYZ_to_RGB)
    # the CMFs and V(lambda) at any wavelengths: colour-science's tables, linear between entries, 0 outside
    nm = np.array([300.0, 360.0, 555.5, 830.0, 900.0])
    cmfs = colour.MSDS_CMFS[CIE_1931_2DEG]
    for i in range(3):
        want = np.interp(nm, cmfs.wavelengths, cmfs.values[:, i], left=0.0, right=0.0)
        assert _same(cie_xyz_cmfs(nm)[i], want)
    lef = colour.SDS_LEFS["CIE 1924 Photopic Standard Observer"]
    assert _same(photopic_v(nm), np.interp(nm, lef.wavelengths, lef.values, left=0.0, right=0.0))


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty", "other key"])
def test_a_corrupt_or_foreign_file_is_rebuilt_from_colour_science(cache, damage):
    _tables("observer")
    path = datacache.cache_path("observer")
    good = path.read_bytes()
    if damage == "garbage":
        path.write_bytes(b"not a zip file" * 100)
    elif damage == "truncated":
        path.write_bytes(good[: len(good) // 2])
    elif damage == "empty":
        path.write_bytes(b"")
    else:  # a valid file of another table set under this name
        srgb = datacache.cache_path("srgb")
        path.write_bytes(srgb.read_bytes())
    datacache.clear_memo()
    builds = []

    def build():
        builds.append(1)
        return _observer_from_colour_science()

    again = datacache.cached_tables("observer", build)
    assert builds == [1]
    expected = _observer_from_colour_science()
    assert all(_same(again[k], expected[k]) for k in expected)
    with np.load(path, allow_pickle=False) as z:  # the file was written again, whole
        assert set(expected) <= set(z.files)
    datacache.clear_memo()  # the rebuilt file is good again
    assert all(_same(datacache.cached_tables("observer", lambda: pytest.fail("rebuilt twice"))[k], expected[k])
               for k in expected)


def test_a_folder_that_cannot_be_written_only_costs_the_import(tmp_path, monkeypatch):
    blocker = tmp_path / "a file"
    blocker.write_text("the cache folder would have to be inside a file")
    monkeypatch.setenv("LENSRT_CACHE", str(blocker))
    datacache.clear_memo()
    try:
        t = datacache.cached_tables("observer", lambda: {"x": np.arange(3.0)})
        assert _same(t["x"], np.arange(3.0))
        assert list(tmp_path.iterdir()) == [blocker]
    finally:
        datacache.clear_memo()


def test_8_bit_srgb_codes_equal_colour_science_curve_bit_for_bit(cache):
    rng = np.random.default_rng(19)
    thresholds = _tables("srgb")["code8_from"]
    assert thresholds.shape == (255,) and np.all(np.diff(thresholds) > 0)
    x = np.concatenate([rng.random(500_000), rng.random(100_000) * 0.01, np.geomspace(1e-300, 1.0, 20_000),
                        thresholds, np.nextafter(thresholds, -np.inf), np.nextafter(thresholds, np.inf),
                        [0.0, 1.0, -0.5, 2.0, 0.0031308, np.inf, -np.inf]])
    want = (srgb_encode(np.clip(x, 0.0, 1.0)) * 255.0 + 0.5).astype(np.uint8)
    got = srgb_encode8(x)
    assert got.dtype == np.uint8 and np.array_equal(got, want)
    assert srgb_encode8(np.array([np.nan]))[0] == 0
    # every code is reached, 0 at black and 255 at white
    assert set(np.unique(srgb_encode8(np.linspace(0, 1, 200_001)))) == set(range(256))


def test_a_warm_process_reads_the_tables_without_importing_colour_science(cache):
    _tables("observer")
    code = ("import sys\n"
            "from lensrt.colour import cie_xyz_cmfs, cie_illuminant, srgb_encode8, srgb_matrices, photopic_v\n"
            "x = cie_xyz_cmfs(); v = photopic_v(); d = cie_illuminant('D65'); m = srgb_matrices()\n"
            "c = srgb_encode8([0.0, 0.18, 1.0])\n"
            "import json; print(json.dumps({'colour': 'colour' in sys.modules, 'pandas': 'pandas' in sys.modules,"
            " 'codes': c.tolist()}))\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT), LENSRT_CACHE=str(cache.parent))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["codes"] == srgb_encode8([0.0, 0.18, 1.0]).tolist()
    assert not seen["colour"] and not seen["pandas"]


def test_charts_reflectance_basis_and_camera_sensitivities_equal_colour_science(cache):
    from lensrt.colour.charts import chart_names, colorchecker_names, colorchecker_reflectances
    from lensrt.colour.reflectance import mallett2019_basis
    from lensrt.colour.wavelengths import WavelengthGrid
    from lensrt.sensor.spectral import CAMERA_DATASETS, camera_response
    for _ in range(2):  # built from colour-science, then read from the files
        datacache.clear_memo()
        assert chart_names() == tuple(colour.SDS_COLOURCHECKERS)
        grid = WavelengthGrid(360.0, 800.0, 2.0)  # beyond the tables: edge values held
        for chart in chart_names():
            sds = colour.SDS_COLOURCHECKERS[chart]
            assert colorchecker_names(chart) == tuple(sds.keys())
            want = np.stack([np.interp(grid.nm, sd.wavelengths, sd.values) for sd in sds.values()])
            assert _same(colorchecker_reflectances(grid, chart), want)
        assert colorchecker_names("colorchecker n ohta") == colorchecker_names("ColorChecker N Ohta")
        basis = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
        want = np.stack([np.interp(grid.nm, basis.wavelengths, basis.values[:, i]) for i in range(3)])
        assert _same(mallett2019_basis(WavelengthGrid(360.0, 800.0, 2.0)), want)
        for key, full in CAMERA_DATASETS.items():
            msds = colour.MSDS_CAMERA_SENSITIVITIES[full]
            got = camera_response(key)
            assert _same(got.wavelength_nm, msds.wavelengths)
            assert _same(got.relative, np.clip(msds.values, 0.0, None) / msds.values.max(axis=0))
        assert len(list(cache.glob("*.npz"))) >= 3
