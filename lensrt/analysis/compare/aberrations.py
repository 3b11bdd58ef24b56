"""Ray fans, OPD fans and spot diagrams from real rays.

Ray fan
    Transverse ray aberration (x, y of a ray minus the reference chief ray's, on
    the image surface or a given plane, mm) against the pupil coordinate along a
    tangential (Px = 0, Py in [-1, 1]) or sagittal (Py = 0, Px) line. All
    wavelengths are referred to the *primary* wavelength's chief ray, so lateral
    colour shows as an offset. Pupil coordinates are fractions of the real stop
    radius (``aim="real"``) or CODE V's paraxial-pupil offsets about the real chief
    ray (``aim="chief"``); see :mod:`lensrt.trace.aiming`.
OPD fan
    Optical path difference to the reference sphere centred on the chief ray's
    image point (of the same wavelength, on the same plane) and passing through
    the real exit pupil (where the real chief ray crosses the axis in image space;
    the paraxial exit pupil on axis; a plane perpendicular to the chief ray when
    the exit pupil is at infinity). OPD = path(ray) - path(chief ray), in waves:
    positive means the ray's path to the sphere is longer (its wavefront lags).
    CODE V's ``ssp`` prints the opposite sign (reference minus ray).
Spot diagram
    Ray landing points relative to the reference (the primary wavelength's chief
    ray, or the centroid), from a square grid over the real pupil (the dots, and a
    geometric radius = the largest distance of a grid ray), and Monte Carlo
    estimates from the stream kernel (RMS radius about the chief ray and about the
    centroid, centroid offset: :class:`lensrt.stats.Estimate` with jackknife
    standard errors over batches).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Lens
from ...stats import Estimate, jackknife
from ...units import NM_PER_MM
from ..raysets import (aim_batches, chief_batch, exit_pupil_point_z_mm, field_spec, object_field_point,
                       pupil_grid_rays_many, trace64, trace64_many)

__all__ = ["RayFan", "ray_fan", "fan_jobs", "trace_fans", "SpotDiagram", "spot_diagrams", "opd_to_reference_sphere_mm"]


def opd_to_reference_sphere_mm(p: np.ndarray, v: np.ndarray, opl: np.ndarray, chief: int, xp_z_mm: float,
                               n_image: float) -> np.ndarray:
    """OPD (mm, + = longer) of rays (p, v, opl on a plane) to the sphere about the chief ray's point there.

    The sphere passes through the chief ray's point at z = ``xp_z_mm`` (a plane
    perpendicular to the chief ray when that is infinite).
    """
    c, v0 = p[chief], v[chief]
    q = p - c
    if not math.isfinite(xp_z_mm):
        t = (q @ v0) / (v @ v0)
        path = opl - n_image * t
        return path - path[chief]
    s_e = (xp_z_mm - c[2]) / v0[2]  # chief point E = C + s_e v0 (s_e < 0: the pupil lies before the plane)
    radius2 = s_e * s_e
    b = np.sum(q * v, axis=1)
    disc = np.maximum(b * b - (np.sum(q * q, axis=1) - radius2), 0.0)
    root = np.sqrt(disc)
    t1, t2 = b + root, b - root
    t = np.where(np.abs(t1 + s_e) <= np.abs(t2 + s_e), t1, t2)  # the root near the pupil (t_chief = -s_e)
    path = opl - n_image * t
    return path - path[chief]


@dataclass
class RayFan:
    """A tangential or sagittal ray fan at one field point (module docstring). Arrays are (wavelengths, pupil);
    NaN where a ray did not reach the plane (``passed`` False)."""

    fan: str
    object_value: float
    infinite: bool
    label: str
    wavelengths_nm: np.ndarray
    pupil: np.ndarray
    ex_mm: np.ndarray
    ey_mm: np.ndarray
    opd_waves: np.ndarray
    passed: np.ndarray
    plane_z_mm: float
    reference_mm: tuple[float, float]
    exit_pupil_z_mm: np.ndarray
    aim: str

    def to_dict(self) -> dict:
        return {"fan": self.fan, "field": self.label, "wavelengths_nm": self.wavelengths_nm, "pupil": self.pupil,
                "ex_mm": self.ex_mm, "ey_mm": self.ey_mm, "opd_waves": self.opd_waves, "passed": self.passed,
                "plane_z_mm": self.plane_z_mm, "reference_mm": self.reference_mm,
                "exit_pupil_z_mm": self.exit_pupil_z_mm, "aim": self.aim}


def fan_jobs(lens: Lens, hy: float = 0.0, fan: str = "tangential", wavelengths_nm: Sequence[float] | None = None,
             pupil: Sequence[float] | None = None, object_value: float | None = None) -> list[tuple]:
    """What :func:`ray_fan` aims (jobs for :func:`lensrt.analysis.raysets.aim_batches`): the reference chief ray
    at the primary wavelength, then per wavelength the fan and its chief ray -- so that a caller can aim the
    fans of many fields in one solve and hand each its part (``ray_fan(..., aimed=...)``)."""
    fp, wls, px, py = _fan_rays(lens, hy, fan, wavelengths_nm, pupil, object_value)[1:5]
    primary = lens.wavelengths.primary_nm
    return [(fp, 0.0, 0.0, primary)] + [job for w in wls for job in ((fp, px, py, float(w)),
                                                                      (fp, 0.0, 0.0, float(w)))]


def _fan_rays(lens: Lens, hy: float, fan: str, wavelengths_nm, pupil, object_value):
    """(label, field point, wavelengths, px, py, rho, object-space field value) of a fan."""
    if fan not in ("tangential", "sagittal"):
        raise LensrtError(f"unknown fan {fan!r}", hint="use 'tangential' or 'sagittal'")
    spec = field_spec(lens, hy) if object_value is None else None
    obj = spec.object_value if spec is not None else float(object_value)
    label = spec.label if spec is not None else f"{obj:g}"
    fp = object_field_point(lens, obj)
    wls = np.asarray(lens.wavelengths.nm if wavelengths_nm is None else wavelengths_nm, dtype=np.float64)
    rho = np.linspace(-1.0, 1.0, 41) if pupil is None else np.asarray(pupil, dtype=np.float64)
    px, py = (np.zeros_like(rho), rho) if fan == "tangential" else (rho, np.zeros_like(rho))
    px, py = np.concatenate([[0.0], px]), np.concatenate([[0.0], py])
    return label, fp, wls, px, py, rho, obj


def ray_fan(lens: Lens, hy: float = 0.0, fan: str = "tangential", wavelengths_nm: Sequence[float] | None = None,
            pupil: Sequence[float] | None = None, *, aim: str = "real", plane_z_mm: float | None = None,
            clip: bool = True, device: str | None = None, object_value: float | None = None,
            aimed: list | None = None, traced: tuple | None = None) -> RayFan:
    """Transverse-aberration and OPD fan (module docstring) at normalised field ``hy`` along +y.

    ``pupil`` default: 41 points in [-1, 1]; ``plane_z_mm`` default: the image surface;
    ``clip`` applies the clear apertures (False: CODE V's unblocked ssp rays). ``aimed``: the rays of
    :func:`fan_jobs` already aimed; ``traced``: those rays already traced to the plane (:func:`trace_fans`).
    """
    label, fp, wls, px, py, rho, obj = _fan_rays(lens, hy, fan, wavelengths_nm, pupil, object_value)
    z = lens.image_z_mm if plane_z_mm is None else float(plane_z_mm)
    # every ray of the fan aimed at once: the reference chief ray, then per wavelength the fan and its chief ray
    if aimed is None:
        aimed = aim_batches(lens, fan_jobs(lens, hy, fan, wavelengths_nm, pupil, object_value), aim, device)
    fans, (ref, *chiefs) = trace_fans(lens, [aimed], device, clip=clip, plane_z_mm=z)[0] if traced is None \
        else traced
    if not ref.ok[0]:
        raise LensrtError(f"the chief ray of field {label} does not reach the image")
    ref_xy = (float(ref.position_mm[0, 0]), float(ref.position_mm[0, 1]))
    k, m = len(wls), len(rho)
    ex, ey, opd = (np.full((k, m), np.nan) for _ in range(3))
    passed = np.zeros((k, m), dtype=bool)
    xps = np.full(k, np.nan)
    for i, w in enumerate(wls):
        rays, r, c = aimed[1 + 2 * i], fans[i], chiefs[i]
        p, v, opl = r.position_mm.copy(), r.direction.copy(), r.opl_mm.copy()
        p[0], v[0], opl[0] = c.position_mm[0], c.direction[0], c.opl_mm[0]
        ok = r.ok & rays.aimed
        ok[0] = bool(c.ok[0])
        xps[i] = exit_pupil_point_z_mm(lens, p[0], v[0], float(w))
        n_img = float(lens.indices(float(w))[-1])
        d = opd_to_reference_sphere_mm(p, v, opl, 0, xps[i], n_img) * NM_PER_MM / float(w)
        good = ok[1:] & ok[0]
        passed[i] = good
        ex[i] = np.where(good, p[1:, 0] - ref_xy[0], np.nan)
        ey[i] = np.where(good, p[1:, 1] - ref_xy[1], np.nan)
        opd[i] = np.where(good, d[1:], np.nan)
    return RayFan(fan, obj, fp.infinite, label, wls, rho, ex, ey, opd, passed, z, ref_xy, xps, aim)


def trace_fans(lens: Lens, aimed: Sequence[list | None], device: str | None = None, *, clip: bool = True,
               plane_z_mm: float | None = None) -> list[tuple | None]:
    """Several fans' aimed rays (each a :func:`fan_jobs` list aimed, or None) traced to the plane (default: the
    image surface): the fans of every wavelength in one trace; the reference chief rays and each wavelength's
    chief rays (without apertures: the reference even when vignetted) in another -- two launches for all.
    An entry is (fan results per wavelength, [reference, chief per wavelength]) as :func:`ray_fan` takes it
    (``traced``), the same as tracing that fan alone."""
    z = lens.image_z_mm if plane_z_mm is None else float(plane_z_mm)
    live = [a for a in aimed if a is not None]
    fans = trace64_many(lens, [b for a in live for b in a[1::2]], device, clip=clip, plane_z_mm=z)
    chiefs = trace64_many(lens, [b for a in live for b in [a[0]] + a[2::2]], device, plane_z_mm=z)
    out: list[tuple | None] = []
    i = j = 0
    for a in aimed:
        if a is None:
            out.append(None)
            continue
        n = len(a[1::2])
        out.append((fans[i:i + n], chiefs[j:j + n + 1]))
        i, j = i + n, j + n + 1
    return out


@dataclass
class SpotDiagram:
    """Spot diagram of one field point (module docstring). Points are relative to ``reference_mm``."""

    object_value: float
    infinite: bool
    label: str
    wavelengths_nm: tuple[float, ...]
    reference: str
    reference_mm: tuple[float, float]
    plane_z_mm: float
    x_mm: list[np.ndarray]  # per wavelength (grid rays that passed)
    y_mm: list[np.ndarray]
    geometric_radius_mm: float
    grid_rms_radius_mm: float
    estimates: dict[str, Estimate] = field(default_factory=dict)  # polychromatic (lens weights)
    per_wavelength: dict[float, dict[str, Estimate]] = field(default_factory=dict)
    geometric_radius_by_wavelength_mm: dict[float, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"field": self.label, "wavelengths_nm": self.wavelengths_nm, "reference": self.reference,
                "reference_mm": self.reference_mm, "plane_z_mm": self.plane_z_mm,
                "geometric_radius_mm": self.geometric_radius_mm, "grid_rms_radius_mm": self.grid_rms_radius_mm,
                **{k: v.to_dict() for k, v in self.estimates.items()},
                "per_wavelength": [{"wavelength_nm": w, **{k: v.to_dict() for k, v in e.items()},
                                    "geometric_radius_mm": self.geometric_radius_by_wavelength_mm.get(w)}
                                   for w, e in self.per_wavelength.items()]}


def _spot_estimates(sums: np.ndarray, samples: int, seconds: float, shift: tuple[float, float]) -> dict[str, Estimate]:
    """Jackknife estimates from per-batch sums (B, 5) = (w, wx, wy, wxx, wyy), positions relative to the
    chief ray; ``shift`` moves the RMS reference from the chief ray (0, 0) to another point."""
    b = sums.shape[0]
    method = f"jackknife over {b} batches"
    sx, sy = shift

    def rms_ref(t: np.ndarray) -> float:
        w, wx, wy, wxx, wyy = t
        return math.sqrt(max((wxx - 2 * sx * wx + sx * sx * w + wyy - 2 * sy * wy + sy * sy * w) / w, 0.0))

    def rms_cen(t: np.ndarray) -> float:
        w, wx, wy, wxx, wyy = t
        return math.sqrt(max((wxx + wyy) / w - (wx / w) ** 2 - (wy / w) ** 2, 0.0))

    out = {}
    for key, fn in (("rms_radius_mm", rms_ref), ("rms_radius_centroid_mm", rms_cen),
                    ("centroid_x_mm", lambda t: t[1] / t[0] - sx), ("centroid_y_mm", lambda t: t[2] / t[0] - sy)):
        v, se = jackknife(sums, fn)
        out[key] = Estimate(float(v), float(se), samples, seconds, method, "mm")
    return out


def spot_diagrams(lens: Lens, hy: Sequence[float], wavelengths_nm: Sequence[float] | None = None, *,
                  reference: str = "chief", plane_z_mm: float | None = None, n_grid: int = 21,
                  rays: int = 1 << 15, batches: int = 16, seed: int = 0, sampler: str = "sobol",
                  device: str | None = None) -> list[SpotDiagram]:
    """Spot diagrams at normalised fields ``hy`` (module docstring).

    ``rays`` Monte Carlo rays per field and wavelength (and again for the
    polychromatic estimate with the lens's wavelength weights). A field point
    whose every ray is vignetted has no spot diagram and is left out of the list.
    """
    from ...trace.sampling import spectrum_discrete
    from ...trace.stream import Grid, stream, stream_sources
    if reference not in ("chief", "centroid"):
        raise LensrtError(f"unknown spot reference {reference!r}", hint="use 'chief' or 'centroid'")
    wls = tuple(float(w) for w in (lens.wavelengths.nm if wavelengths_nm is None else wavelengths_nm))
    z = lens.image_z_mm if plane_z_mm is None else float(plane_z_mm)
    specs = [field_spec(lens, h) for h in hy]
    fps = [object_field_point(lens, s.object_value) for s in specs]
    primary = lens.wavelengths.primary_nm
    chief = trace64(lens, chief_batch(lens, fps, primary, device), device, plane_z_mm=z)
    # every field point's pupil box in one batched pass (the same sources as stream_source one by one)
    sources = stream_sources(lens, fps, plane_z_mm=z, layers=[0] * len(fps), wavelengths_nm=wls, device=device,
                             centres_mm=[(float(chief.position_mm[k, 0]), float(chief.position_mm[k, 1]))
                                         for k in range(len(fps))])
    # fields whose every ray is vignetted have no spot: they are left out
    keep = [k for k, src in enumerate(sources) if src.box.area_mm2 > 0 and chief.ok[k]]
    if not keep:
        raise LensrtError("no ray of any of these field points reaches the image")
    specs, fps, sources = [specs[k] for k in keep], [fps[k] for k in keep], [sources[k] for k in keep]
    chief_pos = chief.position_mm[keep]
    grid = Grid(1, 1, 1.0)
    table = dict(zip(lens.wavelengths.nm, lens.wavelengths.weights))

    # one stream launch for every wavelength's run and the polychromatic one: run s gives each field its
    # seed + s, its own random-number index (its position in the field list) and spectrum s -- the rays and
    # sums of that run launched alone
    spectra = [spectrum_discrete([w], [1.0]) for w in wls] + \
        [spectrum_discrete(list(wls), [table.get(w, 1.0) for w in wls])]
    runs = [replace(src, seed=seed + s, rng_index=k, spectrum=s) for s in range(len(spectra))
            for k, src in enumerate(sources)]
    t0 = time.perf_counter()
    res = stream(lens, runs, grid, rays, spectrum=spectra, sampler=sampler, seed=seed, batches=batches,
                 precision="float64", device=device)
    each = (time.perf_counter() - t0) / len(spectra)
    st = res.batch_stats[:, :, [1, 2, 3, 4, 5]]
    n_src = len(sources)
    per_wl = {w: (st[i * n_src:(i + 1) * n_src], res.rays_per_source, each) for i, w in enumerate(wls)}
    poly = (st[len(wls) * n_src:], res.rays_per_source, each)
    # the spot grids of every field point and wavelength: one pupil-box search, one trace
    grid_rays = pupil_grid_rays_many(lens, [(fp, w) for fp in fps for w in wls], n_grid, device)
    traced = iter(trace64_many(lens, [g for g in grid_rays if g is not None], device, clip=True, plane_z_mm=z))
    grids = [None if g is None else next(traced) for g in grid_rays]
    out = []
    for k, (spec, fp) in enumerate(zip(specs, fps)):
        xs, ys = [], []
        for i in range(len(wls)):
            r = grids[k * len(wls) + i]
            xs.append(np.zeros(0) if r is None else r.position_mm[r.ok, 0] - chief_pos[k, 0])
            ys.append(np.zeros(0) if r is None else r.position_mm[r.ok, 1] - chief_pos[k, 1])
        allx, ally = np.concatenate(xs), np.concatenate(ys)
        if not len(allx):
            continue
        est = _spot_estimates(poly[0][k], poly[1], poly[2], (0.0, 0.0))
        shift = (0.0, 0.0)
        if reference == "centroid":
            shift = (est["centroid_x_mm"].value, est["centroid_y_mm"].value)
            est = _spot_estimates(poly[0][k], poly[1], poly[2], shift)
        pw = {w: _spot_estimates(per_wl[w][0][k], per_wl[w][1], per_wl[w][2], shift) for w in wls}
        xs = [x - shift[0] for x in xs]
        ys = [y - shift[1] for y in ys]
        allx, ally = allx - shift[0], ally - shift[1]
        ref_mm = (float(chief_pos[k, 0] + shift[0]), float(chief_pos[k, 1] + shift[1]))
        rr = np.hypot(allx, ally)
        geo = {w: float(np.hypot(x, y).max()) if len(x) else math.nan for w, x, y in zip(wls, xs, ys)}
        out.append(SpotDiagram(spec.object_value, spec.infinite, spec.label, wls, reference, ref_mm, z, xs, ys,
                               float(rr.max()), float(math.sqrt(np.mean(rr * rr))), est, pw, geo))
    return out
