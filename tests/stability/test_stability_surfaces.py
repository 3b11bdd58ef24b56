"""Stability of single surfaces: nearly flat, nearly concentric, hemispheres, TIR, misses,
the axis and aperture edges -- each against a closed form or the float64 reference tracer.

Stated tolerances (mm unless said):

=====================================  ==============  ==============
case                                    float64         float32
=====================================  ==============  ==============
hit point on \\|R\\| = 1e4..1e9 surfaces   1e-12 (sag)     2e-6
image through them (vs float64)         --              1e-5
concentric meniscus, through centre     1e-12           1e-5 (dir 1e-6)
nearly concentric, random rays          1e-10 (ref.)    1e-4
hemisphere exit direction (Snell)       1e-12           1e-6 (I' < 80 deg)
TIR threshold h_c = R / n               exact           +-1e-5 h_c
axial ray: x = y = 0, L = M = 0         exact (bits)    exact (bits)
axial OPL = sum n_i t_i                 1e-12 rel       1e-6 rel
aperture edge r = sd (1 + delta)        pass iff delta <= 1e-6 (both), |delta - 1e-6| >= 3e-7
=====================================  ==============  ==============
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from stability_cases import F32_BOUND_MM, WL_D, collimated, finite, library, system

from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Iris, Surface
from lensrt.trace import RayBatch, trace
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import APERTURE_TOLERANCE, GRAZING_COS, MISSED, OK, TIR, VIGNETTED

GLASS = ConstantIndex(1.5)


# ---------------------------------------------------------------------------------------------
# nearly flat surfaces


def _flat_lens(radius_mm: float | None):
    c = 0.0 if radius_mm is None else 1.0 / radius_mm
    return system(Surface(curvature_per_mm=c, thickness_mm=5.0, material=GLASS, is_stop=True, semi_diameter_mm=25.0),
                  Surface(thickness_mm=50.0, semi_diameter_mm=30.0))


def _naive_float32_sphere_hit(o: np.ndarray, d: np.ndarray, radius_mm: float) -> np.ndarray:
    """The textbook intersection with a sphere centred at (0, 0, R), in float32: what the
    cancellation-free form avoids (it subtracts numbers of size R^2)."""
    R = np.float32(radius_mm)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    oc = o32 - np.array([0.0, 0.0, R], dtype=np.float32)
    b = np.sum(oc * d32, axis=1)
    cc = np.sum(oc * oc, axis=1) - R * R
    root = np.sqrt(np.maximum(b * b - cc, np.float32(0.0)))
    t = -b - root if radius_mm > 0 else -b + root
    return (o32 + t[:, None] * d32).astype(np.float64)


FLAT_RADII = (1e4, 1e5, 1e6, 1e7, 1e8, 1e9, -1e4, -1e6, -1e9)


@pytest.fixture(scope="module")
def flat_rays() -> RayBatch:
    o, d = collimated(np.linspace(-20.0, 20.0, 41), z_mm=-1.0, angle_rad=math.radians(10.0))
    return RayBatch(o, d, WL_D)


@pytest.mark.parametrize("radius_mm", FLAT_RADII)
def test_nearly_flat_surface_intersection(radius_mm, flat_rays, device):
    lens = _flat_lens(radius_mm)
    h64 = trace(lens, flat_rays, "float64", device, end=0).position_mm
    h32 = trace(lens, flat_rays, "float32", device, end=0).position_mm
    # float64: the hit lies on the surface (closed-form sag at its height) ...
    r2 = h64[:, 0] ** 2 + h64[:, 1] ** 2
    sag = r2 / radius_mm / (1.0 + np.sqrt(1.0 - r2 / radius_mm**2))
    assert np.max(np.abs(h64[:, 2] - sag)) < 1e-12
    # ... float32 finds the same point to a few ulp of the coordinates (20 mm: 1.2e-6 per ulp) ...
    assert np.max(np.abs(h32 - h64)) < 2e-6
    # ... where the textbook float32 sphere intersection is off by > 5e-4 mm (1 mm from 1e8 on)
    naive = _naive_float32_sphere_hit(flat_rays.origin_mm, flat_rays.direction, radius_mm)
    assert np.max(np.abs(naive - h64)) > 5e-4


def test_nearly_flat_surfaces_approach_the_plane(flat_rays, device):
    """Through the whole lens: the float64 image moves from the plane's as 1/R (a surface power
    (n - 1)/R; |dy| R is the same constant from 1e4 to 1e9 mm, down to 6e-7 mm), and float32
    stays within 1e-5 mm of float64 at every radius."""
    plane = trace(_flat_lens(None), flat_rays, "float64", device).position_mm
    scaled = []
    for radius_mm in FLAT_RADII:
        lens = _flat_lens(radius_mm)
        r64 = trace(lens, flat_rays, "float64", device)
        r32 = trace(lens, flat_rays, "float32", device)
        assert r64.ok.all() and r32.ok.all()
        assert np.max(np.abs(r32.position_mm - r64.position_mm)) < 1e-5
        scaled.append(np.max(np.abs(r64.position_mm - plane)) * abs(radius_mm))
    assert max(scaled) / min(scaled) < 1.01


# ---------------------------------------------------------------------------------------------
# a nearly concentric meniscus


def _meniscus(eps_mm: float):
    """R1 = 20 mm, 3 mm of n = 1.6, R2 = 17 + eps mm: concentric about z = 20 when eps = 0;
    image plane at z = 43 (23 mm beyond the common centre)."""
    g = ConstantIndex(1.6)
    return system(Surface(curvature_per_mm=1 / 20.0, thickness_mm=3.0, material=g, is_stop=True,
                          semi_diameter_mm=15.0),
                  Surface(curvature_per_mm=1 / (17.0 + eps_mm), thickness_mm=40.0, semi_diameter_mm=13.0))


def _through_centre(angles_deg: np.ndarray, centre_z_mm: float = 20.0) -> RayBatch:
    a = np.radians(angles_deg)
    d = np.stack([np.zeros_like(a), np.sin(a), np.cos(a)], axis=1)
    o = np.array([0.0, 0.0, centre_z_mm]) - 40.0 * d
    return RayBatch(o, d, WL_D)


@pytest.mark.parametrize("precision,tol_mm,tol_dir", [("float64", 1e-12, 1e-14), ("float32", 1e-5, 1e-6)])
def test_concentric_meniscus_passes_rays_through_its_centre_undeviated(precision, tol_mm, tol_dir, device):
    angles = np.array([0.0, 5.0, 15.0, 25.0, 30.0, -20.0])
    rays = _through_centre(angles)
    res = trace(_meniscus(0.0), rays, precision, device)
    assert res.ok.all()
    np.testing.assert_allclose(res.direction, rays.direction, rtol=0, atol=tol_dir)
    np.testing.assert_allclose(res.min_cos_incidence, 1.0, rtol=0, atol=tol_dir)
    # closed form: the line through (0, 0, 20) reaches z = 43 at y = 23 tan(theta)
    np.testing.assert_allclose(res.position_mm[:, 1], 23.0 * np.tan(np.radians(angles)), rtol=0, atol=tol_mm)


@pytest.mark.parametrize("eps_mm", [1e-9, 1e-6, 1e-3])
def test_nearly_concentric_meniscus_float32(eps_mm, device):
    """Slightly off concentric, random rays up to 30 deg: float32 within the general bound of the
    float64 kernel (the strongly curved surfaces, R = 20 mm, and 40 mm to the image make it
    ~3e-5 mm), which equals the reference tracer; through the centre the deviation grows
    linearly with eps."""
    lens = _meniscus(eps_mm)
    rng = np.random.default_rng(3)
    a = np.radians(rng.uniform(-30, 30, 200))
    d = np.stack([np.zeros_like(a), np.sin(a), np.cos(a)], axis=1)
    o = np.stack([np.zeros_like(a), rng.uniform(-8, 8, 200), np.full_like(a, -5.0)], axis=1)
    rays = RayBatch(o, d, WL_D)
    r64 = trace(lens, rays, "float64", device)
    r32 = trace(lens, rays, "float32", device)
    both = r64.ok & r32.ok
    assert both.sum() > 150 and np.array_equal(r64.status, r32.status)
    assert np.max(np.abs(r32.position_mm[both] - r64.position_mm[both])) < F32_BOUND_MM
    for i in range(0, 200, 20):
        ref = trace_reference(lens, o[i], d[i], WL_D)
        assert ref.status == r64.status[i]
        assert abs(ref.y_mm - r64.position_mm[i, 1]) < 1e-10
    centre = trace(lens, _through_centre(np.array([20.0])), "float64", device)
    assert abs(centre.position_mm[0, 1] - 23.0 * math.tan(math.radians(20.0))) < 100 * eps_mm + 1e-12


# ---------------------------------------------------------------------------------------------
# hemispheres: the clear aperture reaches the radius; total internal reflection


def _hemisphere_exit(n: float = 1.5, radius_mm: float = 10.0):
    """Plane front (the stop), 10 mm of glass, rear surface R = -10 mm with sd = |R|: a solid
    hemisphere, its rim on the plane."""
    g = ConstantIndex(n)
    return system(Surface(thickness_mm=radius_mm, material=g, is_stop=True, semi_diameter_mm=radius_mm),
                  Surface(curvature_per_mm=-1.0 / radius_mm, thickness_mm=20.0, semi_diameter_mm=radius_mm))


def _hemisphere_entry(n: float = 1.5, radius_mm: float = 10.0):
    """Front surface R = +10 mm, sd = |R| (its rim at z = 10), then glass to a plane."""
    g = ConstantIndex(n)
    return system(Surface(curvature_per_mm=1.0 / radius_mm, thickness_mm=12.0, material=g, is_stop=True,
                          semi_diameter_mm=radius_mm),
                  Surface(thickness_mm=20.0, semi_diameter_mm=30.0))


@pytest.mark.parametrize("kernel", ["generic", "specialised"])
@pytest.mark.parametrize("precision,tol_dir", [("float64", 1e-12), ("float32", 1e-6)])
def test_hemisphere_exit_snell_and_total_internal_reflection(precision, tol_dir, kernel, device):
    """Collimated rays at height h leave the hemisphere at sin I = h / R, sin I' = n h / R;
    beyond h_c = R / n they are totally reflected at surface 2 (index 1)."""
    n, R = 1.5, 10.0
    h_c = R / n
    h = np.concatenate([np.linspace(0.0, h_c * (1 - 1e-5), 60), np.linspace(6.58, 6.66, 5),
                        np.linspace(h_c * (1 + 1e-5), R * (1 - 1e-6), 40)])
    o, d = collimated(h)
    lens = _hemisphere_exit(n, R)
    res = trace(lens, RayBatch(o, d, WL_D), precision, device, kernel=kernel)
    assert finite(res.position_mm, res.direction, res.opl_mm)
    below = h < h_c
    assert np.all(res.status[below] == OK)
    assert np.all((res.status[~below] == TIR) & (res.surface[~below] == 1))
    # where the TIR rays stopped: on the sphere, z = sqrt(R^2 - h^2) (frame of the first vertex);
    # near the rim that is ill-conditioned (dz = d(h^2) / 2z: 3e-4 mm in float32 at h = R (1 - 1e-6)),
    # so the closed form is checked where the incidence is below 80 deg
    steady = ~below & (h < R * math.sin(math.radians(80.0)))
    np.testing.assert_allclose(res.position_mm[steady, 2], np.sqrt(R * R - h[steady] ** 2), atol=20 * tol_dir)
    assert np.all(res.min_cos_incidence[~below & ~steady] < GRAZING_COS)
    # exit directions: turned toward the axis by I' - I (checked where I' < 80 deg: just short of
    # TIR, I' -> 90 deg, the refraction is ill-conditioned -- 7e-6 in float32 at h = h_c (1 - 1e-5))
    s = h[below] / R
    dev = np.arcsin(n * s) - np.arcsin(s)
    leaves_steep = np.arcsin(np.minimum(n * s, 1.0)) > math.radians(80.0) + 1e-4
    leaves_ok = np.arcsin(np.minimum(n * s, 1.0)) < math.radians(80.0) - 1e-4
    np.testing.assert_allclose(res.direction[below, 1][leaves_ok], -np.sin(dev[leaves_ok]), atol=tol_dir)
    np.testing.assert_allclose(res.direction[below, 2][leaves_ok], np.cos(dev[leaves_ok]), atol=tol_dir)
    # rays that leave at more than 80 deg (h > R sin 80 / n) are flagged grazing
    assert leaves_steep.sum() >= 2
    assert np.all(res.grazing[below][leaves_steep]) and not np.any(res.grazing[below][leaves_ok])
    # the ray along the rim (h = R) meets the sphere tangentially: TIR or MISSED, never NaN
    rim = trace(lens, RayBatch(*collimated(np.array([R])), WL_D), precision, device, kernel=kernel)
    assert rim.status[0] in (TIR, MISSED) and finite(rim.position_mm, rim.direction)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_hemisphere_entry_to_the_rim(precision, device):
    """Air into a hemisphere whose clear aperture reaches its radius: up to the rim the rays
    enter (grazing near the rim, where cos I -> 0), no NaN; beyond it they miss. Exactly at the
    rim (tangent) the ray enters or misses, as the reference tracer decides."""
    R = 10.0
    h = np.array([0.0, 5.0, 9.0, 9.8, 9.99, 9.9999, R, R * (1 + 1e-4), 10.5])
    o, d = collimated(h)
    lens = _hemisphere_entry(1.5, R)
    res = trace(lens, RayBatch(o, d, WL_D), precision, device, end=1)
    assert finite(res.position_mm, res.direction, res.opl_mm, res.min_cos_incidence)
    assert np.all(res.status[:6] == OK) and res.status[6] in (OK, MISSED)
    assert np.all((res.status[7:] == MISSED) & (res.surface[7:] == 0))
    # the entry height and the closed-form refraction sin I' = sin I / n into the glass
    s = h[:6] / R
    refr = np.arcsin(s) - np.arcsin(s / 1.5)
    tol = 1e-12 if precision == "float64" else 2e-6
    np.testing.assert_allclose(res.direction[:6, 1], -np.sin(refr), atol=50 * tol)
    assert res.grazing[5] and not res.grazing[2]
    ref = [trace_reference(lens, o[i], d[i], WL_D, end=1) for i in range(len(h))]
    assert [r.status for r in ref][:6] == list(res.status)[:6]
    assert [r.status for r in ref][7:] == list(res.status)[7:]


# ---------------------------------------------------------------------------------------------
# misses, the axis, aperture edges


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_rays_that_miss(precision, device):
    """Beyond a sphere's extent (h > |R|) and parallel to a plane: MISSED at that surface,
    with a finite position (where the ray was) and its direction unchanged."""
    o = np.array([[0.0, 12.0, -1.0], [3.0, -20.0, -1.0], [0.0, 0.0, -1.0]])
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    for lens, rows in ((_hemisphere_entry(1.5, 10.0), [0, 1]), (_flat_lens(None), [2])):
        res = trace(lens, RayBatch(o[rows], d[rows], WL_D), precision, device, clip=False)
        assert np.all(res.status == MISSED) and np.all(res.surface == 0)
        np.testing.assert_array_equal(res.direction, d[rows])
        np.testing.assert_array_equal(res.position_mm, o[rows])
        assert finite(res.opl_mm)


LIBRARY_NAMES = ("codev_dblgauss_100mm_f2", "cooke_triplet_50mm_f5", "fisheye_10mm_f4", "nikkor_28mm_f1.4_asph",
                 "micro_nikkor_105mm_f2.8_macro", "telephoto_250mm_f5.6")


@pytest.mark.parametrize("name", LIBRARY_NAMES)
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_axial_ray_stays_exactly_on_the_axis(name, precision, device):
    """x = y = 0 and L = M = 0 exactly (bit for bit: every step maps zeros to zeros), and the
    optical path is sum n_i t_i."""
    lens = library(name)
    wl = np.array(lens.wavelengths.nm)
    o = np.zeros((len(wl), 3))
    if not math.isinf(lens.object_distance_mm):
        o[:, 2] = -lens.object_distance_mm
    d = np.tile([0.0, 0.0, 1.0], (len(wl), 1))
    res = trace(lens, RayBatch(o, d, wl), precision, device)
    assert res.ok.all()
    assert np.all(res.position_mm[:, :2] == 0.0) and np.all(res.direction[:, :2] == 0.0)
    assert np.all(res.direction[:, 2] == 1.0)
    n = lens.indices(wl)
    t = np.array([-o[0, 2]] + [s.thickness_mm for s in lens.surfaces])
    want = n @ t
    rel = 1e-12 if precision == "float64" else 1e-6
    np.testing.assert_allclose(res.opl_mm, want, rtol=rel)


def _edge_lens(where: str = "stop", blades: int = 0):
    """A plane stop and a plane window 2 mm behind it; the one named by ``where`` has a clear
    radius of 5 mm (a stop of ``blades``), the other 50 mm."""
    r_stop, r_window = (5.0, 50.0) if where == "stop" else (50.0, 5.0)
    stop = Surface(thickness_mm=2.0, is_stop=True, semi_diameter_mm=r_stop)
    window = Surface(thickness_mm=2.0, material=GLASS, semi_diameter_mm=r_window)
    lens = system(stop, window, Surface(thickness_mm=10.0, semi_diameter_mm=80.0))
    return lens.replace(iris=Iris(blades=blades))


#: relative offsets from the edge: the convention is r <= sd (1 + APERTURE_TOLERANCE) passes
EDGE_DELTAS = np.array([-1e-3, -1e-6, -1e-7, 0.0, 1e-7, 5e-7, 7e-7, 1.3e-6, 2e-6, 1e-5, 1e-3])


@pytest.mark.parametrize("where", ["stop", "window"])
def test_aperture_edge_decided_the_same_in_both_precisions(where, device):
    """A ray exactly at the clear aperture passes, in float32 and float64 alike; the boundary is
    r = sd (1 + 1e-6), and both precisions decide every ray at least 3e-7 (relative) away from it
    the same way (float32 resolves r to 6e-8). Azimuths all round the circle."""
    assert APERTURE_TOLERANCE == 1e-6
    lens = _edge_lens(where)
    phi = np.radians(np.arange(0.0, 360.0, 22.5))
    r = 5.0 * (1.0 + EDGE_DELTAS)
    R, P = np.meshgrid(r, phi, indexing="ij")
    x, y = (R * np.cos(P)).ravel(), (R * np.sin(P)).ravel()
    # meet the stop (z = 0) or the window (z = 2) at exactly that radius, slightly inclined
    z_at = 0.0 if where == "stop" else 2.0
    d = np.tile([0.01, -0.02, 1.0], (len(x), 1))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.stack([x, y, np.full_like(x, z_at)], axis=1) - 3.0 * d
    rays = RayBatch(o, d, WL_D)
    want = np.repeat(EDGE_DELTAS <= APERTURE_TOLERANCE, len(phi))
    surface = 0 if where == "stop" else 1
    for precision in ("float64", "float32"):
        res = trace(lens, rays, precision, device)
        np.testing.assert_array_equal(res.status == OK, want, err_msg=precision)
        assert np.all(res.surface[~want] == surface)
        assert np.all(res.status[~want] == VIGNETTED)


def test_iris_blade_edge_consistent(device):
    """A 6-blade iris: points on a blade edge (the inscribed circle at the middle of each blade,
    the circle's radius at the vertices) pass in both precisions; points 1e-5 outside do not."""
    lens = _edge_lens("stop", blades=6)
    half = math.pi / 6
    phi = np.arange(6) * 2 * half
    pts = []
    for scale in (1.0, 1.0 + 1e-5):
        for p in phi:  # vertices, at the stop radius
            pts.append((5.0 * scale * math.cos(p), 5.0 * scale * math.sin(p)))
            m = p + half  # middle of a blade, at the inscribed radius R cos(pi / N)
            rho = 5.0 * math.cos(half) * scale
            pts.append((rho * math.cos(m), rho * math.sin(m)))
    pts = np.array(pts)
    o = np.column_stack([pts, np.full(len(pts), -1.0)])
    d = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    want = np.r_[np.ones(12, bool), np.zeros(12, bool)]
    for precision in ("float64", "float32"):
        res = trace(lens, RayBatch(o, d, WL_D), precision, device)
        np.testing.assert_array_equal(res.status == OK, want, err_msg=precision)
    ref = [trace_reference(lens, o[i], d[i], WL_D).status == OK for i in range(len(pts))]
    np.testing.assert_array_equal(ref, want)


def test_grazing_threshold_constant():
    assert GRAZING_COS == pytest.approx(math.cos(math.radians(80.0)))
