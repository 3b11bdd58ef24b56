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

from geometry_cases import SYSTEMS, WL_NM, cassegrain_system, ray_grid

from lensrt.prescription.frames import surface_frames
from lensrt.prescription.model import Lens
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK, VIGNETTED

optiland = pytest.importorskip("optiland")

TOL_MM = 1e-9


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
    op.surfaces.trace(rays, skip=1)
    return np.stack([np.asarray(rays.x), np.asarray(rays.y), np.asarray(rays.z)], axis=1)


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
