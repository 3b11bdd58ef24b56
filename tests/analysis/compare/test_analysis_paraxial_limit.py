"""Near the axis, real rays tend to the paraxial ones at the order the aberration theory says.

Gaussian optics is the limit of real rays as the aperture and field go to zero (Field Guide
p. 2). For a small ray height h (or pupil zone rho) and field fraction H:

* real EFL f(h) = -h / (n' sin U') -> 1/Phi with an O(h^2) difference (offence against the sine
  condition);
* the real chief-ray image height -> the paraxial one with an O(H^2) *relative* difference,
  and that difference tends to the Seidel distortion (tho DST) times H^2;
* the real marginal-ray focus -> the paraxial focus as O(rho^2), tending to the Seidel LSA;
* real sagittal and tangential foci -> the Seidel (third-order) ones, relative difference O(H^2);
* the real entrance and exit pupils (chief-ray axis crossings) -> the paraxial pupils as O(H^2).

Each is checked the same way: halving the parameter quarters the difference (ratio 4), and
the difference at the smallest parameter is small. Lenses: the Cooke triplet (f/5) and the
CODE V double Gauss (f/2), both near the axis.
"""
from __future__ import annotations

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.analysis.compare.distortion import distortion_curve
from lensrt.analysis.compare.focus import field_curvature, longitudinal_aberration, real_focal_length
from lensrt.analysis.compare.pupils import real_pupils
from lensrt.paraxial import first_order, seidel_sums

LENSES = ["cooke_triplet_50mm_f5", "codev_dblgauss_100mm_f2"]


def _quadratic(dev: np.ndarray, tol: float = 0.1) -> None:
    """dev at parameters x, 2x, 4x: each doubling multiplies it by 4 (an O(x^2) difference)."""
    dev = np.asarray(dev, dtype=np.float64)
    ratios = dev[1:] / dev[:-1]
    np.testing.assert_allclose(ratios, 4.0, rtol=tol)


@pytest.fixture(scope="module", params=LENSES)
def lens(request):
    return library_lens(request.param)


def test_focal_length_order_h2(lens):
    fo = first_order(lens)
    r = 0.5 * fo.entrance_pupil_diameter_mm
    f = real_focal_length(lens, heights_mm=[0.02 * r, 0.04 * r, 0.08 * r], device="cpu")
    _quadratic(f.real_efl_mm - fo.efl_mm, 0.02)
    assert abs(f.real_efl_near_axis_mm / fo.efl_mm - 1.0) < 1e-7  # h = 1e-3 r_EP
    # the equivalent focal length from a small-angle image height: O(theta^2) too, and it *is* the distortion
    f1 = real_focal_length(lens, small_angle_fraction=0.025, device="cpu")
    f2 = real_focal_length(lens, small_angle_fraction=0.05, device="cpu")
    f4 = real_focal_length(lens, small_angle_fraction=0.1, device="cpu")
    dev = [g.equivalent_focal_length_mm - fo.efl_mm for g in (f1, f2, f4)]
    _quadratic(dev, 0.02)
    c = distortion_curve(lens, object_values=[f2.small_angle_rad], device="cpu")
    assert f2.equivalent_focal_length_mm / fo.efl_mm - 1.0 == pytest.approx(c.distortion_percent[0] / 100, abs=1e-12)


def test_distortion_tends_to_seidel(lens):
    h = np.array([0.025, 0.05, 0.1])
    c = distortion_curve(lens, h, device="cpu")
    tr = seidel_sums(lens).transverse_totals()
    y_max = first_order(lens).paraxial_image_height_mm
    third = 100.0 * tr["DST"] / y_max * (c.paraxial_height_mm / y_max) ** 2
    dev = c.distortion_percent / third - 1.0
    _quadratic(dev, 0.03)
    assert abs(dev[0]) < 2e-4
    # the real image height itself: relative O(H^2) from the paraxial one
    _quadratic(c.real_height_mm / c.paraxial_height_mm - 1.0, 0.03)


def test_spherical_aberration_tends_to_seidel(lens):
    la = longitudinal_aberration(lens, [lens.wavelengths.primary_nm], zones=[0.025, 0.05, 0.1], device="cpu")
    _quadratic(la.lsa_mm[0], 0.02)  # the marginal focus tends to the paraxial focus as rho^2
    dev = la.lsa_mm[0] / la.third_order_lsa_mm - 1.0
    _quadratic(dev, 0.03)
    assert abs(dev[0]) < 5e-4


def test_field_curvature_tends_to_seidel(lens):
    h = np.array([0.05, 0.1, 0.2])
    fc = field_curvature(lens, h, device="cpu")
    zp = fc.paraxial_image_z_mm
    for real, third in ((fc.sagittal_z_mm, fc.third_order_sagittal_z_mm),
                        (fc.tangential_z_mm, fc.third_order_tangential_z_mm)):
        dev = (real - zp) / (third - zp) - 1.0
        _quadratic(dev, 0.12)
        assert abs(dev[0]) < 0.01
    # on the axis both foci are the paraxial focus, up to the close rays' own O(delta^2) spherical
    # aberration (delta = 1e-4 of the pupil: LSA ~ 1e-8 of the marginal one)
    fc0 = field_curvature(lens, [0.0], device="cpu")
    assert fc0.sagittal_z_mm[0] == pytest.approx(zp, abs=1e-7)
    assert fc0.tangential_z_mm[0] == pytest.approx(zp, abs=1e-7)


def test_real_pupils_tend_to_paraxial(lens):
    fo = first_order(lens)
    p = real_pupils(lens, [0.025, 0.05, 0.1], outlines=False, device="cpu")
    _quadratic(p.entrance_pupil_z_mm - fo.entrance_pupil_z_mm, 0.02)
    _quadratic(p.exit_pupil_z_mm - fo.exit_pupil_z_mm, 0.02)
