"""Scene-side Warp functions against the float64 NumPy reference and against closed forms."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import lensrt.colour as sp
from lensrt.render.spectra import WavelengthSampler
from lensrt.render.scene.load import loads_scene
from lensrt.render.scene.pack import evaluate_irradiance, evaluate_radiance, pack_scene
from lensrt.render.scene.reference import ref_intersect_sphere, ref_scene_radiance

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

SCENES = Path(__file__).resolve().parents[2] / "scenes"
HEAD = """
[scene]
units = "m"
[sensor]
pixels = [60, 40]
"""

MIXED = HEAD + """
[illumination]
spectrum = "D65"
illuminance_lux = 200
[background]
spectrum = "A"
luminance_cd_m2 = 5
[[plane]]
name = "checker"
center = [0, 0, -2]
size = [0.6, 0.4]
texture = "colorchecker"
[[plane]]
name = "edge"
center = [0.5, 0.1, -2.5]
size = [0.3, 0.3]
texture = "slanted_edge"
reflectance = { srgb = [0.9, 0.8, 0.5] }
[[plane]]
name = "star"
center = [-0.5, 0.1, -2.5]
size = [0.3, 0.3]
texture = "siemens_star"
[[plane]]
name = "grid"
center = [0, -0.35, -2.2]
size = [1.2, 0.25]
texture = "grid"
cells = [12, 3]
[[plane]]
name = "picture"
center = [0, 0.35, -2.4]
size = [0.3, 0.3]
texture = "image"
image = "textures/hue_wheel.png"
[[plane]]
name = "panel"
center = [0.2, 0.6, -1.5]
size = [0.3, 0.3]
normal = [0, -0.3, 1]
emission = { spectrum = "FL2", luminance_cd_m2 = 500 }
[[light]]
type = "point"
position = [0.1, 0.1, -1]
spectrum = { blackbody_K = 2700 }
flux_lm = 800
[[light]]
type = "sphere"
position = [-0.3, -0.1, -1.0]
radius = 0.02
spectrum = "LED-B3"
luminance_cd_m2 = 1e5
[[mesh]]
file = "models/icosphere.obj"
position = [0.25, -0.2, -1.6]
reflectance = { colorchecker = "orange" }
[[mesh]]
file = "models/cone.stl"
position = [-0.25, -0.25, -1.7]
emission = { spectrum = "A", luminance_cd_m2 = 300 }
"""


@pytest.fixture(scope="module")
def mixed():
    return loads_scene(MIXED, SCENES / "mixed_test.toml")


def _rays_toward(scene, rng, n):
    """Origins on a 40 mm disc at the lens, directions toward points scattered over the objects."""
    targets = [p.center_mm + rng.uniform(-0.55, 0.55, (n, 1)) * p.size_mm[0] * p.right
               + rng.uniform(-0.55, 0.55, (n, 1)) * p.size_mm[1] * p.up for p in scene.planes]
    targets += [m.vertices_mm[rng.integers(0, len(m.vertices_mm), n)] * 1.0 + rng.normal(0, 5, (n, 3))
                for m in scene.meshes]
    targets += [s.center_mm + rng.normal(0, s.radius_mm, (n, 3)) for s in scene.sphere_lights]
    allt = np.concatenate(targets)
    pick = allt[rng.integers(0, len(allt), n)]
    o = np.column_stack([rng.uniform(-20, 20, (n, 2)), np.zeros(n)])
    d = pick - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


def test_radiance_matches_float64_reference(mixed, device):
    rng = np.random.default_rng(11)
    n = 600
    o, d = _rays_toward(mixed, rng, n)
    lam = rng.uniform(380, 780, n)
    u = rng.random((n, 3))
    packed = pack_scene(mixed, device)
    got = evaluate_radiance(packed, o, d, lam, u)
    ref = np.array([ref_scene_radiance(mixed, o[i], d[i], lam[i], u[i]) for i in range(n)])
    assert np.all(np.isfinite(got))
    scale = np.maximum(np.abs(ref), 1e-3 * np.abs(ref).max())
    rel = np.abs(got - ref) / scale
    # float32 against float64: the few rays that straddle an edge (texture, plane rim, shadow
    # boundary) may differ; everything else agrees to float32 accuracy
    assert np.mean(rel < 1e-4) > 0.98, np.sort(rel)[-10:]
    assert (ref > 0).sum() > n // 2


def test_no_bvh_without_meshes(device):
    s = loads_scene(HEAD + '[background]\nspectrum = "D65"\nluminance_cd_m2 = 1\n')
    packed = pack_scene(s, device)
    assert packed.mesh is None and packed.data.has_mesh == 0
    got = evaluate_radiance(packed, np.zeros((2, 3)), np.array([[0, 0, -1.0], [0.1, 0, -1.0]]), np.array([560.0, 560.0]),
                            np.zeros((2, 3)))
    assert got == pytest.approx([s.background.at(s.grid, 560.0)] * 2, rel=1e-6)


def test_uniform_illumination_lambertian(device):
    s = loads_scene(HEAD + """
[illumination]
spectrum = "D65"
illuminance_lux = 1000
[[plane]]
center = [0, 0, -2]
size = [1, 1]
reflectance = 0.5
""")
    lam = np.array([450.0, 550.0, 650.0])
    got = evaluate_radiance(pack_scene(s, device), np.zeros((3, 3)), np.tile([0, 0, -1.0], (3, 1)), lam,
                            np.zeros((3, 3)))
    assert got == pytest.approx(0.5 * s.illumination.at(s.grid, lam) / math.pi, rel=1e-5)
    # its luminance: rho E / pi in cd/m^2
    lv = sp.luminous_value(0.5 * s.illumination.values / math.pi, s.grid)
    assert lv == pytest.approx(0.5 * 1000 / math.pi, rel=1e-9)


def test_point_light_inverse_square_cosine_and_shadow(device):
    s = loads_scene(HEAD + """
[[light]]
type = "point"
position = [0, 0, -1]
spectrum = "E"
intensity_scale = 2.0
[[plane]]
name = "blocker"
center = [0.5, 0, -1.5]
size = [0.2, 0.2]
reflectance = 0.5
""")
    packed = pack_scene(s, device)
    pts = np.array([[0, 0, -3000.0], [1000, 0, -3000.0], [0, 500, -2000.0], [1000, 0, -2000.0]])
    nrm = np.tile([0, 0, 1.0], (4, 1))
    e = evaluate_irradiance(packed, pts, nrm, np.full(4, 550.0), np.full((4, 3), 0.5))
    i_w = float(s.point_lights[0].intensity.at(s.grid, 550.0))  # W/(sr nm): 2 x the E illuminant's 100
    for k in range(3):
        v = np.array([0, 0, -1000.0]) - pts[k]
        d_m = np.linalg.norm(v) / 1000.0
        assert e[k] == pytest.approx(i_w / d_m ** 2 * v[2] / np.linalg.norm(v), rel=1e-5)
    assert e[3] == 0.0                                          # behind the blocker at z = -1.5 m


def test_sphere_light_irradiance_closed_form(device):
    # E = pi L sin^2(theta_max) cos(beta) for a sphere wholly above the surface's horizon;
    # a 5 mm sphere 10 m away tests the cancellation-free cone sampling in float32
    rng = np.random.default_rng(3)
    for radius_m, dist_m, beta in ((0.005, 10.0, 0.0), (0.2, 1.0, 0.6)):
        s = loads_scene(HEAD + f"""
[[light]]
type = "sphere"
position = [0, 0, -{dist_m + 1}]
radius = {radius_m}
spectrum = "E"
radiance_scale = 1.0
""")
        n = 20000
        p = np.tile([0, 0, -1000.0], (n, 1))
        nrm = np.tile([math.sin(beta), 0, -math.cos(beta)], (n, 1))
        e = evaluate_irradiance(pack_scene(s, device), p, nrm, np.full(n, 550.0), rng.random((n, 3)))
        exact = math.pi * (radius_m / dist_m) ** 2 * math.cos(beta) * float(s.sphere_lights[0].radiance.at(s.grid, 550))
        se = e.std(ddof=1) / math.sqrt(n)
        assert abs(e.mean() - exact) < max(4 * se, 1e-5 * exact), (e.mean(), exact, se)


def test_emissive_rectangle_irradiance_closed_form(device):
    # irradiance on the axis of a parallel a x b rectangle at distance c: E = pi L F, with the
    # corner view factor F = 1/(2 pi) [A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + B/sqrt(1+B^2) atan(A/sqrt(1+B^2))]
    s = loads_scene(HEAD + """
[[plane]]
center = [0, 0, -3]
size = [0.6, 0.4]
emission = { spectrum = "E", radiance_scale = 1.0 }
""")
    def corner(a, b, c):
        A, B = a / c, b / c
        return (A / math.sqrt(1 + A * A) * math.atan(B / math.sqrt(1 + A * A))
                + B / math.sqrt(1 + B * B) * math.atan(A / math.sqrt(1 + B * B))) / (2 * math.pi)
    lum = float(s.planes[0].emission.at(s.grid, 550.0))
    exact = math.pi * 4 * corner(0.3, 0.2, 0.5) * lum
    n = 40000
    rng = np.random.default_rng(5)
    e = evaluate_irradiance(pack_scene(s, device), np.tile([0, 0, -2500.0], (n, 1)), np.tile([0, 0, -1.0], (n, 1)),
                            np.full(n, 550.0), rng.random((n, 3)))
    se = e.std(ddof=1) / math.sqrt(n)
    assert abs(e.mean() - exact) < 4 * se, (e.mean(), exact, se)
    # the back of an emissive plane is black; its front shows the radiance
    got = evaluate_radiance(pack_scene(s, device), np.array([[0, 0, 0.0], [0, 0, -5000.0]]),
                            np.array([[0, 0, -1.0], [0, 0, 1.0]]), np.full(2, 550.0), np.zeros((2, 3)))
    assert got == pytest.approx([lum, 0.0], rel=1e-6)


def test_small_far_sphere_hit_in_float32(device):
    s = loads_scene(HEAD + """
[[light]]
type = "sphere"
position = [0, 0, -10]
radius = 0.005
spectrum = "E"
radiance_scale = 1.0
""")
    rng = np.random.default_rng(9)
    n = 2000
    o = np.column_stack([rng.uniform(-20, 20, (n, 2)), np.zeros(n)])
    aim = np.column_stack([rng.uniform(-6, 6, (n, 2)), np.full(n, -10000.0)])
    d = aim - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    got = evaluate_radiance(pack_scene(s, device), o, d, np.full(n, 550.0), np.zeros((n, 3)))
    hit = np.array([ref_intersect_sphere(o[i], d[i], np.array([0, 0, -10000.0]), 5.0) is not None for i in range(n)])
    # miss distance from the centre, to keep clear of the rim where float32 may legitimately differ
    f = o - np.array([0, 0, -10000.0])
    miss = np.linalg.norm(f - np.sum(f * d, axis=1)[:, None] * d, axis=1)
    clear = np.abs(miss - 5.0) > 0.01
    assert hit[clear].sum() > 300
    assert np.array_equal(got[clear] > 0, hit[clear])


def test_wavelength_sampler_kernel_matches_numpy(device):
    from lensrt.device import warp
    from lensrt.render.scene.kernels import sample_wavelength_kernel
    wp = warp()
    g = sp.DEFAULT_GRID
    s = WavelengthSampler.from_weight(g, sp.spectrum("FL11", g) * sp.cie_xyz_cmfs(g)[1])
    u = np.random.default_rng(1).random(5000)
    out = wp.zeros(u.size, dtype=wp.vec2, device=device)
    wp.launch(sample_wavelength_kernel, dim=u.size, inputs=[wp.array(s.cdf.astype(np.float32), dtype=float,
              device=device), g.min_nm, g.step_nm, wp.array(u.astype(np.float32), dtype=float, device=device), out],
              device=device)
    got = out.numpy()
    lam, pdf = s.sample(u.astype(np.float32).astype(np.float64))
    ok = np.abs(got[:, 0] - lam) < 1e-3
    assert ok.mean() > 0.999                     # float32 cdf vs float64 at bin boundaries
    assert np.allclose(got[ok, 1], pdf[ok], rtol=1e-4)
