"""Wavelengths at the ends of the glass catalogs' ranges, and beyond them.

* The kernels' dispersion formula (15 packed coefficients, evaluated per ray) against
  ``Material.index`` (float64, itself tested against opticalglass in test_materials.py): at
  both ends of each glass's measured range, relative 1e-12 in float64 and 2e-7 in float32
  (read back from the optical path of an axial ray through a slab: OPL = n t).
* Far outside (200 nm, 20 um) a formula can give nonsense (n = 8.4 for Hikari J-SF6 at 200 nm)
  or no real index (a power series goes negative in the infrared): rays then end ``INVALID``
  in both precisions and in the reference, never NaN.
* Extrapolation is reported: :meth:`Lens.check_wavelengths` issues an ExtrapolationWarning, and
  the entry points that take wavelengths call it -- loading a lens (its own wavelengths),
  ``lensrt ray`` / ``info`` / ``sweep`` / ``compare --wavelength-nm``, ``trace.stream`` (the
  spectrum's extent: PSF, bokeh, light-splat renders) and camera-path renders (the scene's
  spectral grid). Exactly at a range end: no warning.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from stability_cases import finite, system

from lensrt.cli import main
from lensrt.loading import load_lens
from lensrt.prescription.formats.native import write_native
from lensrt.prescription.materials import ExtrapolationWarning, find_glass
from lensrt.prescription.model import Surface, Wavelengths
from lensrt.trace import RayBatch, trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import INVALID, OK

#: one or two glasses of each catalog (Sellmeier: Schott, Ohara; power series: Hoya, CDGM,
#: Sumita; extended series: Hikari)
GLASSES = ("N-BK7", "N-SF11", "S-LAH66", "E-FD1", "H-ZF52", "J-SF6", "K-VC89")


def _slab(glass_name: str):
    g = find_glass(glass_name)
    lens = system(Surface(thickness_mm=10.0, material=g, is_stop=True, semi_diameter_mm=5.0),
                  Surface(thickness_mm=5.0, semi_diameter_mm=5.0))
    return lens, g


def _kernel_index(lens, wavelength_nm: np.ndarray, precision: str, device: str):
    n = len(wavelength_nm)
    o = np.zeros((n, 3))
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    res = trace(lens, RayBatch(o, d, wavelength_nm), precision, device)
    return (res.opl_mm - 5.0) / 10.0, res


@pytest.mark.parametrize("name", GLASSES)
def test_index_at_the_ends_of_the_measured_range(name, device):
    lens, g = _slab(name)
    lo, hi = g.valid_range_nm
    wl = np.array([lo, 0.5 * (lo + hi), hi])
    want = np.asarray(g.index(wl))
    for precision, rel in (("float64", 1e-12), ("float32", 2e-7)):
        n, res = _kernel_index(lens, wl, precision, device)
        assert res.ok.all()
        np.testing.assert_allclose(n, want, rtol=rel)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # exactly at the ends: no warning
        assert lens.check_wavelengths(wl) == []
    with pytest.warns(ExtrapolationWarning, match=g.name):
        msgs = lens.check_wavelengths([lo - 1.0, hi + 1.0])
    assert len(msgs) == 1 and "extrapolated" in msgs[0]


@pytest.mark.parametrize("name", GLASSES)
def test_far_outside_the_range_invalid_or_finite(name, device):
    lens, g = _slab(name)
    wl = np.array([200.0, 250.0, 5000.0, 12000.0, 20000.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # sqrt of a negative n^2: that is the point
        want = np.asarray(g.index(wl), dtype=np.float64)
    real = np.isfinite(want) & (want > 0)
    for precision in ("float64", "float32"):
        n, res = _kernel_index(lens, wl, precision, device)
        assert finite(res.position_mm, res.direction, res.opl_mm)
        np.testing.assert_array_equal(res.status == OK, real)
        assert np.all(res.status[~real] == INVALID) and np.all(res.surface[~real] == 0)
        if precision == "float64":
            np.testing.assert_allclose(n[real], want[real], rtol=1e-12)
    for i, w in enumerate(wl):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            ref = trace_reference(lens, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), float(w))
        assert (ref.status == OK) == real[i]


def test_lensrt_ray_and_info_warn_when_extrapolating(capsys):
    lens_name = "codev_dblgauss_100mm_f2"  # Schott glasses, measured from 365 nm
    assert main(["ray", lens_name, "--hy", "0.5", "--py", "0.5", "--wavelength-nm", "300"]) == 0
    err = capsys.readouterr().err
    assert "lensrt: warning:" in err and "extrapolated at 300 nm" in err
    assert main(["ray", lens_name, "--wavelength-nm", "587.5618"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["info", lens_name, "--wavelength-nm", "2400", "--json"]) == 0
    assert "extrapolated at 2400 nm" in capsys.readouterr().err
    assert main(["info", lens_name]) == 0
    assert "warning" not in capsys.readouterr().err


def test_sweep_warns_when_extrapolating(capsys):
    assert main(["sweep", "codev_dblgauss_100mm_f2", "--wavelength-nm", "300", "--focus-distance-mm", "inf",
                 "--f-number", "2", "--quantity", "efl_mm", "--format", "json"]) == 0
    assert "extrapolated at 300 nm" in capsys.readouterr().err


def test_loading_a_lens_outside_its_glass_data_warns(tmp_path):
    lens = load_lens("codev_dblgauss_100mm_f2")
    ir = lens.replace(wavelengths=Wavelengths((2500.0, 3000.0)), path=None)
    path = tmp_path / "ir.toml"
    write_native(ir, path)
    with pytest.warns(ExtrapolationWarning, match="2500, 3000 nm"):
        load_lens(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExtrapolationWarning)
        load_lens("codev_dblgauss_100mm_f2")  # the library lens: inside every range


def test_stream_warns_for_a_spectrum_beyond_the_glass_data(device):
    from lensrt.trace.sampling import spectrum_continuous
    from lensrt.trace.stream import Grid, stream, stream_source
    lens = load_lens("codev_dblgauss_100mm_f2")
    src = stream_source(lens, device=device)
    with pytest.warns(ExtrapolationWarning, match="extrapolated at 300"):
        res = stream(lens, [src], Grid(8, 8, 0.05), 1 << 10, spectrum=spectrum_continuous([300.0, 500.0, 700.0],
                                                                                         [1.0, 1.0]),
                     precision="float32", device=device)
    assert math.isfinite(res.transmission()[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExtrapolationWarning)
        stream(lens, [src], Grid(8, 8, 0.05), 1 << 10, precision="float32", device=device)


def test_compare_and_render_warn_when_extrapolating():
    """``lensrt compare --wavelength-nm`` and renders (their spectral grid, 380-780 nm in the
    built-in scenes) check the lens's glasses too."""
    from lensrt.commands.compare import compare_report
    from lensrt.render.setup import RenderOptions, prepare_render
    from lensrt.render.scene.load import load_scene
    lens = load_lens("codev_dblgauss_100mm_f2")
    with pytest.warns(ExtrapolationWarning, match="extrapolated at 300 nm"):
        compare_report(lens, (), (300.0,), rays=64, spot_rays=64, device="cpu")
    cdgm = lens.replace_surface(0, material=find_glass("H-ZF52"))  # CDGM data start at 404.7 nm
    with pytest.warns(ExtrapolationWarning, match="H-ZF52.*extrapolated at 380"):
        prepare_render(load_scene("default"), cdgm, RenderOptions(width=8, pupil_bins=8), device="cpu")
