"""PSF/MTF figures are written, are PNGs and are not blank."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lensrt.analysis.psf import otf as M
from lensrt.analysis.wave.propagation import PupilFunction, psf_fft, through_focus_psfs
from lensrt.analysis.grid import ImageGrid
from lensrt.analysis.psf.result import diffraction_result, geometric_psf, histogram_rays, ray_moment_sums
from lensrt.analysis.wave.pupil_grid import circular_aperture, iris_aperture, pupil_coordinates, zernike
from lensrt.views.plots.psf import (nice_length, plot_mtf_curves, plot_mtf_vs_field, plot_psf, plot_psf_mosaic,
                                 plot_through_focus)


def check_png(path: Path) -> None:
    import matplotlib.image as mpimg

    assert path.exists() and path.stat().st_size > 5000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 200 and float(np.std(img[..., :3])) > 0.02


def _field_psfs() -> list:
    """A 3 x 3 map of aberrated diffraction PSFs (coma growing with field, pointing away from the axis)."""
    n = 48
    mask = iris_aperture(n, 7, roundness=0.3)
    px, py = pupil_coordinates(n)
    rho, th = np.hypot(px, py), np.arctan2(py, px)
    out = []
    for y in (12.0, 0.0, -12.0):
        for x in (-18.0, 0.0, 18.0):
            h = math.hypot(x, y) / math.hypot(18, 12)
            phi = math.atan2(y, x)
            coma = 0.6 * h * (math.cos(phi) * zernike(8, rho, th) + math.sin(phi) * zernike(7, rho, th))
            pup = PupilFunction.from_waves(mask, coma + 0.15 * h * h * zernike(6, rho, th), 550.0, 4.0, intensity=mask)
            psf, grid, rep = psf_fft(pup, 3, reference_mm=(x, y))
            out.append(diffraction_result(psf, grid, "diffraction-fft", wavelengths_nm=[550.0], reference_mm=(x, y),
                                          samples=n * n, metadata={"sampling": rep}))
    return out


def test_psf_and_mtf_figures(tmp_path: Path):
    import os
    if os.environ.get("LENSRT_KEEP_PLOTS"):
        tmp_path = Path(os.environ["LENSRT_KEEP_PLOTS"])
    mask = circular_aperture(64)
    psf, grid, rep = psf_fft(PupilFunction(mask, np.zeros((64, 64)), 550.0, 4.0, intensity=mask), 4)
    airy = diffraction_result(psf, grid, "diffraction-fft", wavelengths_nm=[550.0], metadata={"sampling": rep})
    check_png(plot_psf(tmp_path / "airy.png", airy, title="Airy f/4"))
    check_png(plot_psf(tmp_path / "airy_log.png", airy, log=True))

    rng = np.random.default_rng(0)
    r, t = 0.02 * np.sqrt(rng.random(100_000)), 2 * math.pi * rng.random(100_000)
    x, y = 5.0 + r * np.cos(t), r * np.sin(t)
    g = ImageGrid.centred(64, 1.0, (5.0, 0.0))
    hist, off = histogram_rays(x, y, None, g, 16)
    geo = geometric_psf(hist, g, moment_sums=ray_moment_sums(x, y, None, (5.0, 0.0), 16), off_grid=off,
                        reference_mm=(5.0, 0.0), wavelengths_nm=[550.0], samples=100_000, seconds=0.1, seed=0)
    check_png(plot_psf(tmp_path / "disc.png", geo))

    maps = _field_psfs()
    check_png(plot_psf_mosaic(tmp_path / "map.png", maps, ncols=3))
    f = np.linspace(0, 300, 61)
    curves = [(f"({res.reference_mm[0]:.0f}, {res.reference_mm[1]:.0f}) mm",
               *M.sagittal_tangential(res.psf, res.grid, f, res.reference_mm)) for res in maps[4:6] + maps[2:3]]
    check_png(plot_mtf_curves(tmp_path / "mtf.png", f, curves, diffraction=M.diffraction_mtf(f, 550.0, 4.0),
                              nyquist_cpmm=M.nyquist_cpmm(4.0)))
    along = [maps[4], maps[5], maps[2]]
    field = M.mtf_vs_field([m.psf for m in along], [m.grid for m in along], [m.reference_mm for m in along],
                           M.reference_frequencies_cpmm())
    check_png(plot_mtf_vs_field(tmp_path / "field.png", field))

    pup = PupilFunction(mask, np.zeros((64, 64)), 550.0, 4.0, intensity=mask)
    gz = ImageGrid.centred(48, 0.5)
    z = np.linspace(-0.03, 0.03, 11)
    tf = M.through_focus_mtf(through_focus_psfs(pup, gz, z), gz, z, [20.0, 40.0, 80.0])
    check_png(plot_through_focus(tmp_path / "focus.png", tf))


def test_scale_bar_lengths():
    assert nice_length(40.0) == 10.0
    assert nice_length(9.0) == 2.0
    assert nice_length(0.3) == pytest.approx(0.05)
