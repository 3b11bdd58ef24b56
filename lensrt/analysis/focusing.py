"""Focusing a lens with its own mechanism, solved with real rays, and its focus breathing.

:func:`focus_at` moves the lens's :class:`~lensrt.prescription.focusing.FocusMechanism`
(unit focusing, a focus group, floating groups) until the real best focus
(:func:`lensrt.analysis.focus.best_focus`: the plane of minimum RMS spot radius of
the axial point, a uniformly filled real pupil) of an object at the given distance
lies on the image surface. The travel parameter t is the extension e (mm) for unit
focusing, the group's travel (mm) for a focus group, and the object vergence 1/s
(1/mm) that the floating table is read at for floating groups; the residual
``best focus z - image z`` is driven to zero by the secant method.

:func:`focus_breathing` measures the angle of view against focus distance with
real rays: at each distance the lens is focused by :func:`focus_at` and the real
chief ray that lands at the sensor's half diagonal is found; its object-space
angle is the half angle of view. Beside it, the unit-focus formula of the Field
Guide (p. 18), alpha = 2 atan(d / (2 b f)) with b = 1 + |m| / m_p.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from ..prescription.focus_travel import move_mechanism, solve_travel
from ..prescription.model import Lens

__all__ = ["FocusSolution", "move_mechanism", "focus_residual_mm", "focus_at", "real_half_field_rad",
           "real_half_fields_rad",
           "largest_field_value", "image_circle_radius_mm", "BreathingCurve", "focus_breathing"]


@dataclass(frozen=True)
class FocusSolution:
    """A lens focused by its mechanism: ``lens`` has the object at ``distance_mm``."""

    lens: Lens
    distance_mm: float
    travel: float
    travel_unit: str
    residual_mm: float
    iterations: int
    mechanism: str

    def to_dict(self) -> dict:
        return {"distance_mm": self.distance_mm, "travel": self.travel, "travel_unit": self.travel_unit,
                "residual_mm": self.residual_mm, "iterations": self.iterations, "mechanism": self.mechanism,
                "gaps_mm": {str(i + 1): s.thickness_mm for i, s in enumerate(self.lens.surfaces)
                            if i in self.lens.focus.gaps or (self.lens.focus.is_unit and i == self.lens.n_surfaces - 1)}}


def focus_residual_mm(lens: Lens, distance_mm: float, wavelength_nm: float | None = None) -> float:
    """Real best focus minus the image surface's z (mm) for an axial object at ``distance_mm``."""
    from .compare.focus import best_focus
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    at = lens if distance_mm == lens.object_distance_mm else lens.replace(object_distance_mm=float(distance_mm))
    return best_focus(at, [wl], [1.0], 0.0).z_mm - lens.image_z_mm


def focus_at(lens: Lens, distance_mm: float, wavelength_nm: float | None = None, tol_mm: float = 1e-9,
             max_iter: int = 40) -> FocusSolution:
    """Focus ``lens`` at ``distance_mm`` (in front of the first vertex; ``inf``) with its own mechanism.

    Raises :class:`LensrtError` when the mechanism cannot bring the real best focus
    onto the image surface within ``tol_mm`` in ``max_iter`` secant steps.
    """
    d = float(distance_mm)
    if math.isnan(d) or d <= 0.0:
        raise LensrtError(f"focus distance {distance_mm!r} mm must be positive (inf for infinity)")
    t, r, it, unit = solve_travel(lens, d, lambda moved: focus_residual_mm(moved, d, wavelength_nm),
                                  tol_mm, max_iter)
    moved = move_mechanism(lens, t).replace(object_distance_mm=d)
    return FocusSolution(moved, d, float(t), unit, float(r), it, lens.focus.describe())


def _chief_tracer(lens: Lens, wavelength_nm: float | None):
    """vs -> (real chief-ray heights on the image surface, their object-space angles), vs object field values
    (NaN where the chief ray does not pass). All the values are aimed and traced together (one aiming run and
    one trace for the lot)."""
    from .raysets import chief_batch, object_field_point, trace64
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)

    def trace(vs) -> tuple[np.ndarray, np.ndarray]:
        vs = np.atleast_1d(np.asarray(vs, dtype=np.float64))
        batch = chief_batch(lens, [object_field_point(lens, float(v)) for v in vs], wl)
        res = trace64(lens, batch)
        good = res.ok & batch.aimed
        y = np.where(good, res.position_mm[:, 1], np.nan)
        return y, np.where(good, np.arctan2(batch.direction[:, 1], batch.direction[:, 2]), np.nan)
    return trace


def largest_field_value(lens: Lens) -> float:
    """The lens's largest object field as an object-space value (rad at infinity, else mm in the object plane)."""
    f = lens.fields
    if math.isinf(lens.object_distance_mm):
        return f.max_radial if f.kind == "angle" else math.radians(89.0)
    if f.kind == "object_height":
        return f.max_radial
    angle = f.max_radial if f.kind == "angle" else math.radians(45.0)
    return lens.object_distance_mm * math.tan(min(angle, math.radians(89.0)))


def image_circle_radius_mm(lens: Lens, wavelength_nm: float | None = None) -> float:
    """Real chief-ray height on the image surface at the lens's largest field (mm)."""
    y, _ = _chief_tracer(lens, wavelength_nm)(largest_field_value(lens))
    return abs(float(y[0]))


def _field_guess(lens: Lens, image_height_mm: float, wavelength_nm: float | None) -> float:
    """Paraxial object field value (rad at infinity, else mm) imaged at ``image_height_mm``."""
    from ..paraxial import first_order
    fo = first_order(lens, wavelength_nm)
    if math.isinf(lens.object_distance_mm):
        return min(math.atan(image_height_mm / abs(fo.efl_mm)), math.radians(89.0))
    return image_height_mm / max(abs(fo.magnification), 1e-12)


#: object field values traced together in each round of :func:`real_half_field_rad`: the regula falsi
#: estimate and probes on either side of it at these fractions of the bracket
_PROBE_FRACTIONS = (3e-2, 1e-3, 3e-5, 1e-6)


def real_half_field_rad(lens: Lens, image_height_mm: float, wavelength_nm: float | None = None,
                        tol_mm: float = 1e-7, max_iter: int = 80) -> float:
    """Object-space angle of the real chief ray that lands at ``image_height_mm`` on the image surface (rad).

    The object field is bracketed between the axis and the lens's largest field; each round traces
    the regula falsi estimate together with probes on either side of it (one aiming run and one
    trace for all of them) and keeps the tightest bracket, until a chief ray lands within ``tol_mm``
    (``max_iter`` chief rays at most). The first round traces the bracket's end with probes around
    the paraxial estimate. A height beyond the largest field's is an error.
    """
    return real_half_fields_rad([lens], image_height_mm, wavelength_nm, tol_mm, max_iter)[0]


def real_half_fields_rad(lenses: Sequence[Lens], image_height_mm: float, wavelength_nm: float | None = None,
                         tol_mm: float = 1e-7, max_iter: int = 80) -> list[float]:
    """:func:`real_half_field_rad` of several lenses, the searches run side by side.

    Each lens's search is the same sequence of rounds as on its own; the rounds run in lock-step, and
    when the lenses are unit-focus positions of one lens (:func:`_joint_chief_tracer`) every round's
    chief rays of all of them are aimed and traced together: one aiming run and one trace per round
    for the lot instead of one per lens (the focus-breathing table asks this at each distance).
    """
    lenses = list(lenses)
    searches = [_half_field_search(L, image_height_mm, wavelength_nm, tol_mm, max_iter) for L in lenses]
    joint = _joint_chief_tracer(lenses, wavelength_nm)
    alone = [_chief_tracer(L, wavelength_nm) for L in lenses] if joint is None else []
    out: list[float] = [math.nan] * len(lenses)
    asked = {}
    for k, s in enumerate(searches):
        asked[k] = next(s)  # a search always asks for one round at least
    while asked:
        got = joint(asked) if joint is not None else {k: alone[k](vs) for k, vs in asked.items()}
        for k, answer in got.items():
            try:
                asked[k] = searches[k].send(answer)
            except StopIteration as done:
                out[k] = done.value
                del asked[k]
    return out


def _joint_chief_tracer(lenses: Sequence[Lens], wavelength_nm: float | None):
    """{k: field values of lens k} -> {k: (heights, angles)} as :func:`_chief_tracer` of each lens gives them,
    for all lenses in one aiming run and one trace -- or None where the lenses cannot share them.

    They can when they differ only in the object distance and the last thickness (unit-focus positions
    of one lens) and the image surface is a plane without a change of frame: the chief rays to the stop
    are then the same computation for each lens (same pupil geometry, same surfaces up to the stop), and
    a ray traced to the first lens's image plane continues in a straight line to another's (z differs by
    the extension). The heights differ from a trace of each lens on its own by rounding (~1e-15 mm).
    """
    from ..trace.aiming import pupil_geometry
    from .raysets import chief_batch, object_field_point, trace64
    if not _share_rays(lenses):
        return None
    base = lenses[0]

    def key(L: Lens) -> float:
        g = pupil_geometry(L)
        return max(g.ep_radius_mm, g.stop_radius_mm)

    if len({key(L) for L in lenses}) > 1:  # aiming's parameters differ: not the same Newton iterates
        return None
    wl = base.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    z_image = np.array([L.image_z_mm for L in lenses])

    def trace(asked: dict) -> dict:
        ks = list(asked)
        vss = [np.atleast_1d(np.asarray(asked[k], dtype=np.float64)) for k in ks]
        batch = chief_batch(base, [object_field_point(lenses[k], float(v)) for k, vs in zip(ks, vss) for v in vs], wl)
        res = trace64(base, batch)
        dz = np.concatenate([np.full(len(vs), z_image[k] - z_image[0]) for k, vs in zip(ks, vss)])
        d = res.direction
        with np.errstate(divide="ignore", invalid="ignore"):
            y = res.position_mm[:, 1] + dz * d[:, 1] / d[:, 2]
        good = res.ok & batch.aimed & (d[:, 2] > 0.0)
        y = np.where(good, y, np.nan)
        ang = np.where(good, np.arctan2(batch.direction[:, 1], batch.direction[:, 2]), np.nan)
        ends = np.cumsum([0] + [len(vs) for vs in vss])
        return {k: (y[a:b], ang[a:b]) for k, a, b in zip(ks, ends[:-1], ends[1:])}

    return trace


def _share_rays(lenses: Sequence[Lens]) -> bool:
    """Whether the lenses (two at least) are unit-focus positions of one lens that one trace can serve: they
    differ only in the object distance and the last thickness, the image surface is a plane square to the
    axis without a change of frame (every ``image_*`` setting of the lens at its default), and the paraxial
    entrance pupil -- where aiming and pupil boxes put their frames -- is at the same z."""
    from dataclasses import MISSING, fields
    from ..trace.aiming import pupil_geometry
    if len(lenses) < 2:
        return False
    base = lenses[0]
    last = base.n_surfaces - 1
    t_base = base.surfaces[last].thickness_mm
    plain = all(f.default is MISSING or getattr(base, f.name) == f.default
                for f in fields(base) if f.name.startswith("image_"))
    if not plain or any(L.n_surfaces != base.n_surfaces or L.replace_surface(last, thickness_mm=t_base).replace(
            object_distance_mm=base.object_distance_mm) != base for L in lenses[1:]):
        return False
    return len({pupil_geometry(L).ep_z_mm for L in lenses}) == 1


def _focus_all(lens: Lens, distances_mm: Sequence[float], wavelength_nm: float | None) -> list[FocusSolution]:
    """:func:`focus_at` at every distance. Unit focusing takes one secant step (the best focus of the lens as it
    is, then of the lens moved by that extension, as the check: :func:`solve_travel`); each of the two is
    evaluated for all distances together (:func:`_best_focus_residuals`) where one trace serves them all,
    and the same :func:`solve_travel` turns them into solutions."""
    d = [float(x) for x in distances_mm]
    if not lens.focus.is_unit or len(d) < 2 or any(math.isnan(x) or x <= 0.0 for x in d):
        return [focus_at(lens, x, wavelength_nm) for x in d]
    start = [move_mechanism(lens, 0.0) for _ in d]
    r0 = _best_focus_residuals(start, d, wavelength_nm)
    if r0 is None:
        return [focus_at(lens, x, wavelength_nm) for x in d]
    moved = [move_mechanism(lens, t) for t in r0]
    r1 = _best_focus_residuals(moved, d, wavelength_nm)
    out = []
    for k, x in enumerate(d):
        table = {start[k]: r0[k], moved[k]: r1[k]}
        t, r, it, unit = solve_travel(lens, x, lambda L, table=table: table[L])
        out.append(FocusSolution(move_mechanism(lens, t).replace(object_distance_mm=x), x, float(t), unit, float(r),
                                 it, lens.focus.describe()))
    return out


def _best_focus_residuals(lenses: list[Lens], distances_mm: list[float], wavelength_nm: float | None
                          ) -> list[float] | None:
    """:func:`focus_residual_mm` of each (lens, distance) from one batched best-focus search
    (:func:`lensrt.trace.focus.focus_moments_fields`), or None where the lenses do not share their rays."""
    from ..paraxial import first_order
    from ..trace.focus import best_focus_plane, focus_moments_fields
    from .raysets import object_field_point
    ats = [L if x == L.object_distance_mm else L.replace(object_distance_mm=x) for L, x in zip(lenses, distances_mm)]
    if not _share_rays(ats):
        return None
    wl = lenses[0].wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    jobs = [(object_field_point(A, 0.0), wl, first_order(A, A.wavelengths.primary_nm).image_z_mm) for A in ats]
    moments = focus_moments_fields(ats[0], jobs)
    return [best_focus_plane([m], [1.0]).z_mm - L.image_z_mm for m, L in zip(moments, lenses)]


def _half_field_search(lens: Lens, image_height_mm: float, wavelength_nm: float | None, tol_mm: float,
                       max_iter: int):
    """The search of :func:`real_half_field_rad` as a generator: it yields the object field values to trace
    next, is sent back their (heights, angles) as :func:`_chief_tracer` gives them, and returns the angle."""
    h = abs(float(image_height_mm))
    lo, hi = 0.0, _field_guess(lens, 1.3 * h, wavelength_nm)
    v_par = _field_guess(lens, h, wavelength_nm)
    fractions = np.asarray(_PROBE_FRACTIONS)
    probes = v_par * np.concatenate([[1.0], 1.0 - fractions, 1.0 + fractions])
    ys, angles = yield np.concatenate([[hi], probes])
    y_hi = float(ys[0])
    if math.isnan(y_hi):  # shrink until the chief ray passes (the candidates of 40 shrink steps, traced together)
        shrink = hi * 0.8 ** np.arange(1, 41)
        ys_s = (yield shrink)[0]
        passing = np.nonzero(np.isfinite(ys_s))[0]
        k = int(passing[0]) if len(passing) else 39
        hi, y_hi = float(shrink[k]), float(ys_s[k])
    limit = math.radians(89.0) if math.isinf(lens.object_distance_mm) else 50.0 * hi
    while abs(y_hi) < h and hi < limit:  # beyond the lens's nominal field, while real chief rays still pass
        wider = min(1.2 * hi, limit)
        y_wider = float((yield np.atleast_1d(wider))[0][0])
        if math.isnan(y_wider):
            break
        hi, y_hi = wider, y_wider
    if not abs(y_hi) >= h:
        raise LensrtError(f"no real chief ray reaches {h:.4g} mm on the image surface: the widest that passes "
                          f"lands at {abs(y_hi):.4g} mm", hint="use a smaller sensor (the image circle is smaller)")
    bracket = [lo, -h, hi, abs(y_hi) - h]
    inside = (probes > lo) & (probes < hi)
    a, done = _tighten(bracket, probes[inside], ys[1:][inside], angles[1:][inside], h, tol_mm)
    if done:
        return a
    return (yield from _bracketed_root(h, bracket, tol_mm, max_iter))


def _tighten(bracket: list, vs: np.ndarray, ys: np.ndarray, angles: np.ndarray, h: float,
             tol_mm: float) -> tuple[float, bool]:
    """Fold traced probes (field values ``vs``, heights ``ys``, chief angles) into ``bracket`` =
    [lo, f_lo, hi, f_hi] (in place): the last probe below the root and the first above it.
    Returns (|angle| of the probe closest to the height, whether it lands within tol_mm)."""
    fv = np.abs(ys) - h
    fin = np.isfinite(fv)
    if not fin.any():
        return 0.0, False
    best = int(np.nanargmin(np.where(fin, np.abs(fv), np.nan)))
    if abs(fv[best]) < tol_mm:
        return abs(float(angles[best])), True
    below, above = fin & (fv < 0.0), fin & (fv > 0.0)
    if above.any():
        j = int(np.argmax(above))
        bracket[2], bracket[3] = float(vs[j]), float(fv[j])
        below &= vs < bracket[2]
    if below.any():
        j = int(np.nonzero(below)[0][-1])
        bracket[0], bracket[1] = float(vs[j]), float(fv[j])
    return abs(float(angles[best])), False


def _bracketed_root(h: float, bracket: list, tol_mm: float, max_iter: int):
    """|chief angle| at the field value in [lo, hi] where |y| - h changes sign (bracket = [lo, f_lo, hi, f_hi],
    f_lo < 0 < f_hi), found by rounds of regula falsi estimates and probes around them traced together
    (see :func:`real_half_field_rad`); a generator like :func:`_half_field_search`."""
    a, used, spread = 0.0, 0, False
    fractions = np.asarray(_PROBE_FRACTIONS)
    while used < max_iter and bracket[2] > bracket[0]:
        lo, f_lo, hi, f_hi = bracket
        v = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        w = hi - lo
        vs = np.unique(np.clip(np.concatenate([[v], v - w * fractions, v + w * fractions]), lo, hi))
        vs = vs[(vs > lo) & (vs < hi)]
        if spread or len(vs) == 0:  # evenly over the bracket (after a round where no chief ray passed)
            vs = np.linspace(lo, hi, 2 + 2 * len(fractions))[1:-1]
        ys, angles = yield vs
        used += len(vs)
        if not np.isfinite(ys).any():
            if spread:
                break
            spread = True
            continue
        spread = False
        a, done = _tighten(bracket, vs, ys, angles, h, tol_mm)
        if done:
            break
    return a


@dataclass
class BreathingCurve:
    """Angle of view against focus distance: real (the lens's mechanism) and the unit-focus formula."""

    distances_mm: np.ndarray
    afov_real_deg: np.ndarray
    afov_unit_formula_deg: np.ndarray
    travel: np.ndarray
    travel_unit: str
    sensor_diagonal_mm: float
    efl_mm: float
    mechanism: str
    residual_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict:
        return {"distance_mm": self.distances_mm, "afov_real_deg": self.afov_real_deg,
                "afov_unit_focus_formula_deg": self.afov_unit_formula_deg, "travel": self.travel,
                "travel_unit": self.travel_unit, "sensor_diagonal_mm": self.sensor_diagonal_mm,
                "efl_at_infinity_mm": self.efl_mm, "mechanism": self.mechanism,
                "focus_residual_mm": self.residual_mm,
                "definition": "diagonal AFoV: twice the object-space angle of the real chief ray that lands at "
                              "half the sensor diagonal, the lens focused by its own mechanism (real best focus "
                              "on the sensor); formula: Field Guide p. 18, 2 atan(d / (2 b f)), b = 1 + |m|/mp"}


def focus_breathing(lens: Lens, distances_mm: Sequence[float], sensor_diagonal_mm: float,
                    wavelength_nm: float | None = None) -> BreathingCurve:
    """Real AFoV against focus distance for the lens's own mechanism, beside the unit-focus formula."""
    from ..paraxial import first_order
    from ..paraxial.photographic import focus_breathing_afov_rad
    fo = first_order(lens.replace(object_distance_mm=math.inf), wavelength_nm)
    real, formula, travel, resid = [], [], [], []
    unit = ""
    sols = _focus_all(lens, distances_mm, wavelength_nm)
    halves = real_half_fields_rad([sol.lens for sol in sols], 0.5 * sensor_diagonal_mm, wavelength_nm)
    for d, sol, half in zip(distances_mm, sols, halves):
        real.append(2.0 * math.degrees(half))
        formula.append(math.degrees(focus_breathing_afov_rad(float(d), fo.efl_mm, sensor_diagonal_mm,
                                                             fo.pupil_magnification)))
        travel.append(sol.travel)
        resid.append(sol.residual_mm)
        unit = sol.travel_unit
    return BreathingCurve(np.asarray(distances_mm, dtype=np.float64), np.array(real), np.array(formula),
                          np.array(travel), unit, float(sensor_diagonal_mm), fo.efl_mm, lens.focus.describe(),
                          np.array(resid))
