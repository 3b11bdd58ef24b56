"""The camera of a render: lens, aperture, focus, sensor geometry, and the one image <-> sensor map.

Frames (docs/tutorials/render-a-scene.md): the lens frame of the scene (z along the axis, light toward +z,
first lens vertex at z = 0 in its focused position, +y up, +x to the photographer's right).
The sensor plane stands at ``sensor_z_mm``; a sensor-plane point is ``(x_mm, y_mm)`` centred
on the axis, +y up, as in the lens frame.

Image orientation. The lens forms an inverted image: a scene point up and to the right lands
on the sensor down and to the left. A camera stores its picture upright, as the photographer
saw the scene; so does lensrt. :meth:`SensorGrid.pixel_of` / :meth:`SensorGrid.position_of`
are the only map between sensor-plane positions and stored image arrays (row, col; origin at
the top-left, scikit-image convention): image row 0 (the top of the picture) is the sensor's
``y = -height/2`` edge, image column 0 (the picture's left) is the sensor's ``x = +width/2``
edge -- the sensor read out rotated by 180 degrees. Every stage of the render (the camera
kernel through :meth:`SensorGrid.affine`, the light splat, the tests) goes through it.

Focus. ``[camera] focus_distance`` (from the first vertex) puts the sensor at the lens's
*best focus* for an object at that distance: the plane of least RMS spot radius of real rays
from the axial object point over the whole (stopped-down) pupil, photopically weighted over
five wavelengths -- what contrast-detect autofocus converges to -- rather than the paraxial
image, which lies a little off for a real lens with spherical aberration (``focus="paraxial"``
keeps the paraxial image plane). ``focus_extension_mm`` moves the whole lens forward from its
infinity position by that much (unit focusing, Field Guide p. 12): in the lens frame the
sensor moves back by the extension. A lens that declares a focus group or floating groups
(:mod:`lensrt.prescription.focusing`) is focused at ``focus_distance`` by moving them instead,
the sensor fixed, to the same best-focus criterion (``Camera.lens`` is the moved lens).

Tilt-shift. ``[camera] lens_tilt_deg / lens_swing_deg / lens_shift_mm`` (or ``lensrt render
--lens-tilt-deg ...``) move the whole focused lens as a rigid body in front of the fixed sensor,
as a view camera does: focus first (the sensor stays where the untilted lens focuses), then the
lens turns about its stop and shifts (:mod:`lensrt.prescription.tilt_shift`, the same motion as
``lensrt bokeh``). The scene's frame stays the camera's frame (the untilted lens's frame);
:meth:`Camera.lens_frame` places the moved lens in it.

Aperture. ``[camera] f_number`` scales the stop's clear radius by N_lens / N (paraxially the
entrance pupil scales with the stop); opening wider than the lens's own f-number is an error.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from ..colour import WavelengthGrid, photopic_v

__all__ = ["SensorGrid", "Camera", "setup_camera", "best_focus_z_mm", "sensor_grid_of"]

#: wavelengths (nm) of the best-focus criterion in spectral renders, weighted by V(lambda)
_FOCUS_WAVELENGTHS_NM = (470.0, 510.0, 555.0, 600.0, 650.0)


@dataclass(frozen=True)
class SensorGrid:
    """The sensor's photosite grid and THE map between sensor-plane mm and stored image pixels.

    Attributes
    ----------
    width_mm, height_mm : float
        Active area, centred on the optical axis.
    pixels_x, pixels_y : int
        Columns and rows of the stored image.
    """

    width_mm: float
    height_mm: float
    pixels_x: int
    pixels_y: int

    def __post_init__(self) -> None:
        if not (self.width_mm > 0 and self.height_mm > 0 and self.pixels_x >= 1 and self.pixels_y >= 1):
            raise LensrtError(f"sensor {self.width_mm} x {self.height_mm} mm, {self.pixels_x} x {self.pixels_y} px "
                              "needs positive sizes")

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the stored image."""
        return (int(self.pixels_y), int(self.pixels_x))

    @property
    def pitch_x_mm(self) -> float:
        return self.width_mm / self.pixels_x

    @property
    def pitch_y_mm(self) -> float:
        return self.height_mm / self.pixels_y

    @property
    def pixel_pitch_um(self) -> float:
        return 1000.0 * self.pitch_x_mm

    @property
    def pixel_area_m2(self) -> float:
        return self.pitch_x_mm * self.pitch_y_mm * 1e-6

    @property
    def half_diagonal_mm(self) -> float:
        return 0.5 * math.hypot(self.width_mm, self.height_mm)

    def pixel_of(self, x_mm: np.ndarray | float, y_mm: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Continuous (row, col) of sensor-plane points in the stored (upright) image.

        Pixel (r, c) covers rows [r - 0.5, r + 0.5) and columns [c - 0.5, c + 0.5); row 0 is
        the sensor's ``y = -height/2`` edge (the top of the scene), column 0 its
        ``x = +width/2`` edge (the scene's left): the sensor rotated by 180 degrees.
        """
        x = np.asarray(x_mm, dtype=np.float64)
        y = np.asarray(y_mm, dtype=np.float64)
        col = (0.5 * self.width_mm - x) / self.pitch_x_mm - 0.5
        row = (y + 0.5 * self.height_mm) / self.pitch_y_mm - 0.5
        return row, col

    def position_of(self, row: np.ndarray | float, col: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Sensor-plane (x_mm, y_mm) of continuous stored-image (row, col): the inverse of :meth:`pixel_of`."""
        r = np.asarray(row, dtype=np.float64)
        c = np.asarray(col, dtype=np.float64)
        x = 0.5 * self.width_mm - (c + 0.5) * self.pitch_x_mm
        y = (r + 0.5) * self.pitch_y_mm - 0.5 * self.height_mm
        return x, y

    def affine(self) -> tuple[float, float, float, float]:
        """(x0, dx/dcol, y0, dy/drow) with x = x0 + col dx/dcol, y = y0 + row dy/drow: :meth:`position_of`
        as the kernels take it (they add the in-pixel offset in [-0.5, 0.5) to row and col)."""
        x0, y0 = self.position_of(0.0, 0.0)
        x1, _ = self.position_of(0.0, 1.0)
        _, y1 = self.position_of(1.0, 0.0)
        return float(x0), float(x1 - x0), float(y0), float(y1 - y0)

    def pixel_centres_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of every pixel centre, each of shape (rows, cols)."""
        rows, cols = np.meshgrid(np.arange(self.pixels_y), np.arange(self.pixels_x), indexing="ij")
        return self.position_of(rows, cols)


def sensor_grid_of(scene) -> SensorGrid:
    """The :class:`SensorGrid` of a scene's ``[sensor]``."""
    s = scene.sensor
    return SensorGrid(float(s.width_mm), float(s.height_mm), int(s.pixels_x), int(s.pixels_y))


@dataclass(frozen=True)
class Camera:
    """Lens, aperture, focus and sensor of a render (module docstring).

    Attributes
    ----------
    lens : Lens
        The lens as loaded (lens frame of the scene).
    sensor : SensorGrid
    sensor_z_mm : float
        z of the sensor plane (lens frame).
    focus_distance_mm : float
        First vertex -> plane of focus (``inf`` at infinity).
    focus_method : str
        ``"best"`` (least RMS spot) or ``"paraxial"``; with ``focus_extension_mm``, how the
        infinity position was found.
    stop_radius_mm : float or None
        Iris radius for the scene's f-number (``None``: the lens's own stop).
    f_number, working_f_number : float
        Paraxial N at infinity for this stop, and N_w = N (1 + |m| / m_p) at the focus distance (p. 31).
    magnification : float
        Paraxial m at the focus distance (negative: inverted).
    """

    lens: Lens
    sensor: SensorGrid
    sensor_z_mm: float
    focus_distance_mm: float
    focus_method: str
    stop_radius_mm: float | None
    f_number: float
    working_f_number: float
    magnification: float
    exit_pupil_z_mm: float
    tilt_rad: float = 0.0
    swing_rad: float = 0.0
    shift_mm: tuple[float, float] = (0.0, 0.0)

    @property
    def is_tilt_shift(self) -> bool:
        """Whether the lens is tilted, swung or shifted relative to the sensor."""
        return bool(self.tilt_rad or self.swing_rad or self.shift_mm[0] or self.shift_mm[1])

    def lens_frame(self) -> tuple[np.ndarray, np.ndarray]:
        """(origin, axes) of the moved lens's first-vertex frame in the camera frame (identity when not moved):
        a lens-frame point p is the camera point ``origin + axes @ p`` (pivot: the stop's vertex)."""
        from ..prescription.tilt_shift import lens_frame
        pivot = float(self.lens.vertex_z_mm()[self.lens.stop_index])
        return lens_frame(self.tilt_rad, self.shift_mm, pivot, self.swing_rad)

    def forward_lens(self) -> Lens:
        """The lens as the forward tracer sees it in the camera frame: tilted/shifted when asked, else itself."""
        from ..prescription.tilt_shift import tilt_shift_lens
        return tilt_shift_lens(self.lens, self.tilt_rad, self.shift_mm, swing_rad=self.swing_rad)

    def sensor_corners_in_lens_frame(self) -> np.ndarray:
        """The sensor's four corners (4, 3) in the moved lens's frame (the sensor is a rectangle at ``sensor_z_mm``)."""
        origin, rot = self.lens_frame()
        hw, hh = 0.5 * self.sensor.width_mm, 0.5 * self.sensor.height_mm
        corners = np.array([[sx * hw, sy * hh, self.sensor_z_mm] for sx in (-1, 1) for sy in (-1, 1)])
        return (corners - origin) @ rot          # rot^T (p - origin), row by row

    @property
    def rear_vertex_z_mm(self) -> float:
        """z of the last lens vertex: the plane on which rear-pupil points are sampled."""
        return float(self.lens.vertex_z_mm()[self.lens.n_surfaces - 1])

    @property
    def rear_distance_mm(self) -> float:
        """Sensor -> last vertex distance D along the axis (mm)."""
        return self.sensor_z_mm - self.rear_vertex_z_mm

    def to_dict(self) -> dict:
        return {"lens": self.lens.name, "sensor_z_mm": self.sensor_z_mm, "focus_distance_mm": self.focus_distance_mm,
                "focus_method": self.focus_method, "stop_radius_mm": self.stop_radius_mm,
                "f_number": self.f_number, "working_f_number": self.working_f_number,
                "magnification": self.magnification, "rear_distance_mm": self.rear_distance_mm,
                "lens_tilt_deg": math.degrees(self.tilt_rad), "lens_swing_deg": math.degrees(self.swing_rad),
                "lens_shift_mm": list(self.shift_mm),
                "sensor": {"width_mm": self.sensor.width_mm, "height_mm": self.sensor.height_mm,
                           "pixels": [self.sensor.pixels_x, self.sensor.pixels_y],
                           "pixel_pitch_um": self.sensor.pixel_pitch_um},
                "orientation": "upright: image row 0 = sensor y = -h/2, column 0 = sensor x = +w/2"}


def _stop_radius(lens: Lens, f_number: float | None) -> tuple[float | None, float]:
    """(iris radius override or None, paraxial f-number at infinity) for the asked f-number."""
    from ..paraxial.fnumber import check_f_number, full_aperture_f_number
    from ..trace.aiming import pupil_geometry
    if f_number is None:
        return None, full_aperture_f_number(lens)
    n_full = check_f_number(lens, f_number, "[camera] f_number")
    r_full = pupil_geometry(lens).stop_radius_mm
    return r_full * n_full / float(f_number), float(f_number)


def best_focus_z_mm(lens: Lens, object_distance_mm: float, wavelengths_nm: tuple[float, ...],
                    weights: tuple[float, ...], stop_radius_mm: float | None = None) -> float:
    """z (lens frame) of least weighted RMS spot radius for the axial object point at ``object_distance_mm``,
    with the stop at ``stop_radius_mm``: :mod:`lensrt.trace.focus`, the routine every table uses."""
    from ..trace.focus import best_focus_plane, focus_moments_many
    fp = _axial_point(object_distance_mm)
    moments = focus_moments_many(lens, [float(wl) for wl in wavelengths_nm], fp=fp, z0_mm=lens.image_z_mm,
                                 stop_radius_mm=stop_radius_mm)
    return best_focus_plane(moments, weights).z_mm


def _axial_point(distance_mm: float):
    from ..trace.aiming import FieldPoint
    if math.isinf(distance_mm):
        return FieldPoint(True, (0.0, 0.0, 1.0), None)
    return FieldPoint(False, None, (0.0, 0.0, -float(distance_mm)))


def _focus_weights(scene) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Wavelengths and weights for the focus criterion: the line of a monochromatic scene, else V(lambda)."""
    line = scene.line_nm if scene is not None else None
    mono = scene.spectral.wavelength_nm if scene is not None and scene.spectral.mode == "monochromatic" else None
    lam = line if line is not None else mono
    if lam is not None:
        return (float(lam),), (1.0,)
    g = WavelengthGrid(380.0, 780.0, 5.0)
    v = np.interp(_FOCUS_WAVELENGTHS_NM, g.nm, photopic_v(g))
    return _FOCUS_WAVELENGTHS_NM, tuple(float(x) for x in v)


def _focus_by_mechanism(lens: Lens, distance_mm: float, wls: tuple[float, ...], wts: tuple[float, ...],
                        stop_radius: float | None) -> Lens:
    """``lens`` with its focus group / floating groups moved so the best focus of ``distance_mm`` is on its image
    surface (the same criterion as :func:`best_focus_z_mm`)."""
    from ..prescription.focus_travel import move_mechanism, solve_travel

    def residual(moved: Lens) -> float:
        return best_focus_z_mm(moved, distance_mm, wls, wts, stop_radius) - moved.image_z_mm
    travel, _, _, _ = solve_travel(lens, distance_mm, residual, tol_mm=1e-7)
    return move_mechanism(lens, travel)


def setup_camera(scene, lens: Lens, focus: str = "best") -> Camera:
    """The :class:`Camera` of ``scene`` with ``lens`` (focus ``"best"`` or ``"paraxial"``; module docstring)."""
    from ..paraxial.first_order import first_order
    if focus not in ("best", "paraxial"):
        raise LensrtError(f"unknown focus method {focus!r}", hint="use best or paraxial")
    cam = scene.camera
    stop_radius, n_inf = _stop_radius(lens, cam.f_number)
    wls, wts = _focus_weights(scene)

    def image_z(distance_mm: float) -> float:
        if focus == "paraxial":
            return first_order(lens, None, distance_mm).image_z_mm
        return best_focus_z_mm(lens, distance_mm, wls, wts, stop_radius)

    if cam.focus_extension_mm is not None:
        from ..paraxial.photographic import unit_focus_object_distance_mm
        fo_inf = first_order(lens, None, math.inf)
        sensor_z = image_z(math.inf) + float(cam.focus_extension_mm)
        # the object distance from the front principal plane, then from the first vertex
        s = unit_focus_object_distance_mm(cam.focus_extension_mm, fo_inf.front_focal_length_mm,
                                          fo_inf.rear_focal_length_mm)
        dist = math.inf if math.isinf(s) else s + fo_inf.front_principal_z_mm
    else:
        dist = math.inf if cam.focus_distance_mm is None else float(cam.focus_distance_mm)
        if not math.isinf(dist) and not -dist < first_order(lens, None, math.inf).front_focal_z_mm:
            raise LensrtError(f"focus distance {dist / 1000.0:g} m is inside the lens's front focal point",
                              hint="focus farther away")
        if not lens.focus.is_unit and focus == "best":
            lens = _focus_by_mechanism(lens, dist, wls, wts, stop_radius)
            sensor_z = lens.image_z_mm  # the sensor stays; the lens's focus group moved
        else:
            sensor_z = image_z(dist)
    try:
        fo = first_order(lens, None, dist if math.isfinite(dist) and dist > 0 else math.inf)
        bellows, mag, xp_z = fo.bellows_factor, fo.magnification, fo.exit_pupil_z_mm
    except LensrtError:
        bellows, mag, xp_z = 1.0, 0.0, float("nan")
    sensor = sensor_grid_of(scene)
    if not sensor_z > float(lens.vertex_z_mm()[lens.n_surfaces - 1]):
        raise LensrtError(f"the focused image plane (z = {sensor_z:.4g} mm) lies inside the lens",
                          hint="focus farther away")
    camera = Camera(lens, sensor, float(sensor_z), float(dist), focus, stop_radius, float(n_inf),
                    float(n_inf * bellows), float(mag), float(xp_z))
    if cam.is_tilt_shift:
        camera = _tilt_shift(camera, cam)
    return camera


def _tilt_shift(camera: Camera, spec) -> Camera:
    """``camera`` with its focused lens tilted/swung/shifted as the scene's camera block asks (one clear error
    for a lens that cannot be moved, or a motion that puts the sensor into the lens)."""
    from dataclasses import replace
    moved = replace(camera, tilt_rad=float(spec.lens_tilt_rad), swing_rad=float(spec.lens_swing_rad),
                    shift_mm=(float(spec.lens_shift_mm[0]), float(spec.lens_shift_mm[1])))
    lens = camera.lens
    if lens.has_mirrors or not lens.is_centred:
        raise LensrtError("a tilt-shift camera needs a centred refractive lens: this lens has mirrors, tilts/decenters "
                          "or surface apertures", path=lens.path,
                          hint="drop lens_tilt_deg/lens_swing_deg/lens_shift_mm (--lens-tilt-deg ...) for this lens")
    moved.forward_lens()          # the motion's own checks (finite, below 45 deg)
    # the sensor must stay behind the moved lens's last surface (its rim included)
    last = lens.surfaces[-1]
    sd = last.semi_diameter_mm if last.semi_diameter_mm is not None else 0.0
    rim_z = camera.rear_vertex_z_mm + max(0.0, float(last.sag(min(sd, last.max_semi_diameter_mm))))
    z_near = float(moved.sensor_corners_in_lens_frame()[:, 2].min())
    if not z_near > rim_z:
        raise LensrtError(f"lens tilt {math.degrees(moved.tilt_rad):g} deg, swing {math.degrees(moved.swing_rad):g} deg "
                          f"puts a sensor corner {rim_z - z_near:.3g} mm into the lens's rear element",
                          path=lens.path, hint="tilt or swing less, or use a smaller sensor")
    return moved
