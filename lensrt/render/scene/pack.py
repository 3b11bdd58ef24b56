"""Scene -> Warp arrays: the :class:`~lensrt.render.scene.kernels.SceneData` struct the kernels read.

The spectrum table holds every spectrum of the scene on its grid in final
units (reflectances, W/(m^2 sr nm), W/(sr nm), W/(m^2 nm)); objects refer to
rows. The ``wp.Mesh`` (Warp's BVH) is built only when the scene has meshes,
all meshes in one, with a face -> mesh-object table. Lights are sampled in
proportion to their radiant power over the grid.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...colour import colorchecker_reflectances, integrate, mallett2019_basis
from ...device import resolve_device, warp
from ...units import MM_PER_M
from .model import Scene, Spectrum
from .textures import TEXTURE_KINDS

__all__ = ["PackedScene", "pack_scene", "light_powers_w", "evaluate_radiance", "evaluate_irradiance"]


@dataclass
class PackedScene:
    """The kernel struct plus what must stay alive with it (the wp.Mesh) and host-side facts."""

    data: Any                                   # scene_kernels.SceneData
    device: str
    mesh: Any = None                            # wp.Mesh or None
    n_rows: int = 0
    light_kinds: list[str] = field(default_factory=list)
    light_probabilities: np.ndarray = field(default_factory=lambda: np.zeros(0))


def light_powers_w(scene: Scene) -> list[tuple[str, int, float]]:
    """``(kind, index, radiant power in W over the grid)`` of each sampled light (points, spheres, emissive planes).

    Emissive planes count their emission spectrum times the texture's ``high``
    level (an upper bound for two-level textures).
    """
    g = scene.grid
    m2 = 1.0 / (MM_PER_M * MM_PER_M)
    out = []
    for i, p in enumerate(scene.point_lights):
        out.append(("point", i, 4.0 * math.pi * float(integrate(p.intensity.values, g))))
    for i, s in enumerate(scene.sphere_lights):
        area_m2 = 4.0 * math.pi * s.radius_mm ** 2 * m2
        out.append(("sphere", i, math.pi * area_m2 * float(integrate(s.radiance.values, g))))
    for i, pl in enumerate(scene.planes):
        if pl.emission is not None:
            area_m2 = pl.size_mm[0] * pl.size_mm[1] * m2
            out.append(("plane", i, math.pi * area_m2 * pl.texture.high * float(integrate(pl.emission.values, g))))
    return out


def pack_scene(scene: Scene, device: str | None = None) -> PackedScene:
    """Pack ``scene`` for the kernels on ``device`` (None/"auto" = CUDA when present, else CPU)."""
    wp = warp()
    from .kernels import SceneData
    dev = resolve_device(device)
    g = scene.grid
    rows: list[np.ndarray] = []

    def row(values: np.ndarray | Spectrum | None) -> int:
        if values is None:
            return -1
        v = values.values if isinstance(values, Spectrum) else values
        rows.append(np.asarray(v, dtype=np.float64))
        return len(rows) - 1

    basis_row = len(rows)
    rows.extend(mallett2019_basis(g))

    def arr(a: Any, dtype: Any, empty_shape: tuple = (0,)) -> Any:
        a = np.asarray(a)
        if a.size == 0:
            a = np.zeros(empty_shape, dtype=np.float32 if dtype is not int else np.int32)
        return wp.array(a, dtype=dtype, device=dev)

    d = SceneData()
    d.lam0, d.dlam, d.n_lam = float(g.min_nm), float(g.step_nm), int(g.n)
    d.basis_row = basis_row
    d.illum_row = row(scene.illumination)
    d.bg_row = row(scene.background)

    # planes (textures: colorchecker rows and image texels appended as needed)
    pl = scene.planes
    texels: list[np.ndarray] = []
    n_texels = 0
    tex_base, img_w, img_h, pl_rows = [], [], [], []
    for p in pl:
        base, w, h = -1, 0, 0
        if p.texture.kind == "colorchecker":
            cc = colorchecker_reflectances(g, p.texture.chart)
            base = len(rows)
            rows.extend(cc)
            rows.append(cc[23])                      # the frame: the chart's black patch
        elif p.texture.kind == "image":
            img = p.texture.image_linear
            h, w = img.shape[:2]
            base = n_texels
            texels.append(img.reshape(-1, 3))
            n_texels += w * h
        tex_base.append(base)
        img_w.append(w)
        img_h.append(h)
        pl_rows.append(row(p.emission if p.emissive else p.tint))
    d.n_planes = len(pl)
    d.pl_center = arr([p.center_mm for p in pl], wp.vec3, (0, 3))
    d.pl_right = arr([p.right for p in pl], wp.vec3, (0, 3))
    d.pl_up = arr([p.up for p in pl], wp.vec3, (0, 3))
    d.pl_normal = arr([p.normal for p in pl], wp.vec3, (0, 3))
    d.pl_half = arr([(0.5 * p.size_mm[0], 0.5 * p.size_mm[1]) for p in pl], wp.vec2, (0, 2))
    d.pl_tex = arr(np.array([TEXTURE_KINDS[p.texture.kind] for p in pl], dtype=np.int32), int)
    d.pl_param = arr([p.texture.params for p in pl], wp.vec4, (0, 4))
    d.pl_levels = arr([(p.texture.low, p.texture.high) for p in pl], wp.vec2, (0, 2))
    d.pl_row = arr(np.array(pl_rows, dtype=np.int32), int)
    d.pl_emissive = arr(np.array([int(p.emissive) for p in pl], dtype=np.int32), int)
    d.pl_tex_base = arr(np.array(tex_base, dtype=np.int32), int)
    d.pl_img_w = arr(np.array(img_w, dtype=np.int32), int)
    d.pl_img_h = arr(np.array(img_h, dtype=np.int32), int)
    d.texels = arr(np.concatenate(texels) if texels else np.zeros((0, 3)), wp.vec3, (0, 3))

    sp = scene.sphere_lights
    d.n_spheres = len(sp)
    d.sp_center = arr([s.center_mm for s in sp], wp.vec3, (0, 3))
    d.sp_radius = arr(np.array([s.radius_mm for s in sp], dtype=np.float32), float)
    d.sp_row = arr(np.array([row(s.radiance) for s in sp], dtype=np.int32), int)
    pt = scene.point_lights
    d.n_points = len(pt)
    d.pt_pos = arr([p.position_mm for p in pt], wp.vec3, (0, 3))
    d.pt_row = arr(np.array([row(p.intensity) for p in pt], dtype=np.int32), int)

    # meshes: one wp.Mesh for all, built only when there are meshes
    mesh = None
    mo_rows = [row(m.emission if m.emission is not None else m.reflectance) for m in scene.meshes]
    if scene.meshes:
        verts, faces, owner, off = [], [], [], 0
        for k, m in enumerate(scene.meshes):
            verts.append(m.vertices_mm)
            faces.append(m.faces + off)
            owner.append(np.full(m.n_triangles, k, dtype=np.int32))
            off += m.vertices_mm.shape[0]
        mesh = wp.Mesh(points=wp.array(np.concatenate(verts).astype(np.float32), dtype=wp.vec3, device=dev),
                       indices=wp.array(np.concatenate(faces).astype(np.int32).ravel(), dtype=int, device=dev))
        d.has_mesh, d.mesh = 1, mesh.id
        d.tri_obj = arr(np.concatenate(owner), int)
    else:
        d.has_mesh, d.mesh = 0, wp.uint64(0)
        d.tri_obj = arr(np.zeros(0, dtype=np.int32), int)
    d.mo_row = arr(np.array(mo_rows, dtype=np.int32), int)
    d.mo_emissive = arr(np.array([int(m.emission is not None) for m in scene.meshes], dtype=np.int32), int)

    # light selection in proportion to power
    lights = light_powers_w(scene)
    kinds = {"point": 0, "sphere": 1, "plane": 2}
    power = np.array([x[2] for x in lights], dtype=np.float64)
    probs = power / power.sum() if power.size and power.sum() > 0 else np.zeros(len(lights))
    d.n_lights = len(lights)
    d.li_kind = arr(np.array([kinds[x[0]] for x in lights], dtype=np.int32), int)
    d.li_index = arr(np.array([x[1] for x in lights], dtype=np.int32), int)
    cdf = np.concatenate([[0.0], np.cumsum(probs)])
    if power.size:
        cdf[-1] = 1.0
    d.li_cdf = arr(cdf.astype(np.float32), float)

    d.spectra = wp.array(np.asarray(rows, dtype=np.float32), dtype=float, ndim=2, device=dev)
    return PackedScene(d, dev, mesh, len(rows), [x[0] for x in lights], probs)


def _launch(packed: PackedScene, kernel_name: str, a: np.ndarray, b: np.ndarray, lams: np.ndarray,
            us: np.ndarray) -> np.ndarray:
    wp = warp()
    from . import kernels as sk
    dev = packed.device
    n = len(lams)
    out = wp.zeros(n, dtype=float, device=dev)
    inputs = [packed.data, wp.array(np.asarray(a, dtype=np.float32).reshape(n, 3), dtype=wp.vec3, device=dev),
              wp.array(np.asarray(b, dtype=np.float32).reshape(n, 3), dtype=wp.vec3, device=dev),
              wp.array(np.asarray(lams, dtype=np.float32), dtype=float, device=dev),
              wp.array(np.asarray(us, dtype=np.float32).reshape(n, 3), dtype=wp.vec3, device=dev), out]
    wp.launch(getattr(sk, kernel_name), dim=n, inputs=inputs, device=dev)
    return out.numpy().astype(np.float64)


def evaluate_radiance(packed: PackedScene, origins_mm: np.ndarray, directions: np.ndarray,
                      wavelength_nm: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``scene_radiance`` (W / (m^2 sr nm)) for N object-space rays, on ``packed.device``.

    ``origins_mm``, ``directions`` (N, 3); ``wavelength_nm`` (N,); ``u`` (N, 3) uniform numbers.
    """
    return _launch(packed, "radiance_kernel", origins_mm, directions, wavelength_nm, u)


def evaluate_irradiance(packed: PackedScene, points_mm: np.ndarray, normals: np.ndarray,
                        wavelength_nm: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``direct_irradiance`` (W / (m^2 nm)) at N points with unit normals, on ``packed.device``."""
    return _launch(packed, "irradiance_kernel", points_mm, normals, wavelength_nm, u)
