"""Light splat: point and small sphere lights traced from the light side with the tracer's stream kernel.

A scene of point and sphere lights only (no surfaces, no background, no uniform illumination:
the plan's ``light_splat``) is cheaper to render from the lights: every ray starts at a light,
goes through the lens and is binned on the sensor, as the bokeh tracer does
(:func:`lensrt.trace.stream.stream`, int64 fixed-point histograms, deterministic).

Radiometry. A point light of spectral intensity I(lambda) (W / (sr nm)) sends I d Omega into a
solid angle d Omega. The stream samples wavelengths in proportion to I (total T = int I d lambda)
and rays uniformly over a box of area A in a plane at distance D from the light, perpendicular
to the axis w through the entrance pupil, each with weight w = cos(theta) (D / rho)^2 = d Omega
D^2 / dA (``emitter="isotropic"``). The power reaching a pixel through the lens, weighted by a
channel response c(lambda), is then T A / (N D^2) times the pixel's histogram value (N rays);
divided by the pixel area it is the irradiance. Channels are the output bands (1 / band width
inside the band) and K_m x-bar, y-bar, z-bar (lux).

A Lambertian sphere light of radiance L and radius r looks, from the lens, like a uniformly bright
disc: intensity L pi r^2 toward the camera, spread over the disc. Each pass places K point
sources on that disc (stratified, jittered anew every pass, so the passes together integrate the
disc), each with intensity L pi r^2 / K; K grows with the disc's image size so that neighbouring
points land less than a pixel apart (at most 256). All share one pupil box: the box of the disc's
centre united with those of four rim points, grown by 5 %.

Passes: each pass traces spp_per_pass x pixels rays in all, the same number from every point
source (a sphere light's K disc points get K shares), with its own seed; per-pass images give
the per-pixel standard errors (batch means). All the lights of a pass go into one stream launch
(one per kind of spectrum: lines, tabulated), each source with its own spectrum and its light's
scale as a weight factor relative to the largest; the pupil boxes are found once for all lights
and rim points together, and cached.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..errors import LensrtError
from ..units import LUMINOUS_EFFICACY_LM_PER_W, MM_PER_M
from ..colour import cie_xyz_cmfs

__all__ = ["splat_feasible", "render_splat"]

_MAX_DISC_POINTS = 256


def splat_feasible(scene, lens, options) -> tuple[bool, str]:
    """Whether the light-side path can render this request (and why not)."""
    if options.window is not None:
        return False, "a window of the sensor was asked for"
    if not (scene.point_lights or scene.sphere_lights):
        return False, "no lights"
    return True, ""


def _disc_points(k: int, rng: np.random.Generator) -> np.ndarray:
    """k stratified, jittered points in the unit disc (Shirley-Chiu concentric map of a jittered grid)."""
    nx = max(1, int(math.floor(math.sqrt(k))))
    ny = int(math.ceil(k / nx))
    idx = np.arange(k)
    u = ((idx % nx) + rng.random(k)) / nx
    v = ((idx // nx) + rng.random(k)) / ny
    a, b = 2.0 * u - 1.0, 2.0 * v - 1.0
    r = np.where(np.abs(a) > np.abs(b), a, b)
    phi = np.where(np.abs(a) > np.abs(b), (math.pi / 4) * b / np.where(a == 0, 1, a),
                   math.pi / 2 - (math.pi / 4) * a / np.where(b == 0, 1, b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def _light_list(scene) -> list[dict]:
    """(name, centre mm, radius mm, intensity spectrum W/(sr nm) on the grid, line nm) per light."""
    out = []
    for p in scene.point_lights:
        out.append({"name": p.name, "centre": np.asarray(p.position_mm, float), "radius": 0.0,
                    "intensity": np.asarray(p.intensity.values, float), "line": p.intensity.line_nm})
    for s in scene.sphere_lights:
        area_m2 = math.pi * (s.radius_mm / MM_PER_M) ** 2
        out.append({"name": s.name, "centre": np.asarray(s.center_mm, float), "radius": float(s.radius_mm),
                    "intensity": np.asarray(s.radiance.values, float) * area_m2, "line": s.radiance.line_nm})
    return out


_BOX_CACHE: dict = {}


def _shared_boxes(lens, camera, lights: list[dict], wls, device: str) -> list:
    """Per light the PupilBox of its centre, united with its rim points' and grown by 5 % (None when no
    ray passes): every light's centre and rim points in one batched pupil-box search, cached per
    (lens, stop, wavelengths, lights, device) -- the boxes do not change between passes or renders."""
    from ..trace.stream import PupilBox, pupil_boxes
    key = (lens, camera.stop_radius_mm, tuple(float(w) for w in wls), str(device),
           tuple((tuple(float(v) for v in li["centre"]), float(li["radius"])) for li in lights))
    hit = _BOX_CACHE.get(key)
    if hit is not None:
        return hit
    centres = np.array([li["centre"] for li in lights], dtype=np.float64)
    boxes = pupil_boxes(lens, centres, wls, stop_radius_mm=camera.stop_radius_mm, device=device)
    # rim points: along each centre box's e1 and e2, one batched search for all sphere lights
    rims, owner = [], []
    for k, (li, box) in enumerate(zip(lights, boxes)):
        if li["radius"] > 0.0 and box.area_mm2 > 0.0:
            e1, e2 = np.asarray(box.e1), np.asarray(box.e2)
            for d in (e1, -e1, e2, -e2):
                rims.append(li["centre"] + li["radius"] * d)
                owner.append(k)
    rim_boxes = pupil_boxes(lens, np.array(rims), wls, stop_radius_mm=camera.stop_radius_mm,
                            device=device) if rims else []
    out = []
    for k, box in enumerate(boxes):
        if box.area_mm2 <= 0.0:
            out.append(None)
            continue
        a0, a1, b0, b1 = box.a0, box.a1, box.b0, box.b1
        for rim, o in zip(rim_boxes, owner):
            if o == k and rim.area_mm2 > 0:
                a0, a1, b0, b1 = min(a0, rim.a0), max(a1, rim.a1), min(b0, rim.b0), max(b1, rim.b1)
        ga, gb = 0.05 * (a1 - a0), 0.05 * (b1 - b0)
        out.append(PupilBox(box.centre, box.axis, box.e1, box.e2, a0 - ga, a1 + ga, b0 - gb, b1 + gb))
    if len(_BOX_CACHE) > 32:
        _BOX_CACHE.clear()
    _BOX_CACHE[key] = out
    return out


def _channels(plan, grid, band0: float, bw: float, nb: int):
    """Channel table: the output bands (1 / width inside) then K_m x-bar, y-bar, z-bar."""
    from ..trace.stream import Channels
    if not plan.spectral:
        lam = float(plan.wavelength_nm)
        cm = cie_xyz_cmfs(grid)
        xyz = [LUMINOUS_EFFICACY_LM_PER_W * float(np.interp(lam, grid.nm, cm[c])) for c in range(3)]
        table = np.array([[1.0] * 3] + [[v] * 3 for v in xyz])
        return Channels(table, lam - 1.0, 1.0)
    step = 0.5
    nm = np.arange(grid.min_nm, grid.max_nm + 0.5 * step, step)
    rows = []
    for k in range(nb):
        lo, hi = band0 + k * bw, band0 + (k + 1) * bw
        rows.append(np.where((nm >= lo) & ((nm < hi) | ((k == nb - 1) & (nm <= hi))), 1.0 / bw, 0.0))
    cm = cie_xyz_cmfs(grid)
    for c in range(3):
        rows.append(LUMINOUS_EFFICACY_LM_PER_W * np.interp(nm, grid.nm, cm[c]))
    return Channels(np.array(rows), float(grid.min_nm), step)


def _splat_lights(scene, lens, cam, plan, dev) -> list[dict]:
    """Every light that reaches the lens: its shared pupil box, distance, spectrum and disc points."""
    from ..trace.sampling import spectrum_continuous, spectrum_discrete
    g, sen = scene.grid, cam.sensor
    wls = [float(plan.wavelength_nm)] if not plan.spectral else [g.min_nm, 0.5 * (g.min_nm + g.max_nm), g.max_nm]
    all_lights = _light_list(scene)
    lights = []
    for li, box in zip(all_lights, _shared_boxes(lens, cam, all_lights, wls, dev)):
        if box is None:
            continue
        c = li["centre"]
        w = np.asarray(box.axis)
        dist = float(np.dot(np.asarray(box.centre) - c, w))
        if li["line"] is not None:
            spec = spectrum_discrete([li["line"]], [1.0])
            total = float(li["intensity"][0])
        else:
            power = 0.5 * (li["intensity"][:-1] + li["intensity"][1:]) * g.step_nm
            if not power.sum() > 0:
                continue
            spec = spectrum_continuous(g.nm, power)
            total = spec.total
        r_img = li["radius"] * cam.sensor_z_mm / max(-c[2], 1e-9)     # generous: sensor distance over depth
        k = 1 if li["radius"] == 0 else int(min(_MAX_DISC_POINTS, max(1, math.ceil((4.0 * r_img / sen.pitch_x_mm) ** 2))))
        lights.append({"light": li, "box": box, "dist": dist, "spec": spec, "total": total, "k": k})
    if not lights:
        raise LensrtError("no light of the scene gets through the lens")
    return lights


def render_splat(scene, lens, plan, options, progress=None):
    """Render a point/sphere-light scene from the light side (module docstring); a RenderResult."""
    from ..device import resolve_device
    from ..trace.aiming import FieldPoint
    from ..trace.stream import Grid, StreamSource, stream
    from .camera import setup_camera
    from .progressive import history_row, regions, relative_error, stop_rule
    from .setup import RenderResult, band_note, bands
    from .passes import PassSum, pass_seed
    t_start = time.perf_counter()
    dev = resolve_device(options.device)
    cam = setup_camera(scene, lens, options.focus)
    # a declared focus group / floating groups moved to focus (render.camera); a tilt-shift camera's lens moved in
    # front of the sensor (the stream traces it in the camera frame, onto the plane z = sensor_z_mm)
    lens = cam.forward_lens()
    sen = cam.sensor
    rows, cols = sen.shape
    n_px = rows * cols
    g = scene.grid
    band0, bw, nb = bands(plan, options.band_width_nm)
    chans = _channels(plan, g, band0, bw, nb)
    grid = Grid(cols, rows, sen.pitch_x_mm, sen.pitch_y_mm)
    # histogram bin (iy, ix) -> stored image pixel, through the camera's one map
    iy, ix = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    xb = -0.5 * cols * sen.pitch_x_mm + (ix + 0.5) * sen.pitch_x_mm
    yb = -0.5 * rows * sen.pitch_y_mm + (iy + 0.5) * sen.pitch_y_mm
    pr, pc = sen.pixel_of(xb, yb)
    order = (np.rint(pr).astype(np.int64) * cols + np.rint(pc).astype(np.int64)).ravel()
    gather = np.argsort(order, kind="stable")     # stored pixel p <- histogram bin gather[p]
    lights = _splat_lights(scene, lens, cam, plan, dev)
    # one stream launch per pass for every light (one per spectrum kind: lines and tabulated spectra);
    # each light's rays carry its scale (total x box area / (points x distance^2)) relative to the
    # largest, so that one fixed-point histogram holds them all
    kinds = sorted({L["spec"].mode for L in lights})
    for L in lights:
        L["scale"] = L["total"] * L["box"].area_mm2 / (L["k"] * L["dist"] ** 2)
    n_sources = sum(L["k"] for L in lights)
    rule = stop_rule(scene, options, n_px)
    spp = rule.max_samples // n_px
    spp_pass = options.spp_per_pass or max(1, spp // 8)
    planned = max(1, math.ceil(spp / spp_pass))
    rays_pass = spp_pass * n_px
    n_src = max(2, rays_pass // n_sources)
    seed = scene.render.seed if options.seed is None else int(options.seed)
    acc = PassSum(n_px, nb, (rows, cols), 1)
    history: list[dict] = []
    t_loop = time.perf_counter()
    cpu0 = time.process_time()
    area_m2 = sen.pixel_area_m2
    stop = None
    rays_done = 0
    pass_times = []
    kernel_s = 0.0
    while stop is None:
        t0 = time.perf_counter()
        ps = pass_seed(seed, acc.passes)
        rng = np.random.default_rng(ps)
        img = None
        for kind in kinds:
            group = [L for L in lights if L["spec"].mode == kind]
            top = max(L["scale"] for L in group)
            srcs = []
            for j, L in enumerate(group):
                li, box = L["light"], L["box"]
                pts = [li["centre"]]
                if L["k"] > 1:
                    e1, e2 = np.asarray(box.e1), np.asarray(box.e2)
                    uv = _disc_points(L["k"], rng) * li["radius"]
                    pts = [li["centre"] + a * e1 + b * e2 for a, b in uv]
                srcs += [StreamSource(FieldPoint(False, None, tuple(p)), box, cam.sensor_z_mm, (0.0, 0.0), 0,
                                      "isotropic", spectrum=j, weight=L["scale"] / top) for p in pts]
            res = stream(lens, srcs, grid, n_src, spectrum=[L["spec"] for L in group], channels=chans,
                         sampler="sobol", seed=(ps + 7919 * kind) & 0x7FFFFFFF, batches=2, precision="float32",
                         device=dev, stop_radius_mm=cam.stop_radius_mm)
            part = np.take(res.histogram[0].reshape(nb + 3, -1), gather, axis=1)
            part *= top / (res.rays_per_source * area_m2)
            img = part if img is None else img + part
            rays_done += res.rays_total
            kernel_s += float(res.extra.get("kernel_seconds", res.seconds))
        spec_pass = img[:nb].T.astype(np.float32)
        acc.add(img[nb:].T.astype(np.float32), 0, spec_pass)
        pass_times.append(time.perf_counter() - t0)
        elapsed = time.perf_counter() - t_loop
        err = relative_error(acc)
        history.append(history_row(acc, n_px, elapsed, err))
        stop = rule.reason(acc.passes * rays_pass, elapsed, err, acc.passes)
        if progress is not None:
            per = float(np.mean(pass_times[1:][-8:] or pass_times))
            progress(acc.passes, planned, elapsed, 0.0 if stop else per * max(planned - acc.passes, 0))
    seconds = time.perf_counter() - t_loop
    irr = (acc.spec / acc.passes).astype(np.float32).reshape(rows, cols, nb)
    centres = (np.array([float(plan.wavelength_nm)]) if not plan.spectral
               else band0 + (np.arange(nb) + 0.5) * bw)
    notes = [f"light splat: {len(lights)} light(s), " + ", ".join(f"{L['light']['name']} ({L['k']} point(s))"
                                                                  for L in lights)]
    bnote = band_note(plan, options.band_width_nm, bw)
    if bnote:
        notes.append(bnote)
    if plan.variant.diffraction:
        notes.append("the plan asks for diffraction; the integrator does not apply it (geometric optics only)")
    res = RenderResult(irr, centres, bw, plan.output_unit, acc.xyz_mean(), acc.xyz_stderr(), rays_done,
                       acc.passes * spp_pass, acc.passes, seconds, stop or "samples", "light_splat", dev, cam, plan,
                       regions(acc, rays_done, seconds), history, float("nan"),
                       {"total_before_passes": t_loop - t_start}, notes, None)
    res.cpu_seconds = time.process_time() - cpu0
    res.kernel_seconds = kernel_s
    return res
