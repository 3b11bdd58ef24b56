"""The ideal paraxial lens (``Surface.ideal_focal_mm``, OpticStudio's ``TYPE PARAXIAL``; issue 22).

Oracles: the Gaussian equation n'/s' = 1/f + n/s (the lens images every plane perfectly onto its conjugate,
so real rays land on the closed-form image point to rounding), a parallel bundle meeting at f' tan(theta)
in the back focal plane, rays from a front-focal-plane point leaving parallel, the thin-lens phase (equal
optical paths to the axial focus), the float64 reference tracer for the Warp kernels, and optiland
(test-only oracle) reading the same Zemax file.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from trace_cases import max_reference_error

from lensrt.errors import PrescriptionError
from lensrt.loading import load_lens
from lensrt.paraxial import first_order, seidel_sums
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.trace import make_rays, trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK
from lensrt.trace.variants import choose_kernel, shape_and_constants
from lensrt.trace.pack import pack_lens

WL = 587.5618
DATA = Path(__file__).resolve().parents[1] / "data"
KEPLER = DATA / "kepler_paraxial_eyepiece.zmx"


def _ideal(f_mm: float, image_distance_mm: float, *, object_distance_mm: float = math.inf,
           n_after: float = 1.0) -> Lens:
    after = ConstantIndex(n_after) if n_after != 1.0 else ConstantIndex(1.0)
    surface = Surface(thickness_mm=image_distance_mm, ideal_focal_mm=f_mm, is_stop=True, semi_diameter_mm=20.0,
                      material=after)
    fields = Fields("angle", (0.0, math.radians(10.0))) if math.isinf(object_distance_mm) else \
        Fields("object_height", (0.0, 5.0))
    return Lens((surface,), aperture=Aperture("epd", 20.0), fields=fields, wavelengths=Wavelengths((WL,)),
                object_distance_mm=object_distance_mm)


def _kepler() -> Lens:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_lens(KEPLER)


@pytest.mark.parametrize("n_after", [1.0, 1.5])
def test_finite_object_images_perfectly(n_after: float) -> None:
    """Every ray from an object point lands on the Gaussian image point (n'/s' = 1/f - 1/s) within 1e-12 mm,
    at any height and pupil position: the ideal lens has no aberration at any conjugate."""
    f, s = 40.0, 100.0  # object 100 mm in front
    s_img = n_after / (1.0 / f - 1.0 / s)
    lens = _ideal(f, s_img, object_distance_mm=s, n_after=n_after)
    m = -s_img / (n_after * s)  # m = n u / (n' u')
    rng = np.random.default_rng(3)
    worst = 0.0
    for y0, x0 in ((0.0, 0.0), (7.0, 0.0), (-3.0, 4.0)):
        for px, py in rng.uniform(-15.0, 15.0, (20, 2)):
            d = np.array([px - x0, py - y0, s])
            ray = trace_reference(lens, (x0, y0, -s), d / np.linalg.norm(d), WL, clip=False)
            assert ray.status == OK
            worst = max(worst, abs(ray.x_mm - m * x0), abs(ray.y_mm - m * y0), abs(ray.z_mm - s_img))
    assert worst < 1e-12
    fo = first_order(lens)
    assert fo.efl_mm == pytest.approx(f, rel=1e-15) and fo.magnification == pytest.approx(m, rel=1e-14)
    assert fo.rear_focal_length_mm == pytest.approx(n_after * f, rel=1e-15)


def test_parallel_bundles_meet_in_the_back_focal_plane_and_focal_points_leave_parallel() -> None:
    f = 50.0
    lens = _ideal(f, f)
    for theta in (0.0, math.radians(5.0), math.radians(30.0)):
        for h in (-10.0, 0.0, 4.0, 9.0):
            ray = trace_reference(lens, (1.0, h, -5.0), (0.0, math.sin(theta), math.cos(theta)), WL)
            assert ray.status == OK
            assert abs(ray.y_mm - f * math.tan(theta)) < 1e-12 and abs(ray.x_mm) < 1e-12
    # rays from one point of the front focal plane: one direction after the lens
    dirs = []
    for py in (-8.0, -1.0, 3.0, 10.0):
        d = np.array([0.5, py - 6.0, f])
        ray = trace_reference(lens, (0.0, 6.0, -f), d / np.linalg.norm(d), WL)
        dirs.append((ray.L, ray.M, ray.N))
    assert np.ptp(np.array(dirs), axis=0).max() < 1e-15


def test_optical_paths_to_the_axial_focus_are_equal() -> None:
    """The perfect lens's phase: a collimated axial beam has the same OPL at the focus for every ray."""
    lens = _ideal(50.0, 50.0)
    opl = [trace_reference(lens, (0.0, h, -5.0), (0.0, 0.0, 1.0), WL).opl_mm for h in (0.0, 3.0, 9.0, 19.0)]
    assert np.ptp(opl) < 1e-12


def test_zemax_paraxial_eyelens_efl_against_optiland() -> None:
    lens = _kepler()
    ideal = [s for s in lens.surfaces if s.is_ideal]
    assert len(ideal) == 1 and ideal[0].ideal_focal_mm == 50.0 and ideal[0].ideal_opd_mode == 0
    assert any(w.code == "ideal_lens_opd" for w in lens.warnings)
    fo = first_order(lens)
    optiland = pytest.importorskip("optiland.fileio")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op = optiland.load_zemax_file(str(KEPLER))
    # both read N-BK7 from Schott's catalog: measured 3e-16 relative
    assert fo.efl_mm == pytest.approx(float(op.paraxial.f2()), rel=1e-12)
    # closed form of an afocal group followed by an ideal lens: EFL = f_ideal * (beam height in / out)
    tele = lens.replace(surfaces=lens.surfaces[:4])
    from lensrt.paraxial import paraxial_system, trace_ynu
    ray = trace_ynu(paraxial_system(tele), 1.0, 0.0)
    y_ideal = ray.y[-2] + lens.surfaces[3].thickness_mm * ray.u[-1]
    u_after = ray.u[-1] - y_ideal / 50.0
    assert fo.efl_mm == pytest.approx(-1.0 / u_after, rel=1e-12)


def test_native_round_trip_and_seidel() -> None:
    lens = _kepler()
    again = loads_native(dumps_native(lens))
    assert [s.ideal_focal_mm for s in again.surfaces] == [s.ideal_focal_mm for s in lens.surfaces]
    assert first_order(again).efl_mm == pytest.approx(first_order(lens).efl_mm, rel=1e-15)
    sums = seidel_sums(lens)
    k = next(i for i, s in enumerate(lens.surfaces) if s.is_ideal)
    assert all(sums.table()[k] == 0.0) and sums.petzval_curvature_per_mm[k] == 0.0


def test_ideal_lens_is_a_plane() -> None:
    with pytest.raises(PrescriptionError, match="is a plane"):
        Surface(curvature_per_mm=0.01, ideal_focal_mm=50.0)
    with pytest.raises(PrescriptionError, match="focal length 0"):
        Surface(ideal_focal_mm=0.0)
    with pytest.raises(PrescriptionError, match="ideal_opd_mode without"):
        loads_native('[aperture]\ntype = "epd"\nvalue = 5.0\n[[surface]]\nradius_mm = inf\nthickness_mm = 5.0\n'
                     'stop = true\nideal_opd_mode = 1\n')


@pytest.mark.parametrize("lens_name", ["kepler", "finite"])
def test_kernels_equal_the_reference(lens_name: str, device: str) -> None:
    lens = _kepler() if lens_name == "kepler" else load_lens(_ideal(-30.0, -25.0, object_distance_mm=80.0))
    rng = np.random.default_rng(9)
    n = 300
    rays = make_rays(lens, 0.0, rng.uniform(-1.0, 1.0, n), rng.uniform(-1.1, 1.1, n), rng.uniform(-1.1, 1.1, n),
                     aim="real")
    r64 = trace(lens, rays, "float64", device)
    assert r64.kernel == "generic" and r64.counts["OK"] > 100
    assert max_reference_error(lens, rays, r64) < 1e-12
    r32 = trace(lens, rays, "float32", device)
    ok = (r32.status == OK) & (r64.status == OK)
    assert ok.mean() > 0.95
    assert np.max(np.abs(r32.position_mm[ok] - r64.position_mm[ok])) < 1e-4
    # the lens-specialised kernels leave ideal lenses to the generic one
    shape, _ = shape_and_constants(pack_lens(lens, "float64", device))
    assert shape.ideal and choose_kernel("auto", "cuda:0", shape, 1 << 30) == "generic"


def test_real_rays_match_optiland_through_the_paraxial_surface() -> None:
    """optiland's thin lens uses the same direction-tangent law: image intercepts agree to rounding."""
    optiland = pytest.importorskip("optiland.fileio")
    import optiland.backend as be
    from optiland.rays import RealRays
    lens = _kepler()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op = optiland.load_zemax_file(str(KEPLER))
    g = np.linspace(-0.9, 0.9, 7)
    px, py = (a.ravel() for a in np.meshgrid(g, g))
    worst = 0.0
    for hy in (0.0, 1.0):
        rays = make_rays(lens, 0.0, hy, px, py, WL, aim="paraxial")
        o, d = rays.origin_mm, rays.direction
        start = o + ((-20.0 - o[:, 2]) / d[:, 2])[:, None] * d
        n = len(start)
        peer = RealRays(start[:, 0], start[:, 1], start[:, 2], d[:, 0], d[:, 1], d[:, 2], np.ones(n),
                        np.full(n, WL / 1000.0))
        op.surfaces.trace(peer)
        want = np.column_stack([be.to_numpy(peer.x), be.to_numpy(peer.y)])
        for i in range(n):
            ref = trace_reference(lens, o[i], d[i], WL, clip=False)
            assert ref.status == OK
            worst = max(worst, float(np.max(np.abs(np.array([ref.x_mm, ref.y_mm]) - want[i]))))
    assert worst < 1e-9
