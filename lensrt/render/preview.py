"""A pinhole look at a scene: its layout and colours without the lens, in seconds.

For authoring scene files (is everything where it should be, lit as meant?)
and as a lens-free reference: an ideal pinhole at the scene origin with the
scene's sensor format at a chosen focal length, every pixel the CIE XYZ
(Y in cd/m^2) of the scene radiance seen through it, by Monte Carlo over the
pixel area, a jittered comb of 16 wavelengths per ray and the light samples. No lens: no blur,
distortion, vignetting or exposure; the image is upright as a photograph.
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..device import resolve_device, warp
from ..stats import Estimate
from ..units import LUMINOUS_EFFICACY_LM_PER_W
from ..colour import cie_xyz_cmfs
from .scene.model import Scene

__all__ = ["preview_pinhole"]

_KERNEL: Any = None
#: wavelengths per pinhole ray
N_WL = 16


def _kernel() -> Any:
    global _KERNEL
    if _KERNEL is None:
        wp = warp()
        from .scene import kernels as sk

        # n_wl is a runtime argument on purpose: a loop over a compile-time constant is unrolled by
        # Warp (up to 16 trips), which inlined scene_radiance 16 times and made the CUDA compile of
        # this kernel take more than 3 minutes on an H100 (2026-11-21)
        @wp.kernel
        def pinhole_xyz(scn: sk.SceneData, cmfs: wp.array2d(dtype=float), w: int, h: int, sw: float, sh: float,
                        f: float, spp: int, seed: int, km: float, n_wl: int, out: wp.array3d(dtype=float)):
            i, j = wp.tid()
            st = wp.rand_init(seed, i * w + j)
            span = scn.dlam * float(scn.n_lam - 1)
            acc = wp.vec3(0.0, 0.0, 0.0)
            for k in range(spp):
                # sensor point (x right, y up, image row 0 at the top, already upright) -> ray to -z
                x = ((float(j) + wp.randf(st)) / float(w) - 0.5) * sw
                y = (0.5 - (float(i) + wp.randf(st)) / float(h)) * sh
                d = wp.normalize(wp.vec3(x, y, -f))
                u = wp.vec3(wp.randf(st), wp.randf(st), wp.randf(st))
                # a comb of N_WL evenly spaced wavelengths with one random offset (hero-wavelength
                # style, Wilkie et al. 2014): no lens, so all wavelengths share the ray
                u0 = wp.randf(st)
                for q in range(n_wl):
                    lam = scn.lam0 + (float(q) + u0) / float(n_wl) * span
                    rad = sk.scene_radiance(scn, wp.vec3(0.0, 0.0, 0.0), d, lam, u)
                    fx = (lam - scn.lam0) / scn.dlam
                    m = wp.min(int(fx), scn.n_lam - 2)
                    t = fx - float(m)
                    for c in range(3):
                        acc[c] += rad * ((1.0 - t) * cmfs[c, m] + t * cmfs[c, m + 1])
            for c in range(3):
                out[i, j, c] = acc[c] * km * span / float(spp * n_wl)

        _KERNEL = pinhole_xyz
    return _KERNEL


def preview_pinhole(scene: Scene, width_px: int = 360, focal_length_mm: float = 50.0, samples_per_pixel: int = 16,
                    seed: int = 0, device: str | None = None) -> Estimate:
    """CIE XYZ image (H, W, 3), Y in cd/m^2, of ``scene`` through a pinhole; an :class:`Estimate`.

    The standard error is per pixel and channel, from two independent halves
    of the samples (two seeds), so it is rough; ``samples`` counts all rays.
    """
    if width_px < 1 or samples_per_pixel < 2 or not focal_length_mm > 0:
        raise ValueError("width_px >= 1, samples_per_pixel >= 2 and a positive focal length are needed")
    wp = warp()
    from .scene.pack import pack_scene
    dev = resolve_device(device)
    t0 = time.perf_counter()
    packed = pack_scene(scene, dev)
    sen = scene.sensor
    h = max(1, round(width_px * sen.height_mm / sen.width_mm))
    cm = wp.array(cie_xyz_cmfs(scene.grid).astype(np.float32), dtype=float, ndim=2, device=dev)
    halves = []
    for k in range(2):
        out = wp.zeros((h, width_px, 3), dtype=float, device=dev)
        wp.launch(_kernel(), dim=(h, width_px), device=dev,
                  inputs=[packed.data, cm, width_px, h, sen.width_mm, sen.height_mm, float(focal_length_mm),
                          samples_per_pixel // 2, 2 * seed + k, LUMINOUS_EFFICACY_LM_PER_W, N_WL, out])
        halves.append(out.numpy().astype(np.float64))
    value = 0.5 * (halves[0] + halves[1])
    stderr = 0.5 * np.abs(halves[0] - halves[1])
    n = 2 * (samples_per_pixel // 2) * h * width_px
    return Estimate(value, stderr, n, time.perf_counter() - t0, "two independent halves", "XYZ, Y in cd/m^2")
