"""The float64 reference tracer against closed forms (no Warp here)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Iris, Lens, Surface, Wavelengths
from lensrt.trace.reference import inside_iris, intersect, refract, trace_reference
from lensrt.trace.status import MISSED, NO_CONVERGE, OK, TIR, VIGNETTED, describe_status

WL = 587.5618


def _lens(*surfaces: Surface) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0,)),
                wavelengths=Wavelengths((WL,)))


def test_single_sphere_snell_closed_form():
    # a ray parallel to the axis at height h meets a sphere of radius R at incidence asin(h/R)
    R, n, h = 50.0, 1.5, 20.0
    lens = _lens(Surface(curvature_per_mm=1 / R, thickness_mm=100.0, material=ConstantIndex(n), is_stop=True))
    ray = trace_reference(lens, (0.0, h, -10.0), (0.0, 0.0, 1.0), WL)
    hit = ray.hits[0]
    inc = math.asin(h / R)
    assert hit.incidence_rad == pytest.approx(inc, abs=1e-14)
    assert math.sin(hit.refraction_rad) * n == pytest.approx(math.sin(inc), abs=1e-14)  # n' sin I' = n sin I
    assert hit.z_mm == pytest.approx(R - math.sqrt(R * R - h * h), abs=1e-13)
    # the refracted ray turns toward the axis by I - I'
    assert math.atan2(-hit.M, hit.N) == pytest.approx(inc - math.asin(math.sin(inc) / n), abs=1e-14)


def test_plane_parallel_plate_shift():
    # lateral displacement of a tilted ray by a plate: d = t sin(U - U') / cos U'
    t, n, u = 10.0, 1.7, math.radians(30.0)
    lens = _lens(Surface(thickness_mm=t, material=ConstantIndex(n), is_stop=True), Surface(thickness_mm=20.0))
    d = (0.0, math.sin(u), math.cos(u))
    ray = trace_reference(lens, (0.0, 0.0, 0.0), d, WL)
    assert ray.status == OK
    assert (ray.L, ray.M, ray.N) == pytest.approx(d, abs=1e-15)
    up = math.asin(math.sin(u) / n)
    straight_y = (t + 20.0) * math.tan(u)
    shift = t * math.sin(u - up) / math.cos(up)
    assert straight_y - ray.y_mm == pytest.approx(shift / math.cos(u), abs=1e-12)
    assert ray.opl_mm == pytest.approx(n * t / math.cos(up) + 20.0 / math.cos(u), abs=1e-12)


def test_paraxial_limit_focus():
    # a thin-ish biconvex lens: rays at small height cross the axis at the paraxial BFL
    from lensrt.paraxial import first_order
    glass = ConstantIndex(1.6)
    lens = _lens(Surface(curvature_per_mm=1 / 60.0, thickness_mm=4.0, material=glass, is_stop=True),
                 Surface(curvature_per_mm=-1 / 60.0, thickness_mm=40.0))
    fo = first_order(lens)
    lens = lens.replace_surface(1, thickness_mm=fo.bfl_mm)
    for h in (1e-3, 1e-2):
        ray = trace_reference(lens, (0.0, h, 0.0), (0.0, 0.0, 1.0), WL)
        # spherical aberration grows as h^2: the height at the paraxial focus is O(h^3)
        assert abs(ray.y_mm) < 1e-3 * h


def test_nearly_flat_surface_equals_plane():
    # |R| = 1e7 mm: the vertex-branch root must not cancel; it equals the plane intersection to ~sag
    c = 1e-7
    for (x, y, z, L, M, N) in [(0.0, 20.0, -5.0, 0.0, 0.3, math.sqrt(1 - 0.09)), (3.0, -4.0, -1e3, 0.01, 0.0, 1.0)]:
        nrm = math.sqrt(L * L + M * M + N * N)
        L, M, N = L / nrm, M / nrm, N / nrm
        st, t, _ = intersect(c, 1.0, (), x, y, z, L, M, N)
        assert st == OK
        t_plane = -z / N
        px, py = x + t_plane * L, y + t_plane * M
        sag = c * (px * px + py * py) / 2.0
        assert t == pytest.approx(t_plane + sag / N, rel=0, abs=1e-9)


def test_concave_surface_from_beyond_its_centre():
    # the ray starts farther from the vertex than 2|R|: the vertex branch is the far root
    c = -1.0 / 32.0
    st, t, n = intersect(c, 1.0, (), 0.0, 5.0, -70.0, 0.0, 0.0, 1.0)
    assert st == OK
    z_hit = -70.0 + t
    assert z_hit == pytest.approx(c * 25.0 / (1.0 + math.sqrt(1.0 - c * c * 25.0)), abs=1e-12)
    assert n[2] > 0.0


def test_asphere_intersection_lies_on_sag():
    s = Surface(curvature_per_mm=1 / 25.0, conic=-0.8, asphere=(1e-4, -3e-6, 2e-9))
    x, y, z, L, M, N = 1.0, 7.0, -3.0, 0.02, 0.12, 1.0
    nrm = math.sqrt(L * L + M * M + N * N)
    st, t, normal = intersect(s.curvature_per_mm, 1 + s.conic, s.asphere, x, y, z, L / nrm, M / nrm, N / nrm)
    assert st == OK
    px, py, pz = x + t * L / nrm, y + t * M / nrm, z + t * N / nrm
    assert pz == pytest.approx(s.sag(math.hypot(px, py)), abs=1e-12)
    # the normal is the gradient of z - sag(r)
    eps = 1e-6
    dz = (s.sag(math.hypot(px + eps, py)) - s.sag(math.hypot(px - eps, py))) / (2 * eps)
    assert -normal[0] / normal[2] == pytest.approx(dz, rel=1e-6)


def test_asphere_no_root_is_no_converge():
    # z = r^2 (an r^2 asphere term, c = 0): a ray running under the vertex never meets it
    st, _, _ = intersect(0.0, 1.0, (1.0,), 0.0, 0.0, -1.0, math.cos(0.01), 0.0, math.sin(0.01))
    assert st == NO_CONVERGE


def test_missed_beyond_a_hemisphere():
    lens = _lens(Surface(curvature_per_mm=1 / 10.0, thickness_mm=5.0, material=ConstantIndex(1.5), is_stop=True),
                 Surface(thickness_mm=10.0))
    ray = trace_reference(lens, (0.0, 12.0, -5.0), (0.0, 0.0, 1.0), WL)
    assert (ray.status, ray.surface) == (MISSED, 0)
    assert describe_status(ray.status, ray.surface) == "MISSED(surface 1)"


def test_total_internal_reflection():
    # leaving glass n = 1.8 through a plane at 40 deg (critical angle 33.7 deg)
    st, *_ = refract(0.0, math.sin(math.radians(40.0)), math.cos(math.radians(40.0)), (0.0, 0.0, 1.0), 1.8, 1.0)
    assert st == TIR
    st, *_ = refract(0.0, math.sin(math.radians(33.0)), math.cos(math.radians(33.0)), (0.0, 0.0, 1.0), 1.8, 1.0)
    assert st == OK
    # glass behind a plane, then a steep sphere: at h = 8 on R = -10 the incidence is asin(0.8) = 53 deg
    lens = _lens(Surface(thickness_mm=5.0, material=ConstantIndex(1.8), is_stop=True),
                 Surface(curvature_per_mm=-0.1, thickness_mm=5.0))
    ray = trace_reference(lens, (0.0, 8.0, -1.0), (0.0, 0.0, 1.0), WL)
    assert (ray.status, ray.surface) == (TIR, 1)
    assert ray.hits[-1].incidence_rad == pytest.approx(math.asin(0.8), abs=1e-12)
    assert trace_reference(lens, (0.0, 5.0, -1.0), (0.0, 0.0, 1.0), WL).status == OK


def test_vignetting_reports_the_surface():
    lens = _lens(Surface(thickness_mm=5.0, semi_diameter_mm=10.0),
                 Surface(thickness_mm=5.0, semi_diameter_mm=4.0, is_stop=True), Surface(thickness_mm=5.0))
    assert trace_reference(lens, (0.0, 3.9, 0.0), (0, 0, 1), WL).status == OK
    r = trace_reference(lens, (0.0, 4.1, 0.0), (0, 0, 1), WL)
    assert (r.status, r.surface) == (VIGNETTED, 1)
    r = trace_reference(lens, (0.0, 4.1, 0.0), (0, 0, 1), WL, clip=False)
    assert r.status == OK


@pytest.mark.parametrize("blades", [5, 6, 7, 9])
def test_iris_polygon(blades):
    R, rot = 10.0, math.radians(12.0)
    iris = Iris(blades=blades, rotation_rad=rot)
    half = math.pi / blades
    # vertices (at the rotation angle) reach R; mid-edges only R cos(pi/N)
    for k in range(blades):
        a = rot + 2 * half * k
        assert inside_iris(0.999 * R * math.cos(a), 0.999 * R * math.sin(a), R, iris)
        assert not inside_iris(1.001 * R * math.cos(a), 1.001 * R * math.sin(a), R, iris)
        m = a + half
        r_edge = R * math.cos(half)
        assert inside_iris(0.999 * r_edge * math.cos(m), 0.999 * r_edge * math.sin(m), R, iris)
        assert not inside_iris(1.001 * r_edge * math.cos(m), 1.001 * r_edge * math.sin(m), R, iris)
    # area by Monte Carlo equals the N-gon's (N/2) R^2 sin(2 pi / N)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-R, R, size=(40000, 2))
    frac = np.mean([inside_iris(x, y, R, iris) for x, y in pts])
    area = frac * (2 * R) ** 2
    exact = 0.5 * blades * R * R * math.sin(2 * math.pi / blades)
    se = math.sqrt(frac * (1 - frac) / len(pts)) * (2 * R) ** 2
    assert abs(area - exact) < 4 * se


def test_iris_roundness_and_obstruction():
    R = 5.0
    round_iris = Iris(blades=6, roundness=1.0)
    m = math.pi / 6  # a mid-edge direction
    assert inside_iris(0.99 * R * math.cos(m), 0.99 * R * math.sin(m), R, round_iris)
    assert not inside_iris(0.99 * R * math.cos(m), 0.99 * R * math.sin(m), R, Iris(blades=6))
    ob = Iris(obstruction_ratio=0.3)
    assert not inside_iris(0.0, 1.0, R, ob)
    assert inside_iris(0.0, 2.0, R, ob)


def test_never_nan_on_bad_input():
    lens = _lens(Surface(thickness_mm=5.0, is_stop=True))
    for o, d in [((0, 0, 0), (0, 0, 0)), ((math.nan, 0, 0), (0, 0, 1)), ((0, 0, 0), (math.inf, 0, 1))]:
        r = trace_reference(lens, o, d, WL)
        assert r.status != OK
        assert math.isfinite(r.opl_mm)
