"""The camera of a simulation: focus, aperture, pixel frame, and per depth the real chief-ray mapping
and relative illumination.

Pinhole input. The input image is the scene seen by an ideal pinhole at the
paraxial entrance pupil (z_EP) whose image fills the sensor: a pixel at picture
radius r_i (mm on the sensor) looks along tan(theta) = r_i / f_pin, with f_pin
the real lens's r / tan(theta) near the axis at the focus distance. An object
point at depth d (mm in front of the first vertex, the bokeh stage's frame) and
angle theta sits at height (d + z_EP) tan(theta).

Real mapping (distortion). For a table of real image radii r on the sensor
plane, :func:`lensrt.analysis.bokeh.trace.object_heights_for_image` finds the
object height y(r) at depth d whose real chief ray (primary wavelength, through
the centre of the real stop) lands at r; so each output radius r takes the
input at the ideal radius r_i(r) = f_pin |y| / (d + z_EP) (a backward warp;
azimuths are kept -- lensrt's surfaces are rotationally symmetric).

Relative illumination (flux method, as :mod:`lensrt.analysis.compare.vignetting` for a
finite object). A Lambertian object element dA at height y sends the flux
L dA P(y) into the lens, P the projected solid angle of the real, vignetted
pupil seen from it (stream kernel, Lambertian weights, batches); it lands on the
image area dA' with dA/dA' = (y / r) dy/dr from the same chief-ray table. So the
irradiance is E(r) = L P(y(r)) (y / r) dy/dr and RI(r) = E(r) / E(0)
(on the axis (dy/dr)^2). ``axis_gain_sr`` = P(0) (dy/dr)^2 turns scene radiance
into on-axis irradiance (the camera equation from real rays).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens

__all__ = ["Camera", "LayerOptics", "make_camera", "layer_optics", "cached_layer_optics", "picture_positions_mm",
           "object_heights", "pinhole_focal_mm", "far_depth_mm"]

#: radii of a layer's chief-ray table (0 .. 1.04 x the frame's corner radius)
TABLE_RADII = 24


@dataclass(frozen=True)
class Camera:
    """Lens, focus, aperture and pixel frame of a simulation (lengths in mm)."""

    lens: Lens
    focus: object  # lensrt.analysis.bokeh.focus.Focus
    stop_radius_mm: float | None
    f_number: float | None
    shape: tuple[int, int]
    pitch_mm: float
    sensor: str
    wavelength_nm: float
    z_ep_mm: float
    device: str | None = None

    @property
    def sensor_z_mm(self) -> float:
        return float(self.focus.sensor_z_mm)

    @property
    def corner_mm(self) -> float:
        rows, cols = self.shape
        return 0.5 * self.pitch_mm * math.hypot(cols - 1, rows - 1)

    def key(self) -> dict:
        """What the PSFs depend on (the cache key's camera part)."""
        return {"lens": repr(self.lens), "sensor_z_mm": round(self.sensor_z_mm, 9),
                "stop_radius_mm": self.stop_radius_mm, "shape": list(self.shape),
                "pitch_mm": round(self.pitch_mm, 12), "wavelength_nm": self.wavelength_nm}

    def to_dict(self) -> dict:
        return {"lens": self.lens.name, "focus": self.focus.to_dict(), "f_number": self.f_number,
                "stop_radius_mm": self.stop_radius_mm, "pixels": [self.shape[1], self.shape[0]],
                "pitch_um": self.pitch_mm * 1000.0, "sensor": self.sensor, "primary_wavelength_nm": self.wavelength_nm,
                "entrance_pupil_z_mm": self.z_ep_mm}


def make_camera(lens: Lens, shape: tuple[int, int], sensor: str = "full-frame", focus_m: float = math.inf,
                f_number: float | None = None, device: str | None = None) -> Camera:
    """The camera for an image of ``shape`` (rows, cols) spread over ``sensor`` (square pixels)."""
    from ..analysis.bokeh.focus import focus_lens, stop_radius_for_f_number
    from ..paraxial import first_order
    from ..paraxial.photographic import sensor_format
    fmt = sensor_format(sensor)
    rows, cols = shape
    pitch = fmt.width_mm / cols
    if abs(rows * pitch - fmt.height_mm) > 0.01 * fmt.height_mm + 0.5 * pitch:
        raise LensrtError(f"a {cols} x {rows} image on the {fmt.width_mm:g} x {fmt.height_mm:g} mm sensor would need "
                          "non-square pixels", hint=f"give --sensor {fmt.width_mm:g}x{rows * pitch:.4g} or crop the image")
    if not (focus_m > 0):
        raise LensrtError(f"focus distance {focus_m!r} m must be positive (inf for infinity)")
    focus = focus_lens(lens, focus_m * 1000.0)
    stop = None
    if f_number is not None:
        if not (math.isfinite(f_number) and f_number > 0):
            raise LensrtError(f"f-number {f_number!r} must be a positive number")
        stop = stop_radius_for_f_number(lens, float(f_number))
    wl = float(lens.wavelengths.primary_nm)
    z_ep = float(first_order(lens, wl).entrance_pupil_z_mm)
    return Camera(lens, focus, stop, f_number, (int(rows), int(cols)), float(pitch), sensor, wl, z_ep, device)


def picture_positions_mm(cam: Camera, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Picture-frame (u right, v up; mm, centred) of pixel (row, col); the sensor point is (-u, -v)
    (the picture is the sensor image turned by 180 degrees, as lensrt's renders and bokeh images are)."""
    r_n, c_n = cam.shape
    u = (np.asarray(cols, dtype=np.float64) - 0.5 * (c_n - 1)) * cam.pitch_mm
    v = (0.5 * (r_n - 1) - np.asarray(rows, dtype=np.float64)) * cam.pitch_mm
    return u, v


@dataclass
class LayerOptics:
    """One depth's real mapping and relative illumination (module docstring).

    ``radius_mm`` (n,) real image radii; ``object_height_mm`` (n,) |y|; ``ideal_radius_mm`` (n,) the pinhole
    radius of the same direction; ``ri`` (n,) and ``ri_stderr`` (n,); ``axis_gain_sr``.
    """

    depth_mm: float
    radius_mm: np.ndarray
    object_height_mm: np.ndarray
    ideal_radius_mm: np.ndarray
    ri: np.ndarray
    ri_stderr: np.ndarray
    axis_gain_sr: float
    extra: dict = field(default_factory=dict)

    def ideal_of_real(self, r_mm: np.ndarray) -> np.ndarray:
        """Pinhole radius (mm) of the direction whose real chief ray lands at ``r_mm``."""
        from scipy.interpolate import PchipInterpolator
        return PchipInterpolator(self.radius_mm, self.ideal_radius_mm)(np.asarray(r_mm, dtype=np.float64))

    def ri_at(self, r_mm: np.ndarray) -> np.ndarray:
        """Relative illumination at real radius ``r_mm`` (PCHIP through the table)."""
        from scipy.interpolate import PchipInterpolator
        return PchipInterpolator(self.radius_mm, self.ri)(np.asarray(r_mm, dtype=np.float64))

    def to_dict(self) -> dict:
        return {"depth_m": self.depth_mm / 1000.0, "radius_mm": self.radius_mm.tolist(),
                "ideal_radius_mm": self.ideal_radius_mm.tolist(), "relative_illumination": self.ri.tolist(),
                "relative_illumination_stderr": self.ri_stderr.tolist(), "axis_gain_sr": self.axis_gain_sr}


def object_heights(cam: Camera, depth_mm: float, radii_mm: np.ndarray) -> np.ndarray:
    """Signed object heights at ``depth_mm`` whose real chief rays land at ``radii_mm``; one error if any fails."""
    from ..analysis.bokeh.trace import object_heights_for_image
    y, ok = object_heights_for_image(cam.lens, depth_mm, cam.sensor_z_mm, radii_mm, cam.wavelength_nm, cam.device)
    if not np.all(ok):
        bad = float(np.min(np.asarray(radii_mm)[~ok]))
        raise LensrtError(f"no real chief ray from {depth_mm / 1000:g} m reaches the sensor {bad:.3g} mm off axis: the "
                          f"frame ({cam.corner_mm:.3g} mm to the corner) is beyond the lens's coverage",
                          hint="use a smaller --sensor format")
    return y


def pinhole_focal_mm(cam: Camera) -> float:
    """f_pin: the real r / tan(theta) near the axis for an object at the focus distance (far: 1e4 f)."""
    d = _focus_depth_mm(cam)
    r = 1e-3 * max(cam.corner_mm, cam.pitch_mm)
    y = abs(float(object_heights(cam, d, np.array([r]))[0]))
    return r * (d + cam.z_ep_mm) / y


def _focus_depth_mm(cam: Camera) -> float:
    s = float(cam.focus.distance_mm)
    return s if math.isfinite(s) else far_depth_mm(cam.lens)


def far_depth_mm(lens: Lens) -> float:
    """The depth that stands for infinity: 1e5 focal lengths (its blur is 1e-5 of the focal length's)."""
    from ..paraxial import first_order
    return 1e5 * abs(float(first_order(lens).efl_mm))


def _pupil_flux(cam: Camera, obj: np.ndarray, rays: int, seed: int) -> np.ndarray:
    """Per-batch projected solid angle (sr) of the real pupil from each object point (S, B)."""
    from ..analysis.bokeh.trace import pupil_boxes
    from ..trace.aiming import FieldPoint
    from ..trace.sampling import spectrum_discrete
    from ..trace.stream import Grid, StreamSource, stream
    boxes, _ = pupil_boxes(cam.lens, obj, [cam.wavelength_nm], cam.sensor_z_mm, stop_radius_mm=cam.stop_radius_mm,
                           device=cam.device, coarse=64, fine=32)
    srcs = [StreamSource(FieldPoint(False, None, tuple(float(v) for v in o)), b, cam.sensor_z_mm, (0.0, 0.0), 0,
                         "lambertian", seed=seed + k, rng_index=0) for k, (o, b) in enumerate(zip(obj, boxes))]
    res = stream(cam.lens, srcs, Grid(1, 1, 1.0), rays, spectrum=spectrum_discrete([cam.wavelength_nm]),
                 seed=seed, batches=16, device=cam.device, stop_radius_mm=cam.stop_radius_mm, histogram=False)
    n_b = res.rays_per_source // res.batches
    dist = np.array([float(np.dot(np.asarray(b.centre) - o, np.asarray(b.axis))) for o, b in zip(obj, boxes)])
    factor = np.asarray(res.pupil_area_mm2, dtype=np.float64) / n_b / dist ** 2
    return res.batch_stats[:, :, 1] * factor[:, None]


def layer_optics(cam: Camera, depth_mm: float, f_pin_mm: float, rays: int = 1 << 14, seed: int = 0) -> LayerOptics:
    """Real mapping and relative illumination of the depth ``depth_mm`` (module docstring)."""
    from scipy.interpolate import CubicSpline
    r = np.linspace(0.0, 1.04 * cam.corner_mm, TABLE_RADII)
    y_signed = object_heights(cam, depth_mm, r)  # negative where the lens inverts the image
    y = np.abs(y_signed)
    ideal = f_pin_mm * y / (depth_mm + cam.z_ep_mm)
    dy = CubicSpline(r, y)(r, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        jac = np.where(r > 0, y / np.where(r > 0, r, 1.0) * dy, dy ** 2)  # object area per image area
    obj = np.stack([np.zeros_like(r), y_signed, np.full_like(r, -depth_mm)], axis=1)
    p_b = _pupil_flux(cam, obj, rays, seed)  # (S, B)
    e_b = p_b * jac[:, None]
    ri = e_b.mean(axis=1) / e_b[0].mean()
    ri_b = e_b / e_b[0][None, :]
    ri_se = ri_b.std(axis=1, ddof=1) / math.sqrt(ri_b.shape[1])
    return LayerOptics(float(depth_mm), r, y, ideal, ri, ri_se, float(p_b[0].mean() * jac[0]),
                       {"pupil_projected_solid_angle_sr": p_b.mean(axis=1).tolist(), "area_ratio": jac.tolist()})


def cached_layer_optics(cam: Camera, depth_mm: float, f_pin_mm: float, rays: int, seed: int,
                        directory: "Path | None") -> LayerOptics:
    """:func:`layer_optics`, kept as JSON in ``directory`` (None: not cached), keyed by everything it depends on."""
    import hashlib
    import json
    from pathlib import Path
    if directory is None:
        return layer_optics(cam, depth_mm, f_pin_mm, rays, seed)
    key = json.dumps({"camera": cam.key(), "depth_mm": float(depth_mm), "f_pin_mm": round(f_pin_mm, 9),
                      "rays": int(rays), "seed": int(seed), "n": TABLE_RADII, "v": 1}, sort_keys=True)
    path = Path(directory) / f"optics_{hashlib.sha256(key.encode()).hexdigest()[:24]}.json"
    if path.is_file():
        try:
            d = json.loads(path.read_text(encoding="utf-8"))
            return LayerOptics(d["depth_mm"], *(np.array(d[k]) for k in ("r", "y", "ideal", "ri", "ri_se")),
                               d["gain"], d["extra"])
        except (OSError, ValueError, KeyError):
            pass
    opt = layer_optics(cam, depth_mm, f_pin_mm, rays, seed)
    data = {"depth_mm": opt.depth_mm, "r": opt.radius_mm.tolist(), "y": opt.object_height_mm.tolist(),
            "ideal": opt.ideal_radius_mm.tolist(), "ri": opt.ri.tolist(), "ri_se": opt.ri_stderr.tolist(),
            "gain": opt.axis_gain_sr, "extra": opt.extra}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data), encoding="utf-8")
    except OSError as err:
        raise LensrtError(f"cannot write the optics cache {path}: {err}", hint="give --cache-dir or --no-cache") from None
    return opt
