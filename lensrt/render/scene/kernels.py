"""Scene-side Warp functions: intersections, textures, direct lighting, radiance along a ray.

One Warp module (one compile unit). Everything here works in object space, in
mm, float32, on rays that leave the lens's front toward the scene (the
integrator calls these after tracing the sensor sample backward through the
lens): ``scene_radiance(scn, origin_mm, direction, wavelength_nm, u)`` is the
spectral radiance W / (m^2 sr nm) arriving at ``origin`` from ``direction``
(unit vector). ``u`` is a vec3 of uniform numbers in [0, 1) for the light
sample (u[0] picks the light, u[1], u[2] place the point on it); the caller
draws them from its own ``wp.rand_init`` state, so results are reproducible
and the functions stay testable with fixed numbers.

What is computed (one bounce): emission where the ray hits an emitter (sphere
light, front of an emissive plane, either side of an emissive mesh, or the
background); at a reflective (Lambertian, two-sided) plane or mesh,
``rho(lambda) / pi * E(lambda)`` with E the irradiance from the uniform
illumination (no shadows) plus a one-sample estimate of the direct light from
one point, sphere or emissive-plane light chosen in proportion to its power,
with a shadow ray. Emissive meshes are seen but do not light other surfaces;
there are no inter-reflections and no specular surfaces.

Float32 care: the ray-sphere test uses the form of Haines et al., "Precision
improvements for ray/sphere intersection" (Ray Tracing Gems, 2019, ch. 7), so
a 5 mm light 10 m away is hit where it should be; cone sampling of a small
sphere uses 1 - cos(theta_max) = sin^2 / (1 + cos) to avoid cancellation.
"""
from __future__ import annotations

import warp as wp

from ...units import MM_PER_M
from .textures import TEX_COLORCHECKER, TEX_GRID, TEX_IMAGE, TEX_SIEMENS_STAR, TEX_SLANTED_EDGE, TEX_UNIFORM

__all__ = ["SceneData", "SceneHit", "HIT_NONE", "HIT_PLANE", "HIT_SPHERE", "HIT_MESH", "LIGHT_POINT",
           "LIGHT_SPHERE", "LIGHT_PLANE", "spectrum_at", "intersect_rect", "intersect_sphere", "closest_hit",
           "occluded", "texture_value", "plane_value", "direct_irradiance", "scene_radiance", "sample_wavelength",
           "wavelength_pdf", "radiance_kernel", "irradiance_kernel", "sample_wavelength_kernel"]

HIT_NONE = wp.constant(0)
HIT_PLANE = wp.constant(1)
HIT_SPHERE = wp.constant(2)
HIT_MESH = wp.constant(3)
LIGHT_POINT = wp.constant(0)
LIGHT_SPHERE = wp.constant(1)
LIGHT_PLANE = wp.constant(2)
_TEX_UNIFORM = wp.constant(TEX_UNIFORM)
_TEX_SLANTED_EDGE = wp.constant(TEX_SLANTED_EDGE)
_TEX_SIEMENS_STAR = wp.constant(TEX_SIEMENS_STAR)
_TEX_GRID = wp.constant(TEX_GRID)
_TEX_COLORCHECKER = wp.constant(TEX_COLORCHECKER)
_TEX_IMAGE = wp.constant(TEX_IMAGE)
#: (mm per m)^2: W/(sr nm) over a distance in mm squared -> W/(m^2 nm)
_MM2_PER_M2 = wp.constant(MM_PER_M * MM_PER_M)
_PI = wp.constant(3.14159265358979)
_T_MAX = wp.constant(1.0e30)


@wp.struct
class SceneData:
    """Packed scene (see :func:`lensrt.render.scene.pack.pack_scene`); index -1 = none."""

    lam0: float                                # grid start, nm
    dlam: float                                # grid step, nm
    n_lam: int
    spectra: wp.array2d(dtype=float)           # (rows, n_lam) in final units
    basis_row: int                             # first of the 3 Mallett-Yuksel rows (r, g, b)
    illum_row: int                             # uniform irradiance W/(m^2 nm), or -1
    bg_row: int                                # background radiance, or -1
    n_planes: int
    pl_center: wp.array(dtype=wp.vec3)
    pl_right: wp.array(dtype=wp.vec3)
    pl_up: wp.array(dtype=wp.vec3)
    pl_normal: wp.array(dtype=wp.vec3)
    pl_half: wp.array(dtype=wp.vec2)           # half width, half height (mm)
    pl_tex: wp.array(dtype=int)
    pl_param: wp.array(dtype=wp.vec4)
    pl_levels: wp.array(dtype=wp.vec2)         # low, high
    pl_row: wp.array(dtype=int)                # tint (reflective) or emission row; -1 = 1
    pl_emissive: wp.array(dtype=int)
    pl_tex_base: wp.array(dtype=int)           # colorchecker: first of 25 rows; image: first texel
    pl_img_w: wp.array(dtype=int)
    pl_img_h: wp.array(dtype=int)
    texels: wp.array(dtype=wp.vec3)            # linear sRGB, row 0 at the top
    n_spheres: int
    sp_center: wp.array(dtype=wp.vec3)
    sp_radius: wp.array(dtype=float)
    sp_row: wp.array(dtype=int)                # radiance W/(m^2 sr nm)
    n_points: int
    pt_pos: wp.array(dtype=wp.vec3)
    pt_row: wp.array(dtype=int)                # intensity W/(sr nm)
    has_mesh: int
    mesh: wp.uint64
    tri_obj: wp.array(dtype=int)               # face -> mesh object
    mo_row: wp.array(dtype=int)
    mo_emissive: wp.array(dtype=int)
    n_lights: int
    li_kind: wp.array(dtype=int)               # LIGHT_POINT / LIGHT_SPHERE / LIGHT_PLANE
    li_index: wp.array(dtype=int)
    li_cdf: wp.array(dtype=float)              # n_lights + 1 entries, power-proportional


@wp.struct
class SceneHit:
    """Closest hit: ``kind`` HIT_*, ``index`` (plane, sphere or mesh object), position, geometric normal."""

    t: float
    kind: int
    index: int
    p: wp.vec3
    n: wp.vec3
    s: float       # plane coordinates (mm from the centre along right / up)
    q: float


@wp.func
def spectrum_at(scn: SceneData, row: int, lam: float) -> float:
    """Row ``row`` of the spectrum table at ``lam`` nm (linear); 1 for row -1; 0 outside the grid."""
    if row < 0:
        return 1.0
    x = (lam - scn.lam0) / scn.dlam
    if x < 0.0 or x > float(scn.n_lam - 1):
        return 0.0
    i = wp.min(int(x), scn.n_lam - 2)
    f = x - float(i)
    return (1.0 - f) * scn.spectra[row, i] + f * scn.spectra[row, i + 1]


@wp.func
def intersect_rect(o: wp.vec3, d: wp.vec3, c: wp.vec3, right: wp.vec3, up: wp.vec3, n: wp.vec3,
                   half: wp.vec2, tmin: float, tmax: float) -> wp.vec3:
    """Ray o + t d against a rectangle: (t, s, q) with plane coordinates s, q (mm); t = -1 on a miss."""
    den = wp.dot(d, n)
    miss = wp.vec3(-1.0, 0.0, 0.0)
    if wp.abs(den) < 1.0e-12:
        return miss
    t = wp.dot(c - o, n) / den
    if t <= tmin or t >= tmax:
        return miss
    r = o + t * d - c
    s = wp.dot(r, right)
    q = wp.dot(r, up)
    if wp.abs(s) > half[0] or wp.abs(q) > half[1]:
        return miss
    return wp.vec3(t, s, q)


@wp.func
def intersect_sphere(o: wp.vec3, d: wp.vec3, c: wp.vec3, r: float, tmin: float, tmax: float) -> float:
    """Nearest t in (tmin, tmax) where o + t d (d unit) meets the sphere; -1 on a miss (Haines et al. 2019)."""
    f = o - c
    b = -wp.dot(f, d)
    v = f + b * d
    disc = r * r - wp.dot(v, v)
    if disc < 0.0:
        return -1.0
    cc = wp.dot(f, f) - r * r
    sq = wp.sqrt(disc)
    qq = b + wp.where(b >= 0.0, sq, -sq)
    t0 = float(0.0)
    t1 = qq
    if qq != 0.0:
        t0 = cc / qq
    lo = wp.min(t0, t1)
    hi = wp.max(t0, t1)
    if lo > tmin and lo < tmax:
        return lo
    if hi > tmin and hi < tmax:
        return hi
    return -1.0


@wp.func
def closest_hit(scn: SceneData, o: wp.vec3, d: wp.vec3, tmin: float, tmax: float) -> SceneHit:
    """Closest plane, sphere light or mesh triangle along o + t d, t in (tmin, tmax)."""
    h = SceneHit()
    h.t = tmax
    h.kind = HIT_NONE
    h.index = -1
    for i in range(scn.n_planes):
        r = intersect_rect(o, d, scn.pl_center[i], scn.pl_right[i], scn.pl_up[i], scn.pl_normal[i],
                           scn.pl_half[i], tmin, h.t)
        if r[0] > 0.0:
            h.t = r[0]
            h.kind = HIT_PLANE
            h.index = i
            h.s = r[1]
            h.q = r[2]
            h.n = scn.pl_normal[i]
    for i in range(scn.n_spheres):
        t = intersect_sphere(o, d, scn.sp_center[i], scn.sp_radius[i], tmin, h.t)
        if t > 0.0:
            h.t = t
            h.kind = HIT_SPHERE
            h.index = i
            h.n = wp.normalize(o + t * d - scn.sp_center[i])
    if scn.has_mesh != 0:
        mq = wp.mesh_query_ray(scn.mesh, o, d, h.t)
        if mq.result and mq.t > tmin:
            h.t = mq.t
            h.kind = HIT_MESH
            h.index = scn.tri_obj[mq.face]
            h.n = wp.normalize(mq.normal)
    h.p = o + h.t * d
    return h


@wp.func
def occluded(scn: SceneData, o: wp.vec3, d: wp.vec3, tmax: float, skip_sphere: int) -> bool:
    """True when anything (planes, spheres other than ``skip_sphere``, meshes) lies along o + t d, 0 < t < tmax."""
    for i in range(scn.n_planes):
        r = intersect_rect(o, d, scn.pl_center[i], scn.pl_right[i], scn.pl_up[i], scn.pl_normal[i],
                           scn.pl_half[i], 0.0, tmax)
        if r[0] > 0.0:
            return True
    for i in range(scn.n_spheres):
        if i != skip_sphere:
            if intersect_sphere(o, d, scn.sp_center[i], scn.sp_radius[i], 0.0, tmax) > 0.0:
                return True
    if scn.has_mesh != 0:
        mq = wp.mesh_query_ray(scn.mesh, o, d, tmax)
        if mq.result:
            return True
    return False


@wp.func
def _texel(scn: SceneData, base: int, w: int, h: int, x: int, y: int) -> wp.vec3:
    return scn.texels[base + wp.clamp(y, 0, h - 1) * w + wp.clamp(x, 0, w - 1)]


@wp.func
def texture_value(scn: SceneData, i: int, s: float, q: float, lam: float) -> float:
    """Plane ``i``'s texture at plane coordinates (s, q) mm and ``lam`` nm (see lensrt.render.scene.textures)."""
    kind = scn.pl_tex[i]
    p = scn.pl_param[i]
    lv = scn.pl_levels[i]
    half = scn.pl_half[i]
    if kind == _TEX_SLANTED_EDGE:
        cs = wp.cos(p[0])
        sn = wp.sin(p[0])
        sr = cs * s + sn * q
        qr = -sn * s + cs * q
        if wp.abs(sr) <= p[1] and wp.abs(qr) <= p[1]:
            return lv[0]
        return lv[1]
    if kind == _TEX_SIEMENS_STAR:
        if s * s + q * q <= p[1] * p[1] and wp.sin(p[0] * wp.atan2(q, s)) < 0.0:
            return lv[0]
        return lv[1]
    if kind == _TEX_GRID:
        a = (s + half[0]) / p[0]
        b = (q + half[1]) / p[1]
        if wp.abs(a - wp.round(a)) * p[0] <= p[2] or wp.abs(b - wp.round(b)) * p[1] <= p[2]:
            return lv[0]
        return lv[1]
    if kind == _TEX_COLORCHECKER:
        a = s / p[0] + 3.0
        b = 2.0 - q / p[1]
        col = wp.floor(a)
        row = wp.floor(b)
        fa = (a - col) * p[0]
        fb = (b - row) * p[1]
        idx = int(24)
        if col >= 0.0 and col < 6.0 and row >= 0.0 and row < 4.0 and fa >= p[2] and fa <= p[0] - p[2] \
                and fb >= p[2] and fb <= p[1] - p[2]:
            idx = int(row) * 6 + int(col)
        return spectrum_at(scn, scn.pl_tex_base[i] + idx, lam)
    if kind == _TEX_IMAGE:
        w = scn.pl_img_w[i]
        h = scn.pl_img_h[i]
        base = scn.pl_tex_base[i]
        x = wp.clamp((s / (2.0 * half[0]) + 0.5) * float(w) - 0.5, 0.0, float(w - 1))
        y = wp.clamp((0.5 - q / (2.0 * half[1])) * float(h) - 0.5, 0.0, float(h - 1))
        x0 = wp.clamp(int(wp.floor(x)), 0, wp.max(w - 2, 0))
        y0 = wp.clamp(int(wp.floor(y)), 0, wp.max(h - 2, 0))
        fx = x - float(x0)
        fy = y - float(y0)
        rgb = ((1.0 - fx) * (1.0 - fy) * _texel(scn, base, w, h, x0, y0)
               + fx * (1.0 - fy) * _texel(scn, base, w, h, x0 + 1, y0)
               + (1.0 - fx) * fy * _texel(scn, base, w, h, x0, y0 + 1)
               + fx * fy * _texel(scn, base, w, h, x0 + 1, y0 + 1))
        return (rgb[0] * spectrum_at(scn, scn.basis_row, lam) + rgb[1] * spectrum_at(scn, scn.basis_row + 1, lam)
                + rgb[2] * spectrum_at(scn, scn.basis_row + 2, lam))
    return lv[1]


@wp.func
def plane_value(scn: SceneData, i: int, s: float, q: float, lam: float) -> float:
    """Reflectance (reflective plane) or radiance W/(m^2 sr nm) (emissive plane) at (s, q), ``lam``."""
    return texture_value(scn, i, s, q, lam) * spectrum_at(scn, scn.pl_row[i], lam)


@wp.func
def _ray_eps(p: wp.vec3) -> float:
    """Offset (mm) that keeps a shadow ray off its own surface in float32."""
    return 1.0e-4 + 1.0e-5 * wp.max(wp.abs(p[0]), wp.max(wp.abs(p[1]), wp.abs(p[2])))


@wp.func
def _onb_dir(w: wp.vec3, cos_t: float, sin_t: float, phi: float) -> wp.vec3:
    """Direction at polar angle (cos_t, sin_t) and azimuth phi about unit w (Duff et al. 2017 basis)."""
    sgn = wp.where(w[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sgn + w[2])
    b = w[0] * w[1] * a
    t1 = wp.vec3(1.0 + sgn * w[0] * w[0] * a, sgn * b, -sgn * w[0])
    t2 = wp.vec3(b, sgn + w[1] * w[1] * a, -w[1])
    return sin_t * wp.cos(phi) * t1 + sin_t * wp.sin(phi) * t2 + cos_t * w


@wp.func
def _blocked(scn: SceneData, a: wp.vec3, b: wp.vec3, skip_sphere: int) -> bool:
    """Shadow test of the segment from ``a`` (already offset off its surface) to the light point ``b``."""
    v = b - a
    dist = wp.length(v)
    return occluded(scn, a, v / dist, dist * (1.0 - 1.0e-5), skip_sphere)


@wp.func
def _pick_light(scn: SceneData, u: float) -> int:
    lo = int(0)
    hi = scn.n_lights
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if scn.li_cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@wp.func
def direct_irradiance(scn: SceneData, p: wp.vec3, n: wp.vec3, lam: float, u: wp.vec3) -> float:
    """Spectral irradiance E (W / (m^2 nm)) on the side of unit normal ``n`` at ``p``: uniform
    illumination plus a one-sample, power-weighted estimate of one light's direct contribution."""
    e = float(0.0)
    if scn.illum_row >= 0:
        e = spectrum_at(scn, scn.illum_row, lam)
    if scn.n_lights == 0:
        return e
    k = _pick_light(scn, u[0])
    pmf = scn.li_cdf[k + 1] - scn.li_cdf[k]
    if pmf <= 0.0:
        return e
    po = p + _ray_eps(p) * n
    kind = scn.li_kind[k]
    j = scn.li_index[k]
    if kind == LIGHT_POINT:
        wv = scn.pt_pos[j] - p
        dist = wp.length(wv)
        wi = wv / dist
        cos_p = wp.dot(n, wi)
        if cos_p > 0.0:
            if not _blocked(scn, po, scn.pt_pos[j], -1):
                e += spectrum_at(scn, scn.pt_row[j], lam) * _MM2_PER_M2 / (dist * dist) * cos_p / pmf
    elif kind == LIGHT_SPHERE:
        c = scn.sp_center[j]
        r = scn.sp_radius[j]
        wc = c - p
        dc = wp.length(wc)
        if dc > r:
            sin2 = (r / dc) * (r / dc)
            cos_max = wp.sqrt(wp.max(0.0, 1.0 - sin2))
            omc = sin2 / (1.0 + cos_max)                      # 1 - cos(theta_max), no cancellation
            x = u[1] * omc                                    # 1 - cos(theta)
            cos_t = 1.0 - x
            sin_t = wp.sqrt(wp.max(0.0, x * (2.0 - x)))
            wi = _onb_dir(wc / dc, cos_t, sin_t, 2.0 * _PI * u[2])
            cos_p = wp.dot(n, wi)
            if cos_p > 0.0:
                th = intersect_sphere(p, wi, c, r, 0.0, _T_MAX)
                if th < 0.0:
                    th = dc * cos_t                           # grazing the rim in float32
                if not _blocked(scn, po, p + th * wi, j):
                    e += spectrum_at(scn, scn.sp_row[j], lam) * cos_p * 2.0 * _PI * omc / pmf
    else:
        hw = scn.pl_half[j]
        s = (2.0 * u[1] - 1.0) * hw[0]
        q = (2.0 * u[2] - 1.0) * hw[1]
        y = scn.pl_center[j] + s * scn.pl_right[j] + q * scn.pl_up[j]
        wv = y - p
        dist = wp.length(wv)
        wi = wv / dist
        cos_p = wp.dot(n, wi)
        cos_l = -wp.dot(scn.pl_normal[j], wi)
        if cos_p > 0.0 and cos_l > 0.0:
            if not _blocked(scn, po, y, -1):
                area = 4.0 * hw[0] * hw[1]
                e += plane_value(scn, j, s, q, lam) * cos_p * cos_l * area / (dist * dist) / pmf
    return e


@wp.func
def scene_radiance(scn: SceneData, o: wp.vec3, d: wp.vec3, lam: float, u: wp.vec3) -> float:
    """Spectral radiance (W / (m^2 sr nm)) reaching ``o`` (mm) from unit direction ``d`` at ``lam`` nm.

    ``u``: three uniform numbers in [0, 1) for the light sample. Returns 0 for
    wavelengths outside the scene's grid.
    """
    h = closest_hit(scn, o, d, 0.0, _T_MAX)
    if h.kind == HIT_NONE:
        if scn.bg_row >= 0:
            return spectrum_at(scn, scn.bg_row, lam)
        return 0.0
    if h.kind == HIT_SPHERE:
        return spectrum_at(scn, scn.sp_row[h.index], lam)
    front = wp.dot(d, h.n) < 0.0
    nf = wp.where(front, h.n, -h.n)
    rho = float(0.0)
    if h.kind == HIT_PLANE:
        if scn.pl_emissive[h.index] != 0:
            if front:
                return plane_value(scn, h.index, h.s, h.q, lam)
            return 0.0
        rho = plane_value(scn, h.index, h.s, h.q, lam)
    else:
        if scn.mo_emissive[h.index] != 0:
            return spectrum_at(scn, scn.mo_row[h.index], lam)
        rho = spectrum_at(scn, scn.mo_row[h.index], lam)
    if rho <= 0.0:
        return 0.0
    return rho / _PI * direct_irradiance(scn, h.p, nf, lam, u)


@wp.func
def sample_wavelength(cdf: wp.array(dtype=float), lam0: float, dlam: float, u: float) -> wp.vec2:
    """Wavelength (nm) and pdf (1/nm) from a piecewise-constant CDF over grid intervals (WavelengthSampler)."""
    lo = int(0)
    hi = cdf.shape[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    p = cdf[lo + 1] - cdf[lo]
    f = float(0.5)
    if p > 0.0:
        f = wp.clamp((u - cdf[lo]) / p, 0.0, 1.0)
    return wp.vec2(lam0 + (float(lo) + f) * dlam, p / dlam)


@wp.func
def wavelength_pdf(cdf: wp.array(dtype=float), lam0: float, dlam: float, lam: float) -> float:
    """pdf (1/nm) of :func:`sample_wavelength` at ``lam``."""
    nb = cdf.shape[0] - 1
    x = (lam - lam0) / dlam
    if x < 0.0 or x > float(nb):
        return 0.0
    i = wp.min(int(x), nb - 1)
    return (cdf[i + 1] - cdf[i]) / dlam


@wp.kernel
def radiance_kernel(scn: SceneData, origins: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3),
                    lams: wp.array(dtype=float), us: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    """Store kernel: ``scene_radiance`` for given object-space rays and light-sample numbers."""
    i = wp.tid()
    out[i] = scene_radiance(scn, origins[i], wp.normalize(dirs[i]), lams[i], us[i])


@wp.kernel
def irradiance_kernel(scn: SceneData, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
                      lams: wp.array(dtype=float), us: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    """Store kernel: ``direct_irradiance`` at given points and normals."""
    i = wp.tid()
    out[i] = direct_irradiance(scn, points[i], wp.normalize(normals[i]), lams[i], us[i])


@wp.kernel
def sample_wavelength_kernel(cdf: wp.array(dtype=float), lam0: float, dlam: float, us: wp.array(dtype=float),
                             out: wp.array(dtype=wp.vec2)):
    i = wp.tid()
    out[i] = sample_wavelength(cdf, lam0, dlam, us[i])
