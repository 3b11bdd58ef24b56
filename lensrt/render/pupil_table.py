"""The exit-pupil table: per radial distance on the sensor, the box of rear-plane points whose rays pass.

pbrt-v4's realistic camera (Pharr, Jakob & Humphreys, *Physically Based Rendering*, 4th ed.,
5.3.3 "Exit pupil") samples rays from a sensor point toward the lens only inside a precomputed
bound of the exit pupil: for each radial bin of sensor distance from the axis it stores the 2-D
box, in the plane of the last lens vertex, of the points through which rays from sensor points
on the +x axis in that bin get through the whole lens. A sensor point at azimuth phi uses its
bin's box rotated by phi (the lens is rotationally symmetric). lensrt does the same:

* the box is found by tracing grids of rays (the render kernel's own float32 surface code, every
  aperture, the scene's shortest, middle and longest wavelengths) from several sensor radii
  spanning the bin: a coarse grid over a square that surely holds every ray passing the last
  surface, then a finer grid over the coarse bounds; the final box is the fine bounds grown by
  1.5 grid cells (a margin for rays between the grid points);
* a polygonal iris is replaced by its circumscribed circle for the table (rotating a bin's box
  must keep every passing ray inside it; the render itself traces the real iris);
* a box of zero area means no ray from that radius gets through (beyond the image circle);
* a tilt-shift camera (the lens moved as a rigid body in front of the sensor,
  :mod:`lensrt.render.camera`): the table lives in the moved lens's own frame, where the lens is
  still rotationally symmetric and the sensor is a tilted plane. Radii span the sensor's largest
  lens-frame radius, and each bin's box unites the rays passing from sensor points at three depths
  (the nearest and farthest sensor corner and the middle): a box that holds the pupil seen from
  every depth the sensor spans.

Inside a box the rear point is uniform (pdf 1 / area); rays that then fail carry zero weight, so
the estimate stays unbiased as long as the box holds the pupil -- which the margins are for --
and the table only decides how many samples are wasted (``pass_fraction``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from ..core.telemetry import launch, replay

__all__ = ["ExitPupilTable", "exit_pupil_table", "launch_sliced", "record_sliced", "replay_sliced", "circular_iris",
           "table_wavelengths", "sensor_span"]


@dataclass(frozen=True)
class ExitPupilTable:
    """Per radial bin of sensor distance from the axis, a box [a0, a1] x [b0, b1] (mm) in the plane of the
    last lens vertex, for sensor points on the +x axis (module docstring)."""

    r_max_mm: float
    boxes: np.ndarray            # (n_bins, 4): a0, a1, b0, b1 (mm)
    pass_fraction: np.ndarray    # (n_bins,): share of the box's fine grid whose rays passed
    wavelengths_nm: tuple[float, ...]
    seconds: float

    @property
    def n_bins(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def inv_dr(self) -> float:
        """Bins per mm of sensor radius."""
        return self.n_bins / self.r_max_mm

    @property
    def areas_mm2(self) -> np.ndarray:
        b = self.boxes
        return np.maximum(b[:, 1] - b[:, 0], 0.0) * np.maximum(b[:, 3] - b[:, 2], 0.0)

    def to_dict(self) -> dict:
        return {"bins": self.n_bins, "r_max_mm": self.r_max_mm, "seconds": self.seconds,
                "wavelengths_nm": list(self.wavelengths_nm),
                "area_mm2": [float(a) for a in self.areas_mm2],
                "pass_fraction": [float(f) for f in self.pass_fraction]}


def _cpu_workers(device: str, n: int) -> int:
    if device.startswith("cuda") or n < 4096:
        return 1
    import os
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def launch_sliced(kernel, n: int, inputs_of, device: str, workers: int | None = None) -> None:
    """Launch ``kernel`` over ``n`` threads; on the CPU as one slice per core (Warp runs a CPU launch on one
    core). ``inputs_of(base)`` gives the inputs of a slice whose thread ids start at ``base``; slices write
    disjoint outputs, so the result does not depend on the split."""
    from ..device import warp
    wp = warp()
    w = _cpu_workers(device, n) if workers is None else max(1, int(workers))
    bounds = [n * k // w for k in range(w + 1)]

    def run(k: int) -> None:
        if bounds[k + 1] > bounds[k]:
            launch(kernel, dim=bounds[k + 1] - bounds[k], inputs=inputs_of(bounds[k]), device=device,
                   slice_of=bounds[k])

    if w == 1:
        run(0)
        return
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(w) as pool:
        list(pool.map(run, range(w)))


def record_sliced(kernel, n: int, inputs_of, device: str, workers: int | None = None) -> list:
    """The launches of :func:`launch_sliced` recorded, not run (``wp.launch(..., record_cmd=True)``: arguments
    packed once): a list of (first thread id, ``wp.Launch``) for :func:`replay_sliced`, after any
    ``set_param_by_name`` on each of them."""
    from ..device import warp
    wp = warp()
    w = _cpu_workers(device, n) if workers is None else max(1, int(workers))
    bounds = [n * k // w for k in range(w + 1)]
    return [(bounds[k], wp.launch(kernel, dim=bounds[k + 1] - bounds[k], inputs=inputs_of(bounds[k]), device=device,
                                  record_cmd=True)) for k in range(w) if bounds[k + 1] > bounds[k]]


def replay_sliced(cmds: list) -> None:
    """Run the launches of :func:`record_sliced` (on the CPU, its slices on as many cores)."""
    if len(cmds) == 1:
        replay(cmds[0][1], slice_of=cmds[0][0])
        return
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(len(cmds)) as pool:
        list(pool.map(lambda c: replay(c[1], slice_of=c[0]), cmds))


def _region_half_mm(camera, r_max: float, dist_mm: float) -> float:
    """Half side of a square in the last-vertex plane that holds every ray passing the last surface, for sensor
    points at least ``dist_mm`` behind the last vertex."""
    s = camera.lens.surfaces[-1]
    sd = s.semi_diameter_mm if s.semi_diameter_mm is not None else 2.0 * dist_mm
    sag = abs(float(s.sag(min(sd, s.max_semi_diameter_mm))))
    tan_max = (r_max + sd) / max(dist_mm - sag, 1e-3)
    return 1.02 * (sd + sag * tan_max) + 1e-3


def sensor_span(camera) -> tuple[float, list[float]]:
    """(largest sensor radius (mm), sensor distances behind the last vertex (mm) whose pupils the table unites), in
    the lens's frame: the half diagonal and the one distance for a plain camera; for a tilt-shift camera the
    largest lens-frame corner radius and the nearest, middle and farthest corner depth."""
    if not camera.is_tilt_shift:
        return camera.sensor.half_diagonal_mm, [camera.rear_distance_mm]
    q = camera.sensor_corners_in_lens_frame()
    d = q[:, 2] - camera.rear_vertex_z_mm
    return float(np.hypot(q[:, 0], q[:, 1]).max()), [float(d.min()), float(0.5 * (d.min() + d.max())), float(d.max())]


def exit_pupil_table(camera, rev_packed, wavelengths_nm, n_bins: int = 48, radii_per_bin: int = 4,
                     coarse: int = 48, fine: int = 40, device: str = "cpu") -> ExitPupilTable:
    """Compute the :class:`ExitPupilTable` of ``camera`` (module docstring).

    ``rev_packed``: the reversed lens packed (float32) for the table, with a circular iris;
    ``wavelengths_nm``: wavelengths whose passing rays are united.
    """
    from ..device import warp
    from .integrator_kernels import get_render_kernels
    wp = warp()
    k = get_render_kernels()
    t0 = time.perf_counter()
    r_sensor, dists = sensor_span(camera)
    r_max = 1.001 * r_sensor
    dr = r_max / n_bins
    lams = np.asarray(sorted(set(float(w) for w in wavelengths_nm)), dtype=np.float64)
    half = _region_half_mm(camera, r_max, min(dists))
    radii = np.array([[dr * (j + f) for f in np.linspace(0.0, 1.0, radii_per_bin)] for j in range(n_bins)])
    table = wp.zeros((1, 1), dtype=float, device=device)
    rec = wp.zeros((1, 1, 9), dtype=float, device=device)
    lam_arr = wp.array(lams.astype(np.float32), dtype=float, device=device)

    def probe(boxes: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pass mask (bins, n*n) over an n x n grid of cell centres in each bin's box."""
        ga = (np.arange(n) + 0.5) / n
        pts = []
        for b in boxes:
            A, B = np.meshgrid(b[0] + ga * (b[1] - b[0]), b[2] + ga * (b[3] - b[2]), indexing="ij")
            pts.append(np.stack([A.ravel(), B.ravel()], axis=1))
        pts = np.concatenate(pts)                                   # (bins * n*n, 2)
        groups = n_bins * radii_per_bin
        pts_g = np.repeat(pts.reshape(n_bins, 1, n * n, 2), radii_per_bin, axis=1).reshape(-1, 2)
        n_pts = n * n
        total = groups * len(lams) * n_pts
        out = wp.zeros(total, dtype=wp.int32, device=device)
        radii_dev = wp.array(radii.ravel().astype(np.float32), dtype=float, device=device)
        pts_dev = wp.array(pts_g.astype(np.float32), dtype=wp.vec2, device=device)
        ok = None
        for dist in dists:                 # sensor z in the reversed frame is -dist
            inputs = [rev_packed.surf, rev_packed.media, rev_packed.iris, camera.lens.n_surfaces, table, rec,
                      float(-dist), float(dist), radii_dev, pts_dev, lam_arr, n_pts, len(lams)]
            launch_sliced(k.pupil_probe, total, lambda base: inputs + [base, out], device)
            got = (out.numpy().reshape(n_bins, radii_per_bin, len(lams), n_pts) == 0).any(axis=(1, 2))
            ok = got if ok is None else ok | got
        return ok, pts.reshape(n_bins, n_pts, 2), np.array([(b[1] - b[0]) / n for b in boxes])

    region = np.tile([-half, half, -half, half], (n_bins, 1)).astype(np.float64)
    ok, pts, cell = probe(region, coarse)
    box2 = np.zeros((n_bins, 4))
    for j in range(n_bins):
        if ok[j].any():
            p = pts[j][ok[j]]
            m = 1.5 * cell[j]
            box2[j] = (max(p[:, 0].min() - m, -half), min(p[:, 0].max() + m, half),
                       max(p[:, 1].min() - m, -half), min(p[:, 1].max() + m, half))
    live = (box2[:, 1] > box2[:, 0]) & (box2[:, 3] > box2[:, 2])
    safe = np.where(live[:, None], box2, region)
    ok2, pts2, _ = probe(safe, fine)
    boxes = np.zeros((n_bins, 4))
    frac = np.zeros(n_bins)
    for j in range(n_bins):
        if not live[j]:
            continue
        if not ok2[j].any():           # a sliver between fine points: keep the coarse box
            boxes[j] = box2[j]
            continue
        p = pts2[j][ok2[j]]
        ca, cb = (box2[j, 1] - box2[j, 0]) / fine, (box2[j, 3] - box2[j, 2]) / fine
        boxes[j] = (max(p[:, 0].min() - 1.5 * ca, box2[j, 0]), min(p[:, 0].max() + 1.5 * ca, box2[j, 1]),
                    max(p[:, 1].min() - 1.5 * cb, box2[j, 2]), min(p[:, 1].max() + 1.5 * cb, box2[j, 3]))
        frac[j] = ok2[j].sum() * ca * cb / max((boxes[j, 1] - boxes[j, 0]) * (boxes[j, 3] - boxes[j, 2]), 1e-30)
    if not live.any():
        raise LensrtError("no ray from the sensor gets through the lens (exit-pupil table is empty)",
                          hint="check the lens apertures and the focus")
    return ExitPupilTable(float(r_max), boxes, np.clip(frac, 0.0, 1.0), tuple(float(v) for v in lams),
                          time.perf_counter() - t0)


def circular_iris(lens):
    """The lens's iris with its blades replaced by the circumscribed circle (for the table)."""
    from dataclasses import replace
    ir = lens.iris
    return replace(ir, blades=0, rotation_rad=0.0, roundness=0.0) if ir.blades else ir


def table_wavelengths(plan) -> tuple[float, ...]:
    """The wavelengths a plan's table unites: the fixed one, or the grid's ends and middle."""
    if not plan.spectral:
        return (float(plan.wavelength_nm),)
    g = plan.grid
    return (float(g.min_nm), 0.5 * float(g.min_nm + g.max_nm), float(g.max_nm))

