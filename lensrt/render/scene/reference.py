"""Float64 NumPy reference of :mod:`lensrt.render.scene.kernels`: the readable oracle for the tests.

Same inputs, same light choice for the same ``u``, plain float64 arithmetic
(textbook ray-sphere quadratic, Moller-Trumbore triangles), one ray at a time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...units import MM_PER_M
from .model import Scene
from .pack import light_powers_w
from .textures import texture_value_ref

__all__ = ["RefHit", "ref_intersect_rect", "ref_intersect_sphere", "ref_closest_hit", "ref_plane_value",
           "ref_direct_irradiance", "ref_scene_radiance"]


@dataclass
class RefHit:
    t: float
    kind: str            # "none", "plane", "sphere", "mesh"
    index: int
    p: np.ndarray
    n: np.ndarray
    s: float = 0.0
    q: float = 0.0


def ref_intersect_rect(o, d, pl, tmin=0.0, tmax=math.inf):
    """(t, s, q) or None for a :class:`~lensrt.render.scene.model.Plane`."""
    den = float(np.dot(d, pl.normal))
    if abs(den) < 1e-12:
        return None
    t = float(np.dot(pl.center_mm - o, pl.normal)) / den
    if not tmin < t < tmax:
        return None
    r = o + t * d - pl.center_mm
    s, q = float(np.dot(r, pl.right)), float(np.dot(r, pl.up))
    if abs(s) > 0.5 * pl.size_mm[0] or abs(q) > 0.5 * pl.size_mm[1]:
        return None
    return t, s, q


def ref_intersect_sphere(o, d, c, r, tmin=0.0, tmax=math.inf):
    """Nearest root of |o + t d - c| = r in (tmin, tmax), or None (d unit)."""
    f = o - c
    b = float(np.dot(f, d))
    disc = b * b - (float(np.dot(f, f)) - r * r)
    if disc < 0:
        return None
    sq = math.sqrt(disc)
    for t in (-b - sq, -b + sq):
        if tmin < t < tmax:
            return t
    return None


def _mesh_arrays(scene: Scene):
    if not scene.meshes:
        return None
    tris, owner = [], []
    for k, m in enumerate(scene.meshes):
        tris.append(m.vertices_mm[m.faces])
        owner.append(np.full(m.n_triangles, k))
    return np.concatenate(tris), np.concatenate(owner)


def _ref_mesh(o, d, tri, tmax):
    """Moller-Trumbore over all triangles: (t, face, unit normal) of the nearest hit, or None."""
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = o - v0
    u = np.einsum("ij,ij->i", tv, pv) * inv
    qv = np.cross(tv, e1)
    v = (qv @ d) * inv
    t = np.einsum("ij,ij->i", e2, qv) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < tmax)
    if not hit.any():
        return None
    k = int(np.argmin(np.where(hit, t, np.inf)))
    n = np.cross(e1[k], e2[k])
    return float(t[k]), k, n / np.linalg.norm(n)


def ref_closest_hit(scene: Scene, o, d, tmin=0.0, tmax=math.inf, _mesh=None) -> RefHit:
    best = RefHit(tmax, "none", -1, np.zeros(3), np.zeros(3))
    for i, pl in enumerate(scene.planes):
        r = ref_intersect_rect(o, d, pl, tmin, best.t)
        if r is not None:
            best = RefHit(r[0], "plane", i, np.zeros(3), pl.normal, r[1], r[2])
    for i, sp in enumerate(scene.sphere_lights):
        t = ref_intersect_sphere(o, d, sp.center_mm, sp.radius_mm, tmin, best.t)
        if t is not None:
            n = o + t * d - sp.center_mm
            best = RefHit(t, "sphere", i, np.zeros(3), n / np.linalg.norm(n))
    mesh = _mesh if _mesh is not None else _mesh_arrays(scene)
    if mesh is not None:
        r = _ref_mesh(o, d, mesh[0], best.t)
        if r is not None and r[0] > tmin:
            best = RefHit(r[0], "mesh", int(mesh[1][r[1]]), np.zeros(3), r[2])
    best.p = o + best.t * d if best.kind != "none" else best.p
    return best


def _occluded(scene, o, d, tmax, skip_sphere, mesh) -> bool:
    if any(ref_intersect_rect(o, d, pl, 0.0, tmax) is not None for pl in scene.planes):
        return True
    if any(ref_intersect_sphere(o, d, sp.center_mm, sp.radius_mm, 0.0, tmax) is not None
           for i, sp in enumerate(scene.sphere_lights) if i != skip_sphere):
        return True
    return mesh is not None and _ref_mesh(o, d, mesh[0], tmax) is not None


def ref_plane_value(scene: Scene, i: int, s: float, q: float, lam: float) -> float:
    pl = scene.planes[i]
    tex = float(texture_value_ref(pl.texture, pl.size_mm, s, q, lam, scene.grid))
    spec = pl.emission if pl.emissive else pl.tint
    return tex * (float(spec.at(scene.grid, lam)) if spec is not None else 1.0)


def _onb(w):
    sgn = 1.0 if w[2] >= 0 else -1.0
    a = -1.0 / (sgn + w[2])
    b = w[0] * w[1] * a
    return (np.array([1.0 + sgn * w[0] * w[0] * a, sgn * b, -sgn * w[0]]),
            np.array([b, sgn + w[1] * w[1] * a, -w[1]]))


def ref_direct_irradiance(scene: Scene, p, n, lam, u, _mesh=None) -> float:
    """Float64 twin of ``scene_kernels.direct_irradiance`` (same light for the same ``u``)."""
    g = scene.grid
    mesh = _mesh if _mesh is not None else _mesh_arrays(scene)
    e = float(scene.illumination.at(g, lam)) if scene.illumination is not None else 0.0
    lights = light_powers_w(scene)
    if not lights:
        return e
    power = np.array([x[2] for x in lights])
    cdf = np.concatenate([[0.0], np.cumsum(power / power.sum())])
    k = min(int(np.searchsorted(cdf, u[0], side="right")) - 1, len(lights) - 1)
    pmf = cdf[k + 1] - cdf[k]
    kind, j, _ = lights[k]
    po = p + (1e-4 + 1e-5 * np.max(np.abs(p))) * n
    def blocked(b, skip):
        v = b - po
        dist = np.linalg.norm(v)
        return _occluded(scene, po, v / dist, dist * (1 - 1e-5), skip, mesh)

    if kind == "point":
        wv = scene.point_lights[j].position_mm - p
        dist = np.linalg.norm(wv)
        wi = wv / dist
        cp = float(np.dot(n, wi))
        if cp > 0 and not blocked(scene.point_lights[j].position_mm, -1):
            e += float(scene.point_lights[j].intensity.at(g, lam)) * MM_PER_M ** 2 / dist ** 2 * cp / pmf
    elif kind == "sphere":
        sl = scene.sphere_lights[j]
        wc = sl.center_mm - p
        dc = np.linalg.norm(wc)
        if dc > sl.radius_mm:
            omc = 1.0 - math.sqrt(1.0 - (sl.radius_mm / dc) ** 2)
            cos_t = 1.0 - u[1] * omc
            sin_t = math.sqrt(max(0.0, 1.0 - cos_t ** 2))
            t1, t2 = _onb(wc / dc)
            phi = 2 * math.pi * u[2]
            wi = sin_t * math.cos(phi) * t1 + sin_t * math.sin(phi) * t2 + cos_t * wc / dc
            cp = float(np.dot(n, wi))
            if cp > 0:
                th = ref_intersect_sphere(p, wi, sl.center_mm, sl.radius_mm)
                th = dc * cos_t if th is None else th
                if not blocked(p + th * wi, j):
                    e += float(sl.radiance.at(g, lam)) * cp * 2 * math.pi * omc / pmf
    else:
        pl = scene.planes[j]
        s, q = (2 * u[1] - 1) * 0.5 * pl.size_mm[0], (2 * u[2] - 1) * 0.5 * pl.size_mm[1]
        y = pl.center_mm + s * pl.right + q * pl.up
        wv = y - p
        dist = np.linalg.norm(wv)
        wi = wv / dist
        cp, cl = float(np.dot(n, wi)), -float(np.dot(pl.normal, wi))
        if cp > 0 and cl > 0 and not blocked(y, -1):
            area = pl.size_mm[0] * pl.size_mm[1]
            e += ref_plane_value(scene, j, s, q, lam) * cp * cl * area / dist ** 2 / pmf
    return e


def ref_scene_radiance(scene: Scene, o, d, lam, u, _mesh=None) -> float:
    """Float64 twin of ``scene_kernels.scene_radiance``."""
    g = scene.grid
    o, d = np.asarray(o, dtype=np.float64), np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d)
    mesh = _mesh if _mesh is not None else _mesh_arrays(scene)
    h = ref_closest_hit(scene, o, d, _mesh=mesh)
    if h.kind == "none":
        return float(scene.background.at(g, lam)) if scene.background is not None else 0.0
    if h.kind == "sphere":
        return float(scene.sphere_lights[h.index].radiance.at(g, lam))
    front = float(np.dot(d, h.n)) < 0
    nf = h.n if front else -h.n
    if h.kind == "plane":
        pl = scene.planes[h.index]
        if pl.emissive:
            return ref_plane_value(scene, h.index, h.s, h.q, lam) if front else 0.0
        rho = ref_plane_value(scene, h.index, h.s, h.q, lam)
    else:
        m = scene.meshes[h.index]
        if m.emission is not None:
            return float(m.emission.at(g, lam))
        rho = float(m.reflectance.at(g, lam))
    if rho <= 0:
        return 0.0
    return rho / math.pi * ref_direct_irradiance(scene, h.p, nf, lam, u, mesh)
