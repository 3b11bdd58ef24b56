"""The render planner: the plan of every built-in scene, and the lens-dependent decisions."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from lensrt.render.spectra import WavelengthSampler
from lensrt.render.plan import plan_render, wavelength_weight
from lensrt.render.scene.load import builtin_scenes, load_scene, loads_scene

pytestmark = pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")

#: scene -> (splat, spectral, mesh, direct_lighting, sensor_stage, sensor_noise, sampling)
EXPECTED = {
    "default": (False, True, False, True, False, False, "scene x cie"),
    "night_street": (True, True, False, False, False, False, "scene x cie"),
    "resolution_chart": (False, True, False, False, False, False, "scene x cie"),
    "colorchecker_d65": (False, True, False, False, True, True, "scene x camera"),
    "colorchecker_a": (False, True, False, False, True, True, "scene x camera"),
    "depth_of_field": (False, True, False, False, False, False, "scene x cie"),
    "still_life_mesh": (False, True, True, True, False, False, "scene x cie"),
    "sodium_star_test": (True, False, False, False, False, False, "fixed"),
}


def test_every_builtin_scene_has_an_expected_plan():
    assert {p.stem for p in builtin_scenes()} == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_plan_of_builtin_scene(name):
    scene = load_scene(name)
    plan = plan_render(scene)
    v = plan.variant
    got = (v.splat, v.spectral, v.mesh, v.direct_lighting, plan.sensor_stage, plan.sensor_noise,
           plan.wavelength_sampling)
    assert got == EXPECTED[name]
    assert plan.build_bvh == (scene.n_triangles > 0)
    assert ("BVH build" in plan.stages) == plan.build_bvh
    assert any(stage == "BVH build" for stage, _ in plan.skipped) != plan.build_bvh
    assert not v.diffraction                      # no lens given: auto stays off unless the f-number says so
    text = plan.describe()
    assert text.startswith(f"render plan for scene {name!r}") and v.name in text
    json.dumps(plan.to_dict())                    # plain data


def test_monochromatic_plans():
    plan = plan_render(load_scene("sodium_star_test"))
    assert plan.wavelength_nm == pytest.approx(589.3) and plan.output_unit == "W/m^2"
    assert plan.variant.name == "splat_mono_analytic"
    s = loads_scene(_LIT + '[spectral]\nmode = "monochromatic"\nwavelength_nm = 546.1\n')
    plan = plan_render(s)
    assert not plan.spectral and plan.wavelength_nm == 546.1 and plan.output_unit == "W/(m^2 nm)"


_LIT = """
[illumination]
spectrum = "D65"
illuminance_lux = 1000
[[plane]]
center = [0, 0, -2]
size = [1, 1]
reflectance = 0.5
"""


def test_plan_with_a_dispersive_lens_and_diffraction_auto():
    from lensrt.loading import load_lens
    lens = load_lens("codev_dblgauss_100mm_f2")
    plan = plan_render(load_scene("resolution_chart"), lens)
    assert plan.variant.lens_per_wavelength and "dispersive" in plan.reasons["lens"]
    assert plan.lens_name and "Double Gauss" in plan.describe()
    # f/5.6 at 1.5 m: bellows factor from the paraxial stage, Airy disc < 33 um pixels -> off
    assert "Airy disc" in plan.reasons["diffraction"] and not plan.variant.diffraction
    # a tiny-pixel sensor at f/16 turns it on
    s = loads_scene(_LIT + "[camera]\nf_number = 16\nfocus_distance = 2\n[sensor]\nformat = \"1/2.5-inch\"\n"
                           "pixels = [4000, 2979]\n")
    plan = plan_render(s, lens)
    airy_um = 2.44 * 0.55 * 16
    assert s.sensor.pixel_pitch_um < airy_um and plan.variant.diffraction
    assert "diffraction" in " ".join(plan.stages)


def test_plan_with_a_non_dispersive_lens_traces_once_per_path():
    from lensrt.loading import load_lens
    from lensrt.prescription.materials import ConstantIndex
    lens = load_lens("codev_dblgauss_100mm_f2")
    flat = lens.replace(surfaces=tuple(
        dataclasses.replace(s, material=ConstantIndex(float(s.material.index(587.6)))) for s in lens.surfaces))
    plan = plan_render(load_scene("default"), flat)
    assert plan.spectral and not plan.variant.lens_per_wavelength
    assert "achromatic-lens" in plan.variant.name and "non-dispersive" in plan.reasons["lens"]


def test_explicit_switches():
    s = loads_scene(_LIT + "[render]\ndiffraction = true\n[spectral]\nsampling = \"uniform\"\n")
    plan = plan_render(s)
    assert plan.variant.diffraction and plan.wavelength_sampling == "uniform"
    assert wavelength_weight(s, "uniform") is None
    s = loads_scene(_LIT + '[sensor]\npreset = "fullframe_24mp"\nnoise = false\n')
    plan = plan_render(s)
    assert plan.sensor_stage and not plan.sensor_noise
    assert ("sensor noise", "[sensor] noise = false") in plan.skipped


def test_wavelength_weight_scene_times_cie():
    s = load_scene("night_street")
    w = wavelength_weight(s, "scene x cie")
    g = s.grid
    assert w.shape == (g.n,) and np.all(w >= 0)
    # the sodium (HP1) lamps and the narrow red/green signals put weight where they emit
    i589, i450 = np.searchsorted(g.nm, 590), np.searchsorted(g.nm, 450)
    assert w[i589] > w[i450]
    sampler = WavelengthSampler.from_weight(g, w)
    assert math.isclose(sampler.probabilities.sum(), 1.0)
    with pytest.raises(ValueError):
        wavelength_weight(s, "camera")
    resp = np.ones((3, g.n))
    assert np.allclose(wavelength_weight(s, "camera", resp), 3.0)
