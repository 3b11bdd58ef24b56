"""Best focus: one converged routine (lensrt.trace.focus) behind every table, --focus best and the render.

The old routines took cell-centred grids of 32-128 rays a side: their edge cells were all in or all out, an
O(1/n) error in the weight of the marginal zone, 4-16 um on f/1.4 lenses and not monotonic in n (so one
``lensrt compare`` printed two best foci). The oracle here is the same closed form on a far denser pupil
sampling (512 x 512 cells, the boundary cells 4 x 4 more: an edge resolved to 1/2048 of the box), which
agrees with a plain 2048 x 2048 grid to < 0.05 um on both lenses (measured once, 39-72 s each on 2 cores).
"""
from __future__ import annotations

import math

import pytest

from trace_cases import library_lens

from lensrt.paraxial import first_order
from lensrt.trace.focus import best_focus_plane, focus_moments


@pytest.mark.parametrize("name", ["petzval_51mm_f1.4", "nikkor_50mm_f1.4"])
def test_best_focus_is_converged_on_f1_4_lenses(name):
    lens = library_lens(name)
    wl = lens.wavelengths.primary_nm
    z_par = first_order(lens, wl).image_z_mm
    default = best_focus_plane([focus_moments(lens, wl, z0_mm=z_par, device="cpu")])
    dense = best_focus_plane([focus_moments(lens, wl, z0_mm=z_par, n=512, sub=4, device="cpu")])
    assert abs(default.z_mm - dense.z_mm) < 0.5e-3, (default.z_mm - z_par, dense.z_mm - z_par)
    assert default.rms_radius_mm == pytest.approx(dense.rms_radius_mm, rel=0.01)


def test_every_table_uses_the_same_plane():
    """compare's focus table, its axial-colour table, psf/mtf --focus best and the render's best focus."""
    from lensrt.analysis.compare.focus import best_focus, chromatic_focal_shift
    from lensrt.analysis.psf.focus import focus_plane
    from lensrt.render.camera import best_focus_z_mm
    lens = library_lens("petzval_51mm_f1.4")
    wl = lens.wavelengths.primary_nm
    table = best_focus(lens, [wl], [1.0], device="cpu").z_mm
    colour = chromatic_focal_shift(lens, wavelength_nm=[wl], best_focus_wavelengths_nm=[wl], device="cpu")
    assert colour.best_focus_shift_mm[0] + colour.reference_z_mm == pytest.approx(table, abs=1e-12)
    assert focus_plane(lens, "best", device="cpu")["z_mm"] == pytest.approx(table, abs=1e-12)
    render = best_focus_z_mm(lens, math.inf, (wl,), (1.0,))
    assert render == pytest.approx(table, abs=1e-9)   # its own reference plane (the image surface)


def test_pooled_wavelengths_and_bad_weights():
    from lensrt.errors import LensrtError
    lens = library_lens("dgauss_50mm_f2")
    z0 = lens.image_z_mm
    m = [focus_moments(lens, w, z0_mm=z0, device="cpu") for w in lens.wavelengths.nm]   # F, d, C
    # a zero weight leaves a wavelength out; pooling with equal weights lands between the extremes
    assert best_focus_plane(m, [0.0, 1.0, 0.0]).z_mm == pytest.approx(best_focus_plane(m[1:2]).z_mm, abs=1e-12)
    zs = sorted(best_focus_plane([x]).z_mm for x in m)
    pooled = best_focus_plane(m).z_mm
    assert zs[0] < pooled < zs[-1]
    # pooling keeps each wavelength's rays' spread: the polychromatic RMS exceeds each one's at its own focus
    assert best_focus_plane(m).rms_radius_mm > max(best_focus_plane([x]).rms_radius_mm for x in m[1:2])
    with pytest.raises(LensrtError, match="not all zero"):
        best_focus_plane(m, [0.0] * len(m))
    with pytest.raises(LensrtError, match="non-negative"):
        best_focus_plane(m, [-1.0] + [1.0] * (len(m) - 1))
