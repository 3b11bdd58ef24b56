"""The integrator's Warp kernels: camera paths sensor -> lens -> scene, and the exit-pupil probe.

One Warp module (this one, float32), compiled on first use and cached on disk by Warp.
It calls the tracer's own generic ``@wp.func`` surface code (:mod:`lensrt.trace.kernels.surfaces`,
``trace_ray`` with the forward tracer's signature, instantiated for float32) on the lens mirrored by
:func:`lensrt.trace.reverse.reversed_lens`, and the scene stage's ``scene_radiance``
(:mod:`lensrt.render.scene.kernels`). Plan switches (spectral or one wavelength, meshes,
shadow rays) are run-time values the kernel reads (the packed scene has no BVH when it has no
meshes, no lights to sample when nothing is lit by them), so every plan uses this one compiled
module.

:func:`camera_pass` -- one thread per pixel, ``spp`` paths each, summed in a fixed order
into that pixel's own slots (no atomics): the per-pass images are bit-identical for the same
seed on the same device, whatever the launch is split into. Per path:

1. a point uniformly in the pixel, mapped to the sensor plane by the affine form of
   :meth:`lensrt.render.camera.SensorGrid.position_of` (the one image <-> sensor map);
2. a wavelength from the plan's sampler (pdf p(lambda)), or the fixed wavelength;
3. a point uniform in the exit-pupil box of the pixel's radial bin (pbrt-v4's bounds, in the
   plane of the last vertex, computed for sensor points on +x and rotated to the pixel's
   azimuth; pdf 1 / A_box);
4. the ray from the sensor point to it, traced backward through the lens (surface code of the
   forward tracer); a ray that is vignetted, misses or is totally reflected carries nothing;
5. the scene radiance L along the ray leaving the front (one bounce, scene stage);
6. the sensor-plane irradiance estimate E = L (n_image / n_object)^2 cos^4(theta) A_box /
   (D^2 p(lambda)): E = int L cos(theta) d omega, with d omega = cos^3(theta) dA / D^2 for a
   point dA of the plane at distance D (radiance / n^2 is conserved through an uncoated,
   lossless lens: T = 1).

Tilt-shift (the ``frame`` argument, a compile-time variant as the tracer's lens variants are):
:class:`CentredSensor` is the plain camera (the code above, nothing else compiled in);
:class:`TiltedSensor` carries the moved lens's frame in the camera frame. The lens itself stays
centred in its own frame, so the ray is still traced by the symmetric surface code: the sensor
point is moved into the lens frame (where the sensor is a tilted plane, the point at depth D'
from the last vertex), the pupil box is the table's box of its lens-frame radius (the table
unites every depth the sensor spans), and the ray leaving the front goes back into the camera
(scene) frame. The estimate becomes E = L (n_i / n_o)^2 cos(theta_s) cos^3(theta_l) A_box /
(D'^2 p(lambda)): d omega = cos^3(theta_l) dA / D'^2 is measured from the lens axis, the
cosine factor of the irradiance from the sensor's normal (theta_s).
"""
# No ``from __future__ import annotations``: Warp reads the annotations as objects.

from functools import lru_cache
from types import SimpleNamespace
from typing import Any

import warp as wp

from ..trace.kernels.sampling import i32
from ..trace.kernels.surfaces import SymmetricLens, medium_index, trace_ray
from ..trace.status import OK
from .scene import kernels as sk

__all__ = ["get_render_kernels", "MODULE", "camera_pass", "pupil_probe", "accumulate", "accumulate_moments",
           "finalize", "permute", "sensor_ray", "CentredSensor", "TiltedSensor"]

MODULE = __name__
wp.set_module_options({"enable_backward": False})

K1, K2, K3, K4, K5, K6 = (i32(v) for v in (0xE170893D, 0x0929EB3F, 0x6935FA69, 0x74DCB303, 0x9E501CC3, 0xC860A3DF))


@wp.func
def permute_round(i: wp.uint32, p: wp.uint32, w: wp.uint32) -> wp.uint32:
    # one round of Kensler's hash-based permutation ("Correlated multi-jittered sampling", Pixar 2013)
    i = i ^ p
    i = i * wp.uint32(K1)
    i = i ^ (p >> wp.uint32(16))
    i = i ^ ((i & w) >> wp.uint32(4))
    i = i ^ (p >> wp.uint32(8))
    i = i * wp.uint32(K2)
    i = i ^ (p >> wp.uint32(23))
    i = i ^ ((i & w) >> wp.uint32(1))
    i = i * (wp.uint32(1) | (p >> wp.uint32(27)))
    i = i * wp.uint32(K3)
    i = i ^ ((i & w) >> wp.uint32(11))
    i = i * wp.uint32(K4)
    i = i ^ ((i & w) >> wp.uint32(2))
    i = i * wp.uint32(K5)
    i = i ^ ((i & w) >> wp.uint32(2))
    i = i * wp.uint32(K6)
    i = i & w
    i = i ^ (i >> wp.uint32(5))
    return i

@wp.func
def permute(k: int, n: int, p: wp.uint32) -> int:
    # element k of a pseudo-random permutation of 0 .. n-1 chosen by p (cycle walking)
    w = wp.uint32(n - 1)
    w = w | (w >> wp.uint32(1))
    w = w | (w >> wp.uint32(2))
    w = w | (w >> wp.uint32(4))
    w = w | (w >> wp.uint32(8))
    w = w | (w >> wp.uint32(16))
    i = permute_round(wp.uint32(k), p, w)
    while i >= wp.uint32(n):
        i = permute_round(i, p, w)
    return int((i + p) % wp.uint32(n))

@wp.struct
class CentredSensor:
    tag: int


@wp.struct
class TiltedSensor:
    origin: wp.vec3        # the lens's first vertex in the camera frame (mm)
    rot: wp.mat33          # columns: the lens's x, y, z axes in camera coordinates
    sensor_z: float        # the sensor plane z (camera frame, mm)
    z_last: float          # the lens's last vertex z (lens frame, mm)


@wp.func
def is_tilted(frame: CentredSensor) -> bool:
    return False


@wp.func
def is_tilted(frame: TiltedSensor) -> bool:  # noqa: F811 -- a Warp overload
    return True


@wp.func
def sensor_in_lens(frame: CentredSensor, x: float, y: float) -> wp.vec3:
    return wp.vec3(x, y, 0.0)  # never called: the centred camera traces (x, y) as they are


@wp.func
def sensor_in_lens(frame: TiltedSensor, x: float, y: float) -> wp.vec3:  # noqa: F811 -- a Warp overload
    # camera-frame sensor point -> lens frame (q = R^T (p - o)) -> reversed frame (z -> z_last - z)
    q = wp.transpose(frame.rot) * (wp.vec3(x, y, frame.sensor_z) - frame.origin)
    return wp.vec3(q[0], q[1], frame.z_last - q[2])


@wp.func
def camera_point(frame: CentredSensor, p: wp.vec3) -> wp.vec3:
    return p


@wp.func
def camera_point(frame: TiltedSensor, p: wp.vec3) -> wp.vec3:  # noqa: F811 -- a Warp overload
    # lens-frame point -> camera frame: o + R p
    return frame.origin + frame.rot * p


@wp.func
def camera_dir(frame: CentredSensor, d: wp.vec3) -> wp.vec3:
    return d


@wp.func
def camera_dir(frame: TiltedSensor, d: wp.vec3) -> wp.vec3:  # noqa: F811 -- a Warp overload
    return frame.rot * d


@wp.func
def sensor_ray(x: float, y: float, box: wp.vec4, u0: float, u1: float, rear_dist: float) -> wp.vec4:
    # direction (unit, reversed frame: toward +z) from the sensor point to a point of the pupil
    # box rotated to the point's azimuth; w = cos(theta)
    pa = box[0] + u0 * (box[1] - box[0])
    pb = box[2] + u1 * (box[3] - box[2])
    r = wp.sqrt(x * x + y * y)
    c = float(1.0)
    s = float(0.0)
    if r > 0.0:
        c = x / r
        s = y / r
    qx = c * pa - s * pb
    qy = s * pa + c * pb
    dx = qx - x
    dy = qy - y
    inv = 1.0 / wp.sqrt(dx * dx + dy * dy + rear_dist * rear_dist)
    return wp.vec4(dx * inv, dy * inv, rear_dist * inv, rear_dist * inv)

@wp.kernel
def camera_pass(surf: wp.array2d(dtype=wp.float32), media: wp.array2d(dtype=wp.float32),
                iris: wp.array(dtype=wp.float32),
                n_surfaces: int, table: wp.array2d(dtype=wp.float32), rec: wp.array3d(dtype=wp.float32),
                sensor_z: float, rear_dist: float,
                width: int, ax0: float, ax1: float, ay0: float, ay1: float,
                boxes: wp.array(dtype=wp.vec4), inv_dr: float, n_bins: int,
                scn: sk.SceneData, spectral: int, lam_fixed: float, cdf: wp.array(dtype=float),
                band0: float, inv_band: float, n_bands: int,
                cmf: wp.array2d(dtype=float), km: float,
                spp: int, seed: int, pix_base: int, out_base: int,
                spec: wp.array(dtype=float), xyz: wp.array(dtype=wp.vec3), hits: wp.array(dtype=wp.int32),
                frame: Any):
    # pixel pix of the image (its random numbers), stored at pix - out_base (tiles keep their own arrays)
    pix = wp.tid() + pix_base
    o = pix - out_base
    row = pix // width
    col = pix - row * width
    st = wp.rand_init(seed, pix)
    acc = wp.vec3(0.0, 0.0, 0.0)
    n_ok = int(0)
    # stratification within the pass: the pixel's paths take distinct cells of an ncx x ncy grid
    # over the pixel and over the pupil box, and distinct strata of the wavelength sampler's
    # [0, 1), each dimension through its own random permutation (pbrt's padded stratified
    # sampling): every path's sample stays uniform, so each pass is an unbiased, independent
    # estimate (as batch means need), and the dimensions are not paired in lockstep (a pairing
    # by one shift made a pass's error independent of its path count)
    ncx = wp.max(int(wp.floor(wp.sqrt(float(spp)))), 1)
    ncy = (spp + ncx - 1) // ncx
    ncell = ncx * ncy
    p_pix = wp.uint32(wp.randi(st))
    p_pup = wp.uint32(wp.randi(st))
    p_lam = wp.uint32(wp.randi(st))
    for kk in range(spp):
        # 1. sensor point (x right, y up; the orientation lives in ax1, ay1)
        cpx = permute(kk, ncell, p_pix)
        x = ax0 + ax1 * (float(col) + (float(cpx % ncx) + wp.randf(st)) / float(ncx) - 0.5)
        y = ay0 + ay1 * (float(row) + (float(cpx // ncx) + wp.randf(st)) / float(ncy) - 0.5)
        cpu = permute(kk, ncell, p_pup)
        u0 = (float(cpu % ncx) + wp.randf(st)) / float(ncx)
        u1 = (float(cpu // ncx) + wp.randf(st)) / float(ncy)
        ul = (float(permute(kk, spp, p_lam)) + wp.randf(st)) / float(spp)
        us = wp.vec3(wp.randf(st), wp.randf(st), wp.randf(st))
        # 2. wavelength
        lam = lam_fixed
        pdf = float(1.0)
        if spectral != 0:
            lp = sk.sample_wavelength(cdf, scn.lam0, scn.dlam, ul)
            lam = lp[0]
            pdf = lp[1]
        if pdf <= 0.0:
            continue
        # 3. pupil box of the radial bin (a tilt-shift camera: of the sensor point in the lens frame)
        sx = x
        sy = y
        sz = sensor_z
        rd = rear_dist
        if is_tilted(frame):
            q = sensor_in_lens(frame, x, y)
            sx = q[0]
            sy = q[1]
            sz = q[2]
            rd = -q[2]
        b = wp.min(int(wp.sqrt(sx * sx + sy * sy) * inv_dr), n_bins - 1)
        box = boxes[b]
        area = (box[1] - box[0]) * (box[3] - box[2])
        if area <= 0.0:
            continue
        d = sensor_ray(sx, sy, box, u0, u1, rd)
        # 4. backward through the lens
        w_um = lam * 1.0e-3
        w2 = w_um * w_um
        status, where, px, py, pz, L, M, N, opl, mc = trace_ray(
            surf, media, iris, n_surfaces, sx, sy, sz, d[0], d[1], d[2], w2, table, -1,
            n_surfaces, 1, 0.0, 0, rec, 0, SymmetricLens())
        if status != OK:
            continue
        n_ok = n_ok + 1
        # 5. into the scene (lens frame of the scene: z mirrored back; a moved lens's frame into the camera's)
        pos = wp.vec3(px, py, -pz)
        dirn = wp.normalize(wp.vec3(L, M, -N))
        cos_s = float(0.0)
        if is_tilted(frame):
            pos = camera_point(frame, pos)
            dirn = wp.normalize(camera_dir(frame, dirn))
            # cos of the sensor ray (lens frame, unreversed: toward -z) to the sensor's normal (camera -z)
            cos_s = -camera_dir(frame, wp.vec3(d[0], d[1], -d[2]))[2]
        rad = sk.scene_radiance(scn, pos, dirn, lam, us)
        if rad <= 0.0:
            continue
        # 6. irradiance estimate
        n_img = medium_index(media, 0, w2)
        n_obj = medium_index(media, n_surfaces, w2)
        c2 = d[3] * d[3]
        e = float(0.0)
        if is_tilted(frame):
            e = rad * (n_img * n_img) / (n_obj * n_obj) * cos_s * c2 * d[3] * area / (rd * rd * pdf)
        else:
            e = rad * (n_img * n_img) / (n_obj * n_obj) * c2 * c2 * area / (rear_dist * rear_dist * pdf)
        k = int(0)
        if n_bands > 1:
            k = wp.clamp(int((lam - band0) * inv_band), 0, n_bands - 1)
        spec[o * n_bands + k] = spec[o * n_bands + k] + e * inv_band
        fx = (lam - scn.lam0) / scn.dlam
        if fx >= 0.0 and fx <= float(scn.n_lam - 1):
            m = wp.min(int(fx), scn.n_lam - 2)
            t = fx - float(m)
            for c in range(3):
                acc[c] = acc[c] + e * km * ((1.0 - t) * cmf[c, m] + t * cmf[c, m + 1])
    xyz[o] = acc
    hits[o] = wp.int32(n_ok)

@wp.kernel
def pupil_probe(surf: wp.array2d(dtype=wp.float32), media: wp.array2d(dtype=wp.float32),
                iris: wp.array(dtype=wp.float32),
                n_surfaces: int, table: wp.array2d(dtype=wp.float32), rec: wp.array3d(dtype=wp.float32),
                sensor_z: float, rear_dist: float, radii: wp.array(dtype=float),
                pts: wp.array(dtype=wp.vec2), lams: wp.array(dtype=float), n_pts: int, n_lam: int,
                tid_base: int, out: wp.array(dtype=wp.int32)):
    tid = wp.tid() + tid_base
    p = tid % n_pts
    k = (tid // n_pts) % n_lam
    i = tid // (n_pts * n_lam)
    x = radii[i]
    q = pts[i * n_pts + p]
    dx = q[0] - x
    dy = q[1]
    inv = 1.0 / wp.sqrt(dx * dx + dy * dy + rear_dist * rear_dist)
    w_um = lams[k] * 1.0e-3
    status, where, px, py, pz, L, M, N, opl, mc = trace_ray(
        surf, media, iris, n_surfaces, x, 0.0, sensor_z, dx * inv, dy * inv, rear_dist * inv, w_um * w_um,
        table, -1, n_surfaces, 1, 0.0, 0, rec, 0, SymmetricLens())
    out[tid] = wp.int32(status)

@wp.kernel
def accumulate(src: wp.array(dtype=float), dst: wp.array(dtype=wp.float64)):
    i = wp.tid()
    dst[i] = dst[i] + wp.float64(src[i])

@wp.kernel
def accumulate_moments(src: wp.array(dtype=wp.vec3), s1: wp.array2d(dtype=wp.float64),
                       s2: wp.array2d(dtype=wp.float64)):
    # per-pixel sums of the pass values and of their squares (exact in float64: bit-identical to the host)
    i = wp.tid()
    for c in range(3):
        v = wp.float64(src[i][c])
        s1[i, c] = s1[i, c] + v
        s2[i, c] = s2[i, c] + v * v

@wp.kernel
def finalize(src: wp.array(dtype=wp.float64), inv_n: wp.float64, dst: wp.array(dtype=float)):
    # the mean over all paths, as float32 (what the host would compute from the float64 sums)
    i = wp.tid()
    dst[i] = float(src[i] * inv_n)


#: the camera kernel per sensor variant: False -- the plain camera, True -- a tilt-shift camera
CAMERA_PASS = {False: wp.overload(camera_pass, {"frame": CentredSensor}),
               True: wp.overload(camera_pass, {"frame": TiltedSensor})}


@lru_cache(maxsize=None)
def get_render_kernels() -> SimpleNamespace:
    """The render kernels in a namespace (compiled on first launch)."""
    from ..device import warp
    warp()
    return SimpleNamespace(camera_pass=CAMERA_PASS[False], camera_pass_tilted=CAMERA_PASS[True],
                           pupil_probe=pupil_probe, accumulate=accumulate,
                           accumulate_moments=accumulate_moments, finalize=finalize,
                           module=MODULE, trace_ray=trace_ray)
