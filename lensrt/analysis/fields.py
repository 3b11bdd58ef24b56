"""Field points for PSF and MTF maps: named fields, and sensor positions mapped back through the real chief ray.

A PSF map "9 x 9 over the sensor" means 9 x 9 *image* positions, evenly
spaced over the sensor format (corners and edge midpoints included). Which
object field lands there depends on the lens's distortion, so the map is
built backwards: the real chief ray (primary wavelength) is traced for a fine
set of normalised radial fields |H| along +y to the observation plane
(:func:`chief_height_table`); the image height is monotonic in |H| over the
lens's coverage, so the field of a sensor point at radius rho and azimuth phi
is |H| = h(rho) by cubic-spline interpolation of the inverted table,
at azimuth phi (or phi + pi where the image is inverted, e.g. a near object).
Rotational symmetry of the lens is assumed (lensrt's surfaces are
rotationally symmetric). Each PSF reports where its real chief ray actually
lands (its reference point), so the mapping's residual is visible.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens

__all__ = ["FieldSpec", "ChiefTable", "chief_height_table", "fields_for_image_points", "sensor_grid_fields",
           "lens_fields", "angle_fields", "height_fields", "normalised_fields", "image_height_fields",
           "parse_grid"]


@dataclass(frozen=True)
class FieldSpec:
    """One field point: normalised polar field (hx, hy) (see :mod:`lensrt.trace.aiming`) and a label.

    ``target_mm`` is the sensor position asked for (maps), ``grid_index`` (row, col) its place in
    the map with row 0 at the top (+y).
    """

    hx: float
    hy: float
    label: str = ""
    target_mm: tuple[float, float] | None = None
    grid_index: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hx) and math.isfinite(self.hy)):
            raise LensrtError(f"field {self.label or (self.hx, self.hy)} is not a finite number")

    def to_dict(self) -> dict:
        return {"hx": self.hx, "hy": self.hy, "label": self.label,
                "target_mm": None if self.target_mm is None else list(self.target_mm),
                "grid_index": None if self.grid_index is None else list(self.grid_index)}


@dataclass(frozen=True)
class ChiefTable:
    """Signed image height (mm, along +y) of the real chief ray against the normalised radial field |H|.

    ``clear_height_mm`` is the largest |height| up to which the chief ray also passes every clear
    aperture (traced with clipping): beyond it the beam is vignetted at least down to a cat's eye,
    and may not pass at all (a circular fisheye's rim).
    """

    h: np.ndarray
    height_mm: np.ndarray
    plane_z_mm: float
    clear_height_mm: float = math.inf

    @property
    def sign(self) -> float:
        return 1.0 if self.height_mm[-1] >= 0 else -1.0

    @property
    def max_height_mm(self) -> float:
        return float(abs(self.height_mm[-1]))

    def field_of_height(self, rho_mm: np.ndarray) -> np.ndarray:
        """Normalised radial field |H| whose chief ray lands at radius ``rho_mm`` (cubic spline of the inverse)."""
        from scipy.interpolate import CubicSpline
        rho = np.asarray(rho_mm, dtype=np.float64)
        if np.any(rho > self.max_height_mm * (1 + 1e-9)):
            raise LensrtError(f"image radius {rho.max():.4g} mm is beyond the lens's coverage: the real chief "
                              f"ray reaches {self.max_height_mm:.4g} mm at most",
                              hint="use a smaller --sensor format (or fewer/inner field points)")
        return CubicSpline(np.abs(self.height_mm), self.h)(rho)


@lru_cache(maxsize=16)
def _table(lens: Lens, plane_z_mm: float, h_max: float, n: int, device: str | None) -> ChiefTable:
    from ..trace import RayBatch, trace
    from ..trace.aiming import aim_rays, chief_rays, field_point
    from ..trace.api import kernel_to_stop
    if lens.fields.max_radial <= 0:
        raise LensrtError("the lens file declares only the axial field: off-axis points cannot be named",
                          hint="add a field to the lens file ([fields])")
    wl = lens.wavelengths.primary_nm
    hs_all = np.linspace(0.0, h_max, n)[1:]
    fps = []
    for h in hs_all:
        try:
            fps.append(field_point(lens, 0.0, float(h)))
        except LensrtError:
            break
    hs_all = hs_all[:len(fps)]
    # every chief ray of the table in one batched Newton solve and one trace (no per-field fallback:
    # the table ends at the first field that cannot be aimed, which then gets the slow path alone)
    to_stop = kernel_to_stop(lens, device)
    o, d, aimed = chief_rays(lens, fps, wl, to_stop, fallback=False) if fps else (np.zeros((0, 3)),) * 2 + (
        np.zeros(0, dtype=bool),)
    hs, ys, clear = [0.0], [0.0], 0.0
    for k, h in enumerate(hs_all):
        if not aimed[k]:
            ok_k = aim_rays(lens, fps[k], np.zeros(1), np.zeros(1), wl, "real", to_stop)
            if not ok_k[2][0]:
                break
            o[k], d[k], aimed[k] = ok_k[0][0], ok_k[1][0], True
    good = np.nonzero(~aimed)[0]
    m = int(good[0]) if len(good) else len(fps)
    if m:
        batch = RayBatch(o[:m], d[:m], np.full(m, wl))
        r = trace(lens, batch, "float64", device, clip=False, plane_z_mm=plane_z_mm)
        passes = trace(lens, batch, "float64", device, clip=True, plane_z_mm=plane_z_mm).ok
        for k in range(m):
            if not r.ok[k]:
                break
            y = float(r.position_mm[k, 1])
            if abs(y) <= abs(ys[-1]) or (len(ys) > 1 and np.sign(y) != np.sign(ys[-1])):
                break  # no longer monotonic: the end of the usable coverage
            hs.append(float(hs_all[k]))
            ys.append(y)
            if passes[:k + 1].all():
                clear = abs(y)
    if len(hs) < 3:
        raise LensrtError("the real chief ray cannot be traced off axis: no field mapping")
    return ChiefTable(np.array(hs), np.array(ys), float(plane_z_mm), clear)


def chief_height_table(lens: Lens, plane_z_mm: float, h_max: float | None = None, n: int = 49,
                       device: str | None = None) -> ChiefTable:
    """Trace the real chief ray for ``n`` normalised fields 0..``h_max`` (default 1.5, or the 90 deg limit)."""
    if h_max is None:
        h_max = 1.5
        if lens.fields.kind == "angle" and lens.fields.max_radial > 0:
            h_max = min(h_max, 0.999 * (0.5 * math.pi) / lens.fields.max_radial) \
                if lens.fields.max_radial < 0.5 * math.pi else 1.0
    return _table(lens, float(plane_z_mm), float(h_max), int(n), device)


def fields_for_image_points(lens: Lens, points_mm: Sequence[tuple[float, float]], plane_z_mm: float,
                            labels: Sequence[str] | None = None, grid_indices: Sequence | None = None,
                            device: str | None = None) -> list[FieldSpec]:
    """The field points whose real chief rays land at ``points_mm`` on the plane (module docstring)."""
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    rho = np.hypot(pts[:, 0], pts[:, 1])
    need = float(rho.max()) if len(rho) else 0.0
    table = chief_height_table(lens, plane_z_mm, device=device)
    if need > table.max_height_mm:  # try farther out before giving up
        table = chief_height_table(lens, plane_z_mm, h_max=3.0 * float(table.h[-1]), n=97, device=device)
    h = table.field_of_height(rho)
    out = []
    for i, ((x, y), r, hh) in enumerate(zip(pts, rho, h)):
        phi = math.atan2(y, x) if r > 0 else 0.5 * math.pi
        if table.sign < 0:
            phi += math.pi
        hx, hy = (0.0, 0.0) if r == 0 else (float(hh * math.cos(phi)), float(hh * math.sin(phi)))
        lab = labels[i] if labels is not None else f"({x:.2f}, {y:.2f}) mm"
        gi = tuple(grid_indices[i]) if grid_indices is not None else None
        out.append(FieldSpec(hx, hy, lab, (float(x), float(y)), gi))
    return out


def parse_grid(text: str) -> tuple[int, int]:
    """``"9x9"`` -> (rows, cols)."""
    try:
        a, b = (int(v) for v in text.lower().replace("*", "x").split("x"))
    except ValueError:
        raise LensrtError(f"bad grid {text!r}", hint="give it as ROWSxCOLS, e.g. 9x9") from None
    if a < 1 or b < 1 or a * b > 10000:
        raise LensrtError(f"grid {text!r} must have 1..10000 points")
    return a, b


def sensor_grid_fields(lens: Lens, sensor: str, grid: tuple[int, int], plane_z_mm: float,
                       device: str | None = None) -> list[FieldSpec]:
    """Fields for a rows x cols grid of image positions over a sensor format (corners included).

    Row 0 is the top (+y), column 0 the left (-x), as in images.
    """
    from ..paraxial.photographic import sensor_format
    fmt = sensor_format(sensor)
    rows, cols = grid
    xs = np.linspace(-0.5 * fmt.width_mm, 0.5 * fmt.width_mm, cols) if cols > 1 else np.zeros(1)
    ys = np.linspace(0.5 * fmt.height_mm, -0.5 * fmt.height_mm, rows) if rows > 1 else np.zeros(1)
    pts, idx = [], []
    for r, y in enumerate(ys):
        for c, x in enumerate(xs):
            pts.append((float(x), float(y)))
            idx.append((r, c))
    labels = [f"r{r}c{c}" for r, c in idx]
    return fields_for_image_points(lens, pts, plane_z_mm, labels, idx, device)


def lens_fields(lens: Lens) -> list[FieldSpec]:
    """The lens file's own field points, normalised."""
    m = lens.fields.max_radial
    out = []
    for x, y in zip(lens.fields.x, lens.fields.y):
        hx, hy = (x / m, y / m) if m > 0 else (0.0, 0.0)
        unit = "deg" if lens.fields.kind == "angle" else "mm"
        val = math.degrees(math.hypot(x, y)) if lens.fields.kind == "angle" else math.hypot(x, y)
        out.append(FieldSpec(float(hx), float(hy), f"{val:.4g} {unit}"))
    return out


def normalised_fields(values: Sequence[float]) -> list[FieldSpec]:
    """Normalised fields Hy (Hx = 0)."""
    return [FieldSpec(0.0, float(v), f"Hy {v:g}") for v in values]


def angle_fields(lens: Lens, angles_deg: Sequence[float]) -> list[FieldSpec]:
    """Field angles (deg, along +y) of a lens with an object at infinity (angle fields)."""
    if lens.fields.kind != "angle":
        raise LensrtError(f"this lens names its fields by {lens.fields.kind.replace('_', ' ')}, not angle",
                          hint="use --field (normalised) or --image-height-mm")
    m = lens.fields.max_radial
    if m <= 0 and any(a != 0 for a in angles_deg):
        raise LensrtError("the lens file declares only the axial field", hint="add a field to the lens file")
    return [FieldSpec(0.0, math.radians(a) / m if m > 0 else 0.0, f"{a:g} deg") for a in angles_deg]


def height_fields(lens: Lens, heights_mm: Sequence[float]) -> list[FieldSpec]:
    """Object heights (mm, along +y) of a lens with a finite object (object-height fields)."""
    if lens.fields.kind != "object_height":
        raise LensrtError(f"this lens names its fields by {lens.fields.kind.replace('_', ' ')}",
                          hint="use --field (normalised) or --image-height-mm")
    m = lens.fields.max_radial
    return [FieldSpec(0.0, h / m if m > 0 else 0.0, f"{h:g} mm object") for h in heights_mm]


def image_height_fields(lens: Lens, heights_mm: Sequence[float], plane_z_mm: float,
                        device: str | None = None) -> list[FieldSpec]:
    """Real image heights (mm, along +y) through the real chief-ray mapping."""
    pts = [(0.0, float(h)) for h in heights_mm]
    return fields_for_image_points(lens, pts, plane_z_mm, [f"{h:g} mm image" for h in heights_mm], None, device)
