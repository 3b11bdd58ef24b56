"""Independent float64 references for the render tests: sensor irradiance by quadrature over the real pupil.

For a uniformly bright Lambertian scene of radiance L (object and image space in air, T = 1), the
irradiance at sensor point p is E(p) = L * int cos(theta) d omega over the directions from p whose
rays get through the lens. Writing a direction by the point q where it crosses the plane of the
last lens vertex (distance D from the sensor), d omega cos(theta) = cos^4(theta) dA / D^2.

The passing set of q (the exit pupil seen from p, vignetted) is convex for the lenses used here
(an intersection of images of circular apertures), hence star-shaped about any interior point c:
for each of ``n_phi`` azimuths the boundary radius rho(phi) is found by bisection with the float64
reference tracer (lensrt.trace.reference) on the reversed lens, and

    E = L / D^2 * int_0^{2 pi} int_0^{rho(phi)} cos^4(theta(c + r u_phi)) r dr dphi

is summed with Gauss-Legendre in r and the trapezoid rule in phi. This shares no code with the
Monte Carlo integrator (no exit-pupil table, no Warp, no random numbers).
"""
from __future__ import annotations

import math

import numpy as np

from lensrt.trace.reference import trace_reference
from lensrt.trace.reverse import reversed_lens


def _passes(rev, p_rev_z: float, x: float, y: float, qx: float, qy: float, dist: float, wavelength_nm: float,
            stop_radius_mm) -> bool:
    d = np.array([qx - x, qy - y, dist])
    r = trace_reference(rev, (x, y, p_rev_z), tuple(d / np.linalg.norm(d)), wavelength_nm, stop_radius_mm=stop_radius_mm)
    return r.status == 0


def irradiance_quadrature(camera, x_mm: float, y_mm: float, radiance: float, wavelength_nm: float,
                          n_phi: int = 256, n_r: int = 8, bisections: int = 32) -> float:
    """Sensor-plane irradiance at (x_mm, y_mm) for a uniform scene of ``radiance`` (module docstring)."""
    lens = camera.lens
    rev = reversed_lens(lens, 0.0)
    z_s = camera.rear_vertex_z_mm - camera.sensor_z_mm
    dist = camera.rear_distance_mm
    sr = camera.stop_radius_mm

    def ok(qx: float, qy: float) -> bool:
        return _passes(rev, z_s, x_mm, y_mm, qx, qy, dist, wavelength_nm, sr)

    # an interior point: centroid of the passing points of a coarse grid
    sd = lens.surfaces[-1].semi_diameter_mm
    half = 1.6 * sd
    g = np.linspace(-half, half, 25)
    pts = [(a, b) for a in g for b in g if ok(a, b)]
    if not pts:
        return 0.0
    c = np.mean(np.array(pts), axis=0)
    if not ok(*c):
        raise RuntimeError("the pupil's centroid does not pass: not star-shaped about it")
    r_out = 4.0 * half
    nodes, weights = np.polynomial.legendre.leggauss(n_r)
    total = 0.0
    for k in range(n_phi):
        phi = 2.0 * math.pi * k / n_phi
        u = np.array([math.cos(phi), math.sin(phi)])
        lo, hi = 0.0, r_out
        for _ in range(bisections):
            mid = 0.5 * (lo + hi)
            if ok(*(c + mid * u)):
                lo = mid
            else:
                hi = mid
        rho = 0.5 * (lo + hi)
        r = 0.5 * rho * (nodes + 1.0)
        q = c[None, :] + r[:, None] * u[None, :]
        dx, dy = q[:, 0] - x_mm, q[:, 1] - y_mm
        cos2 = dist * dist / (dx * dx + dy * dy + dist * dist)
        total += float(np.sum(0.5 * rho * weights * cos2 * cos2 * r))
    return radiance * total * (2.0 * math.pi / n_phi) / (dist * dist)


def marginal_sine(camera, wavelength_nm: float, bisections: int = 60) -> float:
    """sin(theta') of the real marginal ray: the widest cone from the axial sensor point that passes."""
    rev = reversed_lens(camera.lens, 0.0)
    z_s = camera.rear_vertex_z_mm - camera.sensor_z_mm
    lo, hi = 0.0, 0.9
    for _ in range(bisections):
        m = 0.5 * (lo + hi)
        r = trace_reference(rev, (0.0, 0.0, z_s), (math.sin(m), 0.0, math.cos(m)), wavelength_nm,
                            stop_radius_mm=camera.stop_radius_mm)
        if r.status == 0:
            lo = m
        else:
            hi = m
    return math.sin(0.5 * (lo + hi))
