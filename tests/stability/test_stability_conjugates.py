"""Stability over object distance: from 1e9 mm to 1:1 macro and inside the front focal point.

References and stated tolerances:

* an object 1e9 mm away images where the object at infinity does: real rays (float64) within
  1e-5 mm, the difference falling as 1/d (closed form: a field point's shift is O(f z_EP / d));
  float32 within :data:`F32_BOUND_MM` of float64 at every distance (ray origins sit on the
  object-space wavefront through the first vertex, so 1e9 mm costs float32 nothing);
* angle fields of a finite object: the chief ray from the object point through the paraxial
  entrance pupil's centre makes exactly the field angle (1e-12 rad);
* Newton's equation x x' = -f f' (Field Guide p. 5) for the paraxial image at every distance
  (1e-9 relative), m = -1 at x = -f (1:1 macro);
* real near-axis rays (P = +-0.02) meet the axis at the paraxial image to 2e-3 mm -- behind the
  lens for a real image, in front of it (traced backwards) for the virtual image of an object
  inside the front focal point;
* the object exactly at the front focal point: a LensrtError, not a 1e17 mm image.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from stability_cases import F32_BOUND_MM, finite, library

from lensrt.cli import main
from lensrt.errors import LensrtError
from lensrt.paraxial import first_order
from lensrt.trace import make_rays, trace
from lensrt.trace.aiming import field_point, pupil_geometry

LENS = library("dgauss_50mm_f2")  # angle fields, object at infinity
FO = first_order(LENS)
F_MM = FO.efl_mm
D_FOCAL = -FO.front_focal_z_mm  # object distance (from the first vertex) of the front focal point
HY = np.array([0.0, 0.5, 1.0, 1.0, -0.7])
PY = np.array([0.0, 0.5, 0.0, -0.3, 0.3])


def _at(d_mm: float):
    return LENS.replace(object_distance_mm=d_mm)


def test_angle_fields_of_a_finite_object_are_angles():
    """(A bug before this suite: the radial field in radians was taken as an object height in mm,
    so the 22 deg field of an object 1 m away came out at 0.02 deg.)"""
    for d_mm in (1e9, 1e4, 500.0):
        lens = _at(d_mm)
        ep_z = first_order(lens).entrance_pupil_z_mm
        for hy in (0.5, 1.0):
            fp = field_point(lens, 0.0, hy)
            v = np.array([0.0, 0.0, ep_z]) - np.asarray(fp.point_mm)
            angle = math.atan2(v[1], v[2])
            assert angle == pytest.approx(hy * LENS.fields.max_radial, abs=1e-12)
    with pytest.raises(LensrtError, match="90 deg"):
        field_point(_at(1e3), 0.0, 95.0 / math.degrees(LENS.fields.max_radial))


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_distant_objects_converge_to_infinity(precision, device):
    inf = trace(LENS, make_rays(LENS, 0.0, HY, 0.0, PY, aim="real"), "float64", device)
    assert inf.ok.all()
    shift = {}
    for d_mm in (1e9, 1e7, 1e5):
        lens = _at(d_mm)
        rays = make_rays(lens, 0.0, HY, 0.0, PY, aim="real")
        assert rays.aimed.all() and finite(rays.origin_mm, rays.direction)
        r64 = trace(lens, rays, "float64", device)
        res = trace(lens, rays, precision, device)
        assert res.ok.all() and finite(res.position_mm, res.opl_mm)
        if precision == "float32":
            assert np.max(np.abs(res.position_mm - r64.position_mm)) < F32_BOUND_MM
            assert np.max(np.abs(res.opl_mm - r64.opl_mm)) < F32_BOUND_MM
        shift[d_mm] = float(np.max(np.abs(r64.position_mm - inf.position_mm)))
    assert shift[1e9] < 1e-5
    # O(1/d): a hundred times farther, a hundred times closer (to 10 % -- and the float64 floor)
    assert shift[1e7] == pytest.approx(100.0 * shift[1e5] / 1e4, rel=0.1)
    assert shift[1e9] < 0.02 * shift[1e7] + 1e-9


@pytest.mark.parametrize("x_over_f", [-1e6, -20.0, -1.0, -0.1, 0.3, 0.45])
def test_newtons_equation_from_far_to_inside_the_focal_point(x_over_f):
    """x x' = -f f' with x from F to the object and x' from F' to the image (both + toward +z)."""
    x = x_over_f * F_MM
    fo = first_order(LENS, object_distance_mm=D_FOCAL - x)
    x_img = fo.image_z_mm - FO.rear_focal_z_mm
    assert x * x_img == pytest.approx(-F_MM * F_MM, rel=1e-9)
    assert fo.magnification == pytest.approx(F_MM / x, rel=1e-9)
    assert fo.image_virtual == (fo.image_distance_mm < 0.0)
    if x_over_f == -1.0:  # 1:1
        assert fo.magnification == pytest.approx(-1.0, abs=1e-9)
        assert not fo.image_virtual
    if x_over_f > 0.0:  # inside the front focal point: virtual, upright, magnified
        assert fo.image_virtual and fo.magnification > 1.0
        assert fo.image_z_mm < LENS.length_mm


def _axis_crossings(lens, device) -> np.ndarray:
    """z where real near-axis rays from the axial object point cross the axis after the lens
    (the line through the ray's end, extended either way)."""
    rays = make_rays(lens, 0.0, 0.0, 0.0, [-0.02, 0.02], aim="real")
    res = trace(lens, rays, "float64", device)
    assert res.ok.all()
    y, z = res.position_mm[:, 1], res.position_mm[:, 2]
    M, N = res.direction[:, 1], res.direction[:, 2]
    return z - y * N / M


@pytest.mark.parametrize("x_over_f", [-20.0, -1.0, 0.5])
def test_real_rays_focus_at_the_paraxial_image(x_over_f, device):
    """Real and virtual images alike: near-axis real rays meet the axis where the paraxial image
    is (real: behind the lens; virtual: in front of the last vertex, found by extending the
    diverging rays backwards)."""
    lens = _at(D_FOCAL - x_over_f * F_MM)
    fo = first_order(lens)
    z = _axis_crossings(lens, device)
    # spherical aberration at P = 0.02 shifts the focus by ~1e-4 of the image distance
    tol = 2e-3 + 2e-4 * abs(fo.image_distance_mm)
    np.testing.assert_allclose(z, fo.image_z_mm, atol=tol)
    assert (z < lens.length_mm).all() == fo.image_virtual


def test_inside_the_focal_point_rays_still_reach_the_image_surface(device):
    """The lens's image surface stays where the file puts it: rays reach it (OK, finite), as a
    blur -- lensrt says the image is virtual rather than inventing one."""
    lens = _at(D_FOCAL - 0.3 * F_MM)
    assert first_order(lens).image_virtual
    rays = make_rays(lens, 0.0, HY, 0.0, PY, aim="real")
    assert rays.aimed.all()
    for precision in ("float64", "float32"):
        res = trace(lens, rays, precision, device)
        assert finite(res.position_mm, res.direction, res.opl_mm)
        assert res.ok[[0, 2, 4]].all() and np.all((res.status == 0) == (res.surface == -1))
    geom = pupil_geometry(lens)
    assert math.isfinite(geom.ep_z_mm) and geom.stop_radius_mm > 0


def test_object_at_the_front_focal_point_is_an_error(capsys):
    with pytest.raises(LensrtError, match="front focal point"):
        first_order(LENS, object_distance_mm=D_FOCAL)
    with pytest.raises(LensrtError, match="front focal point"):
        first_order(LENS, object_distance_mm=D_FOCAL * (1 + 1e-13))
    assert main(["info", "dgauss_50mm_f2", "--object-distance-mm", f"{D_FOCAL:.17g}"]) == 2
    assert "front focal point" in capsys.readouterr().err
    assert main(["info", "dgauss_50mm_f2", "--object-distance-mm", f"{D_FOCAL - 0.3 * F_MM:.17g}", "--json"]) == 0
    import json
    assert json.loads(capsys.readouterr().out)["image_virtual"] is True
    assert main(["info", "dgauss_50mm_f2", "--object-distance-mm", f"{D_FOCAL - 0.3 * F_MM:.17g}"]) == 0
    assert "virtual image" in capsys.readouterr().out
