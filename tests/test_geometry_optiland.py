"""Mirrors, tilts and decenters in the float64 reference tracer against optiland (a test-only oracle).

Each system's surfaces are handed to optiland at their global positions and
orientations (lensrt's :func:`~lensrt.prescription.frames.surface_frames`,
written as optiland's absolute x, y, z, rx, ry, rz), with lensrt's indices
(optiland ``IdealMaterial``) and ``material="mirror"`` for mirrors. The same
rays -- global origins and directions over a grid across the beam -- are
traced by both; the image-surface intercepts agree to 1e-9 mm. This checks
lensrt's intersection, reflection and frame handling; the readers' reading of
the file formats is tested in ``tests/test_geometry.py``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lensrt.prescription.frames import surface_frames
from lensrt.prescription.geometry import CoordinateTransform, SurfaceAperture
from lensrt.prescription.materials import AIR, ModelGlass
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK, VIGNETTED

optiland = pytest.importorskip("optiland")

TOL_MM = 1e-9
WL_NM = 587.5618
BK7 = ModelGlass(1.5168, 64.17, name="BK7-model")


def _euler_zyx(axes: np.ndarray) -> tuple[float, float, float]:
    """(rx, ry, rz) with axes = Rz(rz) Ry(ry) Rx(rx), right-handed: optiland's globalize order."""
    ry = -math.asin(max(-1.0, min(1.0, axes[2, 0])))
    rx = math.atan2(axes[2, 1], axes[2, 2])
    rz = math.atan2(axes[1, 0], axes[0, 0])
    return rx, ry, rz


def optiland_copy(lens: Lens, wavelength_nm: float = WL_NM):
    """An optiland Optic with lensrt's surfaces at their global frames (absolute positioning)."""
    import optiland.backend as be
    from optiland import optic
    from optiland.materials import IdealMaterial
    n = lens.indices(wavelength_nm)
    frames = surface_frames(lens)
    op = optic.Optic()
    op.surfaces.add(index=0, radius=be.inf, z=-1e3)
    for i, s in enumerate(lens.surfaces):
        o, a = frames[i]
        rx, ry, rz = _euler_zyx(a)
        mat = "mirror" if s.mirror else ("air" if n[i + 1] == 1.0 else IdealMaterial(float(n[i + 1])))
        op.surfaces.add(index=i + 1, radius=s.radius_mm, conic=s.conic, material=mat, is_stop=s.is_stop,
                        x=float(o[0]), y=float(o[1]), z=float(o[2]), rx=rx, ry=ry, rz=rz)
    o, a = frames[-1]
    rx, ry, rz = _euler_zyx(a)
    op.surfaces.add(index=lens.n_surfaces + 1, x=float(o[0]), y=float(o[1]), z=float(o[2]), rx=rx, ry=ry, rz=rz)
    op.set_aperture(aperture_type="EPD", value=10.0)
    op.fields.set_type(field_type="angle")
    op.fields.add(y=0.0)
    op.wavelengths.add(value=wavelength_nm / 1000.0, is_primary=True)
    return op


def ray_grid(half_width_mm: float, angle_deg: float = 0.0, z0_mm: float = -5.0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of a 7 x 7 grid of parallel rays (global), tilted by ``angle_deg`` about x."""
    g = np.linspace(-half_width_mm, half_width_mm, 7)
    x, y = (v.ravel() for v in np.meshgrid(g, g))
    t = math.radians(angle_deg)
    o = np.stack([x, y, np.full_like(x, z0_mm)], axis=1)
    d = np.tile([0.0, math.sin(t), math.cos(t)], (len(x), 1))
    return o, d


def lensrt_image_points(lens: Lens, o: np.ndarray, d: np.ndarray, clip: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Global image intercepts (nan where a ray failed) and statuses."""
    img_o, img_a = surface_frames(lens)[-1]
    z_img = lens.vertex_z_mm()[-1]
    out, status = np.full((len(o), 3), np.nan), np.zeros(len(o), dtype=int)
    for k in range(len(o)):
        r = trace_reference(lens, tuple(o[k]), tuple(d[k]), WL_NM, clip=clip)
        status[k] = r.status
        if r.status == OK:
            out[k] = img_o + img_a @ np.array([r.x_mm, r.y_mm, r.z_mm - z_img])
    return out, status


def optiland_image_points(lens: Lens, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    from optiland.rays import RealRays
    op = optiland_copy(lens)
    rays = RealRays(o[:, 0].copy(), o[:, 1].copy(), o[:, 2].copy(), d[:, 0].copy(), d[:, 1].copy(),
                    d[:, 2].copy(), np.ones(len(o)), np.full(len(o), WL_NM / 1000.0))
    op.surface_group.trace(rays, skip=1)
    return np.stack([np.asarray(rays.x), np.asarray(rays.y), np.asarray(rays.z)], axis=1)


def _lens(surfaces: list[Surface], **kw) -> Lens:
    return Lens(tuple(surfaces), aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0, math.radians(1.0))),
                wavelengths=Wavelengths((WL_NM,)), **kw)


def folded_system() -> Lens:
    """A singlet, then a flat mirror tilted 45 deg about x that folds the beam (CODE V BEN)."""
    tilt = CoordinateTransform(tilt_x_rad=math.radians(45.0))
    return _lens([Surface(1 / 60.0, 4.0, BK7, is_stop=True), Surface(-1 / 200.0, 40.0, AIR),
                  Surface(0.0, -55.0, AIR, mirror=True, transform_before=tilt,
                          transform_after=CoordinateTransform(tilt_x_rad=math.radians(45.0)))])


def tilted_decentred_system() -> Lens:
    """A singlet decentred 1.5 mm in x and y, tilted 4 deg about y and 3 about x (then returned, CODE V DAR),
    and a second element behind a basic decenter with a tilt about z (order 1)."""
    t = CoordinateTransform(decenter_x_mm=1.5, decenter_y_mm=-1.0, tilt_x_rad=math.radians(3.0),
                            tilt_y_rad=math.radians(4.0))
    u = CoordinateTransform(decenter_y_mm=0.7, tilt_x_rad=math.radians(-2.0), tilt_z_rad=math.radians(20.0), order=1)
    return _lens([Surface(1 / 50.0, 5.0, BK7, is_stop=True, transform_before=t),
                  Surface(-1 / 80.0, 10.0, AIR, transform_after=t.inverse()),
                  Surface(1 / 120.0, 3.0, BK7, transform_before=u), Surface(0.0, 60.0, AIR)])


def mangin_system() -> Lens:
    """rayoptics' mangin.seq (R -1200 front, R -1000 silvered back, BK7-like glass), scaled to 1/10."""
    return _lens([Surface(-1 / 120.0, 1.0, BK7, is_stop=True), Surface(-1 / 100.0, -1.0, BK7, mirror=True),
                  Surface(-1 / 120.0, -50.0, AIR)])


def cassegrain_system(obscuration_mm: float = 4.0) -> Lens:
    """A Cassegrain (paraboloid primary, hyperboloid secondary) with the secondary's central obscuration."""
    obs = SurfaceAperture("circle", obscuration_mm, obscuration=True)
    return _lens([Surface(0.0, 30.0, AIR, is_stop=True, apertures=(obs,)),
                  Surface(-1 / 200.0, -70.0, AIR, mirror=True, conic=-1.0),
                  Surface(-1 / 70.0, 110.0, AIR, mirror=True, conic=-3.0)])


SYSTEMS = {"folded": folded_system, "tilted_decentred": tilted_decentred_system, "mangin": mangin_system,
           "cassegrain": cassegrain_system}


@pytest.mark.parametrize("name", sorted(SYSTEMS))
@pytest.mark.parametrize("angle_deg", [0.0, 1.5])
def test_image_intercepts_match_optiland(name: str, angle_deg: float) -> None:
    lens = SYSTEMS[name]()
    o, d = ray_grid(4.5, angle_deg)
    ours, status = lensrt_image_points(lens, o, d)
    assert np.all(status == OK)
    theirs = optiland_image_points(lens, o, d)
    assert np.max(np.abs(ours - theirs)) < TOL_MM


def test_cassegrain_obscuration_blocks_exactly_the_central_rays() -> None:
    lens = cassegrain_system(obscuration_mm=2.2)
    o, d = ray_grid(4.5)
    _, status = lensrt_image_points(lens, o, d, clip=True)
    r = np.hypot(o[:, 0], o[:, 1])
    assert np.all((status == VIGNETTED) == (r <= 2.2))
    assert np.count_nonzero(status == VIGNETTED) > 0
