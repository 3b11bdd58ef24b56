"""Lenses and helpers for the numerical-stability suite (tests/test_stability_*.py).

Stated tolerances live here, next to the cases that use them, so the manual's
numerical-stability pages (docs/validation/stability.md) and the tests quote one set of numbers.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from lensrt.loading import complete_lens, load_lens
from lensrt.prescription.formats import read_lens
from lensrt.prescription.materials import AIR, ConstantIndex, Material
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths

LIBRARY = Path(__file__).resolve().parents[2] / "lens_prescriptions"

#: float64 kernel against the float64 NumPy reference (mm, direction cosines): the kernels'
#: documented agreement (tests/test_trace_kernels.py), observed ~1e-13
F64_VS_REFERENCE_MM = 1e-10
#: float32 against float64, image intercepts and OPL, rays that are not flagged grazing
#: (tests/test_trace_kernels.py::FLOAT32_BOUND_MM; docs/explanation/kernels.md, the precision table)
F32_BOUND_MM = 1e-4
#: float32 direction cosines against float64 (non-grazing rays)
F32_BOUND_DIRECTION = 1e-5
#: float32 against float64 for *any* lens, per non-grazing ray: the rounding of direction
#: cosines (6e-8) grows along the path, is magnified on the image plane by 1 / N' for a ray that
#: meets it obliquely (N': its final z direction cosine), and by refraction near grazing, where
#: dI'/dI = n cos I / (n' cos I') grows as 1 / cos: so the bound is
#: F32_RAY_BOUND_MM + F32_RAY_BOUND_PER_MM x L / (N' c) with L the ray's optical path (mm) and c the
#: smallest cosine of incidence or refraction along the ray (``RayResult.min_cos_incidence``).
#: Measured: the worst ray of the tests' 450 random lenses reached 0.46 of the bound without the
#: 1 / c term; with it, of the 40 random lenses in benchmarks/stability_table.py and the lenses
#: opened to f/0.95, 0.58 (a ray at 79 deg on the 28 mm f/1.4's hemispherical surface, which
#: reached 2.1 x the bound without the 1 / c term). The library lenses at their own apertures stay
#: below 1e-4 mm (docs/validation/stability.md).
F32_RAY_BOUND_MM = 2e-4
F32_RAY_BOUND_PER_MM = 2e-6
WL_D = 587.5618


def f32_ray_bound_mm(opl_mm: np.ndarray, n_final: np.ndarray, min_cos: np.ndarray) -> np.ndarray:
    """Per-ray float32 bound (mm): :data:`F32_RAY_BOUND_MM` + :data:`F32_RAY_BOUND_PER_MM` x L / (N' c)
    (c: the ray's smallest cosine of incidence or refraction, ``RayResult.min_cos_incidence``)."""
    L = np.abs(np.asarray(opl_mm, dtype=np.float64))
    N = np.maximum(np.abs(np.asarray(n_final, dtype=np.float64)), 1e-3)
    c = np.clip(np.asarray(min_cos, dtype=np.float64), 1e-3, 1.0)
    return F32_RAY_BOUND_MM + F32_RAY_BOUND_PER_MM * L / (N * c)


def library(name: str) -> Lens:
    return load_lens(LIBRARY / f"{name}.toml")


@lru_cache(maxsize=None)
def opened_lens(name: str, f_number: float) -> Lens:
    """A library lens re-specified at image-space f-number ``f_number`` (clear apertures recomputed).

    The file's own semi-diameters (if any) are dropped, so the real marginal rays of the
    new aperture define them (``trace/apertures.py``). A lens opened past its design is not a lens a
    user may load: the f/1.4 Nikkor at f/0.95 loses 33 of 45 of those rays, and its front element's faces
    cross inside the f/0.95 beam (at 24.6 mm), both refused by :func:`lensrt.loading.complete_lens`. For a
    study of the tracer at grazing incidence that does not matter, so this oracle builds it without the
    loader's physical checks (paraxial heights for the failed rays).
    """
    from lensrt.trace.apertures import compute_clear_apertures
    from dataclasses import replace
    raw = read_lens(LIBRARY / f"{name}.toml")
    surfaces = tuple(replace(s, semi_diameter_mm=None, semi_diameter_auto=False) for s in raw.surfaces)
    lens = raw.replace(surfaces=surfaces, aperture=Aperture("image_fno", float(f_number)),
                       name=f"{raw.name} opened to f/{f_number:g}")
    return compute_clear_apertures(lens, max_failed_fraction=1.0)


def system(*surfaces: Surface, epd_mm: float | None = None, object_mm: float = math.inf,
           wavelengths_nm: tuple[float, ...] = (WL_D,), field_deg: float = 0.0) -> Lens:
    """A small lens from explicit surfaces (float by stop unless an EPD is given)."""
    ap = Aperture("float_by_stop", 0.0) if epd_mm is None else Aperture("epd", epd_mm)
    return Lens(tuple(surfaces), aperture=ap, fields=Fields("angle", (0.0, math.radians(field_deg))),
                wavelengths=Wavelengths(wavelengths_nm), object_distance_mm=object_mm, name="stability case")


def plano_convex(n: float, radius_mm: float, thickness_mm: float, sd_mm: float, back_mm: float = 30.0,
                 material: Material | None = None) -> Lens:
    """Stop on a plane front, then a convex rear surface of radius ``radius_mm`` (< 0: convex to +z)."""
    glass = ConstantIndex(n) if material is None else material
    return system(Surface(thickness_mm=thickness_mm, material=glass, is_stop=True, semi_diameter_mm=sd_mm),
                  Surface(curvature_per_mm=1.0 / radius_mm, thickness_mm=back_mm, semi_diameter_mm=sd_mm))


def collimated(heights_mm: np.ndarray, z_mm: float = -1.0, angle_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of rays parallel to (0, sin a, cos a) crossing y = h at z = ``z_mm``."""
    h = np.asarray(heights_mm, dtype=np.float64)
    o = np.stack([np.zeros_like(h), h, np.full_like(h, z_mm)], axis=1)
    d = np.broadcast_to(np.array([0.0, math.sin(angle_rad), math.cos(angle_rad)]), o.shape).copy()
    return o, d


def finite(*arrays: np.ndarray) -> bool:
    return all(bool(np.all(np.isfinite(a))) for a in arrays)


__all__ = ["F64_VS_REFERENCE_MM", "F32_BOUND_MM", "F32_BOUND_DIRECTION", "WL_D", "library", "opened_lens",
           "system", "plano_convex", "collimated", "finite", "AIR"]


# ---------------------------------------------------------------------------------------------
# random prescriptions within physical bounds (hypothesis strategy; also used by
# benchmarks/stability_table.py)

#: glasses of the random lenses: catalog glasses whose data cover 400-700 nm, a model glass and
#: a constant index
RANDOM_GLASSES = ("N-BK7", "N-SF11", "N-LAK22", "F2", "S-LAH66", "model 1.62/36", "n=1.75")
#: smallest edge thickness of a glass element and of an air gap inside the clear aperture (mm)
MIN_EDGE_GLASS_MM = 0.5
MIN_EDGE_AIR_MM = 0.1


def random_material(key: str) -> Material:
    from lensrt.prescription.materials import ModelGlass, find_glass
    if key.startswith("model"):
        nd, vd = (float(v) for v in key.split()[1].split("/"))
        return ModelGlass(nd, vd)
    if key.startswith("n="):
        return ConstantIndex(float(key[2:]))
    return find_glass(key)


def _largest_aperture(surfaces: list[dict]) -> float:
    """Largest common semi-diameter (mm) at which no element or gap gets thinner than its minimum
    edge and every sphere stays within 0.95 |R|."""
    limit = min([0.95 / abs(s["c"]) for s in surfaces if s["c"] != 0.0] + [200.0])
    r = np.linspace(0.0, limit, 400)

    def sag(c: float) -> np.ndarray:
        return c * r * r / (1.0 + np.sqrt(np.maximum(1.0 - c * c * r * r, 0.0)))

    ok = np.ones_like(r, dtype=bool)
    for a, b in zip(surfaces[:-1], surfaces[1:]):
        gap = a["t"] + sag(b["c"]) - sag(a["c"])
        ok &= gap >= (MIN_EDGE_AIR_MM if a["glass"] is None else MIN_EDGE_GLASS_MM)
    bad = np.nonzero(~ok)[0]
    return float(r[bad[0] - 1]) if len(bad) else float(limit)


def build_random_lens(elements: list[list[tuple[float, float | None]]], gaps: list[float], stop_gap: int,
                      stop_split: float, aperture_frac: float, stop_frac: float, field_deg: float,
                      object_mm: float) -> Lens | None:
    """A lens from drawn parameters, or None when they make no usable lens.

    ``elements``: per element a list of (curvature 1/mm, glass thickness mm or None for the
    element's last surface) -- a singlet has two surfaces, a cemented doublet three; the
    glass of each layer is drawn separately (``glasses`` travel in the thickness slot as
    (t, key)). ``gaps``: air after each element (the last is replaced by the paraxial back focal
    distance). The stop is a plane in air gap ``stop_gap`` (-1: in front of the first element),
    ``stop_split`` of the way along it.
    """
    from lensrt.errors import LensrtError
    from lensrt.paraxial import first_order
    rows: list[dict] = []
    if stop_gap < 0:
        rows.append({"c": 0.0, "t": 5.0, "glass": None, "stop": True})
    for k, elem in enumerate(elements):
        for j, (c, layer) in enumerate(elem):
            last = j == len(elem) - 1
            if last:
                t, glass = gaps[k], None
            else:
                t, glass = layer
            rows.append({"c": c, "t": t, "glass": glass, "stop": False})
        if k == stop_gap and k < len(elements) - 1:
            g = rows[-1]["t"]
            rows[-1]["t"] = g * stop_split
            rows.append({"c": 0.0, "t": g * (1.0 - stop_split), "glass": None, "stop": True})
    if not any(r["stop"] for r in rows):
        rows.insert(0, {"c": 0.0, "t": 5.0, "glass": None, "stop": True})
    a_max = _largest_aperture(rows)
    if a_max < 1.0:
        return None
    sd = aperture_frac * a_max
    surfaces = []
    for r in rows:
        surfaces.append(Surface(curvature_per_mm=r["c"], thickness_mm=r["t"],
                                material=AIR if r["glass"] is None else random_material(r["glass"]),
                                semi_diameter_mm=sd * (stop_frac if r["stop"] else 1.0), is_stop=r["stop"]))
    lens = Lens(tuple(surfaces), aperture=Aperture("float_by_stop", 0.0),
                fields=Fields("angle", (0.0, math.radians(field_deg))),
                wavelengths=Wavelengths((486.1327, 587.5618, 656.2725), primary=1),
                object_distance_mm=object_mm, name="random lens")
    try:
        fo = first_order(lens)
        back = fo.image_distance_mm
    except LensrtError:
        return None
    back = back if (math.isfinite(back) and 1.0 <= back <= 1000.0) else 50.0
    try:
        return lens.replace_surface(len(surfaces) - 1, thickness_mm=back)
    except LensrtError:  # pragma: no cover - a replace that breaks the model's checks
        return None


def random_lens_strategy():
    """A hypothesis strategy of :func:`build_random_lens` lenses (None-filtered)."""
    from hypothesis import strategies as st

    curvature = st.one_of(st.just(0.0),
                          st.tuples(st.sampled_from([-1.0, 1.0]), st.floats(math.log(8.0), math.log(2000.0)))
                          .map(lambda p: p[0] * math.exp(-p[1])))
    layer = st.tuples(st.floats(1.0, 12.0), st.sampled_from(RANDOM_GLASSES))
    element = st.integers(1, 2).flatmap(
        lambda n_layers: st.tuples(st.lists(st.tuples(curvature, layer), min_size=n_layers, max_size=n_layers),
                                   curvature)
        .map(lambda p: p[0] + [(p[1], None)]))

    @st.composite
    def lenses(draw):
        elems = draw(st.lists(element, min_size=1, max_size=3))
        gaps = draw(st.lists(st.floats(0.5, 20.0), min_size=len(elems), max_size=len(elems)))
        stop_gap = draw(st.integers(-1, max(len(elems) - 2, -1)))
        lens = build_random_lens(elems, gaps, stop_gap, draw(st.floats(0.2, 0.8)), draw(st.floats(0.3, 1.0)),
                                 draw(st.floats(0.3, 1.0)), draw(st.floats(0.0, 30.0)),
                                 draw(st.sampled_from([math.inf, math.inf, 1e9, 2000.0, 300.0])))
        return lens

    return lenses().filter(lambda lens: lens is not None)


def random_rays(lens: Lens, n_named: int, n_free: int, seed: int):
    """Named rays (fields 0, 0.5, 1 of the lens, pupil [-1.2, 1.2]^2, paraxial aim, 450-650 nm)
    and free rays (origins around the front, directions up to 60 deg off axis, some backwards)."""
    from lensrt.trace import RayBatch, make_rays
    rng = np.random.default_rng(seed)
    hy = rng.choice([0.0, 0.5, 1.0], n_named)
    hx = np.where(rng.random(n_named) < 0.3, rng.uniform(-0.7, 0.7, n_named), 0.0)
    px, py = rng.uniform(-1.2, 1.2, n_named), rng.uniform(-1.2, 1.2, n_named)
    wl = rng.uniform(450.0, 650.0, n_named)
    named = make_rays(lens, hx, hy, px, py, wl, aim="paraxial", device="cpu")
    sd = max(s.semi_diameter_mm for s in lens.surfaces)
    o = np.column_stack([rng.uniform(-sd, sd, (n_free, 2)), rng.uniform(-20.0, 0.0, n_free)])
    theta = np.radians(rng.uniform(0.0, 60.0, n_free))
    phi = rng.uniform(0.0, 2 * math.pi, n_free)
    d = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    d[: n_free // 10] *= -1.0  # a few travel away from the lens
    origins = np.vstack([named.origin_mm, o])
    dirs = np.vstack([named.direction, d])
    waves = np.concatenate([named.wavelength_nm, rng.uniform(450.0, 650.0, n_free)])
    return RayBatch(origins, dirs, waves)


def random_lens_numpy(rng: np.random.Generator) -> Lens | None:
    """One lens of the same family as :func:`random_lens_strategy`, drawn with a numpy Generator
    (for benchmarks: reproducible without hypothesis)."""
    def curvature() -> float:
        if rng.random() < 0.2:
            return 0.0
        return float(rng.choice([-1.0, 1.0]) * math.exp(-rng.uniform(math.log(8.0), math.log(2000.0))))

    elems = []
    for _ in range(int(rng.integers(1, 4))):
        layers = int(rng.integers(1, 3))
        elem = [(curvature(), (float(rng.uniform(1.0, 12.0)), str(rng.choice(RANDOM_GLASSES)))) for _ in range(layers)]
        elems.append(elem + [(curvature(), None)])
    gaps = [float(g) for g in rng.uniform(0.5, 20.0, len(elems))]
    stop_gap = int(rng.integers(-1, max(len(elems) - 2, -1) + 1))
    return build_random_lens(elems, gaps, stop_gap, float(rng.uniform(0.2, 0.8)), float(rng.uniform(0.3, 1.0)),
                             float(rng.uniform(0.3, 1.0)), float(rng.uniform(0.0, 30.0)),
                             float(rng.choice([math.inf, math.inf, 1e9, 2000.0, 300.0])))
