"""Lenses for the real-ray tests: the library, the pbrt tables and a few built stiff cases.

The pbrt tables are read here with a ten-line parser (four columns: radius, distance
to the next surface, index after, clear aperture diameter; radius 0 = the stop), so
these tests do not depend on the file-format readers. The last gap is set to the
paraxial back focal length.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

from lensrt.loading import complete_lens, load_lens
from lensrt.prescription.materials import AIR, ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths

DATA = Path(__file__).resolve().parents[1] / "data"
LIBRARY = Path(__file__).resolve().parents[2] / "lens_prescriptions"

#: pbrt table -> half field angle (deg) used in the tests
PBRT_FIELDS = {"dgauss.50mm": 20.0, "wide.22mm": 30.0, "fisheye.10mm": 77.95, "telephoto.250mm": 4.5}


def library_names() -> list[str]:
    return sorted(p.stem for p in LIBRARY.glob("*.toml"))


@lru_cache(maxsize=None)
def library_lens(name: str) -> Lens:
    return load_lens(LIBRARY / f"{name}.toml")


@lru_cache(maxsize=None)
def pbrt_lens(stem: str) -> Lens:
    """A pbrt lens table as a Lens (constant indices, float by stop, image at the paraxial focus)."""
    from lensrt.paraxial import first_order
    rows = []
    for line in (DATA / f"{stem}.dat").read_text().splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        rows.append([float(v) for v in line.split()])
    surfaces = []
    for r, t, n, d in rows:
        stop = r == 0.0
        mat = AIR if (n in (0.0, 1.0)) else ConstantIndex(n)
        surfaces.append(Surface(curvature_per_mm=0.0 if stop else 1.0 / r, thickness_mm=t, material=mat,
                                semi_diameter_mm=d / 2.0, is_stop=stop))
    lens = Lens(tuple(surfaces), aperture=Aperture("float_by_stop", 0.0),
                fields=Fields("angle", (0.0, 0.7 * math.radians(PBRT_FIELDS[stem]), math.radians(PBRT_FIELDS[stem]))),
                wavelengths=Wavelengths((587.5618,)), name=stem)
    bfl = first_order(lens).bfl_mm
    return lens.replace_surface(len(surfaces) - 1, thickness_mm=bfl)


@lru_cache(maxsize=None)
def asphere_lens() -> Lens:
    """An f/2 aspheric singlet (N-BK7-like model glass) plus a conic field flattener."""
    from lensrt.prescription.materials import ModelGlass
    glass = ModelGlass(1.5168, 64.17)
    s = (
        Surface(curvature_per_mm=1 / 30.0, thickness_mm=6.0, material=glass, conic=-0.6,
                asphere=(0.0, -2.0e-6, 3.0e-9, -1.0e-12)),
        Surface(curvature_per_mm=-1 / 200.0, thickness_mm=3.0, is_stop=True, semi_diameter_mm=10.0),
        Surface(curvature_per_mm=1 / 80.0, thickness_mm=3.0, material=glass, conic=-2.0, asphere=(1e-4,)),
        Surface(curvature_per_mm=0.0, thickness_mm=45.0),
    )
    lens = Lens(s, aperture=Aperture("float_by_stop", 0.0),
                fields=Fields("angle", (0.0, math.radians(10.0))), wavelengths=Wavelengths((486.1327, 587.5618, 656.2725), primary=1),
                name="asphere test lens")
    return complete_lens(lens)


@lru_cache(maxsize=None)
def flat_1e7_lens() -> Lens:
    """The CODE V double Gauss with its plane surfaces replaced by |R| = 1e7 mm."""
    lens = library_lens("codev_dblgauss_100mm_f2")
    for i, s in enumerate(lens.surfaces):
        if s.curvature_per_mm == 0.0:
            lens = lens.replace_surface(i, curvature_per_mm=(1e-7 if i % 2 else -1e-7))
    return lens


@lru_cache(maxsize=None)
def fast_lens() -> Lens:
    """The CODE V double Gauss opened to f/1 (EPD 100 mm): steep marginal rays, TIR and misses."""
    lens = library_lens("codev_dblgauss_100mm_f2")
    return lens.replace(aperture=Aperture("epd", 100.0))


def all_cases() -> dict[str, Lens]:
    """Every lens the tracer tests run on."""
    cases = {f"library:{n}": library_lens(n) for n in library_names()}
    cases.update({f"pbrt:{s}": pbrt_lens(s) for s in PBRT_FIELDS})
    cases["asphere"] = asphere_lens()
    cases["flat_1e7"] = flat_1e7_lens()
    cases["f1"] = fast_lens()
    return cases


def max_reference_error(lens: Lens, rays, res) -> float:
    """Largest |kernel - float64 reference tracer| over position, direction, OPL and the smallest cosine
    of incidence of ``rays`` traced to ``res``; asserts each ray's status and surface agree."""
    import numpy as np

    from lensrt.trace.reference import trace_reference
    worst = 0.0
    for i in range(len(rays)):
        ref = trace_reference(lens, rays.origin_mm[i], rays.direction[i], rays.wavelength_nm[i])
        assert (ref.status, ref.surface) == (res.status[i], res.surface[i]), f"ray {i}"
        got = np.r_[res.position_mm[i], res.direction[i], res.opl_mm[i], res.min_cos_incidence[i]]
        want = np.r_[ref.x_mm, ref.y_mm, ref.z_mm, ref.L, ref.M, ref.N, ref.opl_mm, ref.min_cos_incidence]
        worst = max(worst, float(np.max(np.abs(got - want))))
    return worst
