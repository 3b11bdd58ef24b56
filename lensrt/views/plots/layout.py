"""The lens cross-section with traced ray bundles (PNG via matplotlib's Agg canvas; imported lazily).

Surfaces are drawn to their clear semi-diameters; the two faces of an element
(glass between them) are joined at the rim by a flat flange and an edge parallel
to the axis, and the element is shaded. The stop is drawn as two blades outside
its clear radius; central obscurations (a reflex lens's secondary) as dark bars; the image surface as a line. Meridional rays of each field point
(aimed at the real stop) are spread evenly across the meridional extent of the
real, vignetted pupil (found by tracing 97 probe rays with every aperture), so the
drawn bundle is the one that reaches the image.

Folded and tilted systems (mirrors, coordinate transforms) are drawn in the
global y-z plane: every surface profile, ray point and the image line is
placed by its surface's frame (:func:`lensrt.prescription.frames.surface_frames`),
which for a centred lens is the vertex position on the axis (the same drawing
as before).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ...prescription.frames import surface_frames
from ...prescription.model import Lens

from .figure import drawn_by_workers, new_figure, save_figure

__all__ = ["plot_layout", "layout_fans", "draw_layout", "LayoutFan", "element_outlines", "to_plane"]

_FIELD_COLOURS = ("#1f4fb4", "#2a9d3b", "#d2361f", "#8b3fb0", "#c98a00", "#138c8c")


def to_plane(lens: Lens, i: int, y_mm: np.ndarray, z_mm: np.ndarray, x_mm: np.ndarray | float = 0.0
             ) -> tuple[np.ndarray, np.ndarray]:
    """Global (z, y) of points given in surface i's local frame (i = n_surfaces: the image surface)."""
    origin, axes = surface_frames(lens)[i]
    y, z = np.asarray(y_mm, dtype=np.float64), np.asarray(z_mm, dtype=np.float64)
    x = np.broadcast_to(np.asarray(x_mm, dtype=np.float64), y.shape)
    if np.array_equal(axes, np.eye(3)) and origin[0] == 0.0 and origin[1] == 0.0:
        return origin[2] + z, y  # centred: the vertex on the axis (no rounding from the product)
    g = origin[:, None] + axes @ np.stack([x, y, z])
    return g[2], g[1]


def _profile(lens: Lens, i: int, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global (z, y) of surface i's meridional profile at heights r (mm)."""
    s = lens.surfaces[i]
    return to_plane(lens, i, r, np.asarray(s.sag(np.minimum(np.abs(r), s.max_semi_diameter_mm))))


def element_outlines(lens: Lens) -> list[np.ndarray]:
    """Closed (z, y) outlines of each element: glass between surfaces i and i + 1 (upper and lower halves)."""
    out = []
    for i in range(lens.n_surfaces - 1):
        if lens.surfaces[i].material.is_air:
            continue
        sd1 = lens.surfaces[i].semi_diameter_mm or 1.0
        sd2 = lens.surfaces[i + 1].semi_diameter_mm or 1.0
        rim = max(sd1, sd2)
        s1, s2 = lens.surfaces[i], lens.surfaces[i + 1]
        y1 = np.linspace(-sd1, sd1, 61)
        y2 = np.linspace(sd2, -sd2, 61)
        zl1 = np.asarray(s1.sag(np.minimum(np.abs(y1), s1.max_semi_diameter_mm)))
        zl2 = np.asarray(s2.sag(np.minimum(np.abs(y2), s2.max_semi_diameter_mm)))
        zt1, zt2 = float(s1.sag(min(sd1, s1.max_semi_diameter_mm))), float(s2.sag(min(sd2, s2.max_semi_diameter_mm)))
        # front face, up its flange to the rim, along the edge, down the back flange, back face, and back
        a = to_plane(lens, i, np.concatenate([y1, [rim, rim]]), np.concatenate([zl1, [zt1, zt1]]))
        b = to_plane(lens, i + 1, np.concatenate([[rim, sd2], y2, [-sd2, -rim]]),
                     np.concatenate([[zt2, zt2], zl2, [zt2, zt2]]))
        c = to_plane(lens, i, np.array([-rim, -sd1]), np.array([zt1, zt1]))
        z = np.concatenate([a[0], b[0], c[0]])
        y = np.concatenate([a[1], b[1], c[1]])
        out.append(np.stack([z, y], axis=1))
    return out


def _draw_obscurations(ax, lens: Lens, i: int) -> None:
    """Surface i's central (circular, undecentred) obscurations as thick dark bars across the meridional section
    (not on a mirror, where an obscuration is an unsilvered zone)."""
    s = lens.surfaces[i]
    if s.mirror:
        return
    for a in s.apertures:
        if a.obscuration and a.shape in ("circle", "annulus") and not (a.decenter_x_mm or a.decenter_y_mm):
            lo = a.b if a.shape == "annulus" else 0.0
            for sgn in (1.0, -1.0):
                r = sgn * np.linspace(lo, a.a, 21)
                bz, by = to_plane(lens, i, r, np.asarray(s.sag(np.minimum(np.abs(r), s.max_semi_diameter_mm))))
                ax.plot(bz, by, color="0.15", lw=2.5, solid_capstyle="butt", zorder=4)


def plot_layout(path: str | Path, lens: Lens, hy: Sequence[float] | None = None, wavelength_nm: float | None = None,
                rays_per_field: int = 9, device: str | None = None, title: str = "") -> Path:
    """Cross-section of ``lens`` (y-z plane) with meridional ray bundles at normalised fields ``hy``.

    The rays are traced here (:func:`layout_fans`); the drawing (:func:`draw_layout`) may go to a
    figure worker process (:mod:`lensrt.views.plots.figure`)."""
    hy = [0.0, 0.7, 1.0] if hy is None else list(hy)
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    fans, img_h = layout_fans(lens, hy, wl, rays_per_field, device)
    return draw_layout(path, lens, fans, img_h, wl, title)


@dataclass(frozen=True)
class LayoutFan:
    """The drawn rays of one field: its label, and per ray (z_mm, y_mm, labelled) -- the global polyline
    from its start to where it ends (the image surface, or the surface that stops it), and whether its
    line carries the field's legend entry. ``vignetted``: every probe ray of the field was stopped, so no
    ray is drawn and the legend says so."""
    label: str
    polylines: tuple[tuple[np.ndarray, np.ndarray, bool], ...]
    vignetted: bool = False


def layout_fans(lens: Lens, hy: Sequence[float], wavelength_nm: float, rays_per_field: int = 9,
                device: str | None = None) -> tuple[list[LayoutFan], float]:
    """The meridional rays of :func:`plot_layout` at normalised fields ``hy``, traced in float64, and the
    largest image height of the rays that reach the image (mm).

    Rays are spread evenly across the meridional extent of the real (vignetted) pupil of every field
    (97 probe rays aimed together), then aimed and traced with every surface's intersection recorded."""
    from ...analysis.raysets import aim_batches, field_spec, object_field_point, trace64_many
    from ...trace.status import OK, TIR, VIGNETTED
    wl = float(wavelength_nm)
    vz = lens.vertex_z_mm()
    n = lens.n_surfaces
    ymax = max(s.semi_diameter_mm or 1.0 for s in lens.surfaces)
    z_start = -0.25 * max(float(vz[-1] - vz[0]), 4 * ymax)
    specs = [field_spec(lens, h) for h in hy]
    fps = [object_field_point(lens, spec.object_value) for spec in specs]
    probe = np.linspace(-1.2, 1.2, 97)
    probes = aim_batches(lens, [(fp, np.zeros_like(probe), probe, wl) for fp in fps], "real", device)
    passed = [r.ok & pr.aimed for r, pr in zip(trace64_many(lens, probes, device, clip=True), probes)]
    spread = []
    for ok in passed:
        step = probe[1] - probe[0]
        py = np.linspace(probe[ok].min() + 0.02 * step, probe[ok].max() - 0.02 * step, rays_per_field) \
            if ok.any() else np.zeros(0)
        spread.append(py)
    fans = aim_batches(lens, [(fp, np.zeros_like(py), py, wl) for fp, py in zip(fps, spread) if len(py)], "real",
                       device)
    fans = _traced_with_records(lens, fans, device)[::-1]  # every field's fan in one trace
    out, img_h = [], 0.0
    for k, spec in enumerate(specs):
        fp, py = fps[k], spread[k]
        lines = []
        if len(py):
            rays, res = fans.pop()
            for j in range(len(py)):
                st, where = int(res.status[j]), int(res.surface[j])
                rows = n + 1 if st == OK else (where + 1 if st in (VIGNETTED, TIR) else max(where, 0))
                if rows == 0:
                    continue
                rec = res.records[j, :rows]
                pts = [to_plane(lens, q, rec[q:q + 1, 1], rec[q:q + 1, 2], rec[q:q + 1, 0]) for q in range(rows)]
                z = np.array([float(p[0][0]) for p in pts])
                y = np.array([float(p[1][0]) for p in pts])
                o, d = rays.origin_mm[j], rays.direction[j]
                start = o + ((z_start - o[2]) / d[2]) * d if fp.infinite else o
                lines.append((np.concatenate([[start[2]], z]), np.concatenate([[start[1]], y]), j == 0))
                if st == OK:
                    img_h = max(img_h, abs(float(rec[-1, 1])))
        out.append(LayoutFan(spec.label, tuple(lines), not len(py)))
    return out, img_h


@drawn_by_workers
def draw_layout(path: str | Path, lens: Lens, fans: Sequence[LayoutFan], image_height_mm: float,
                wavelength_nm: float, title: str = "") -> Path:
    """Draw the cross-section of ``lens`` with the rays of :func:`layout_fans` (no tracing here)."""
    wl = float(wavelength_nm)
    n = lens.n_surfaces
    sds = [s.semi_diameter_mm or 1.0 for s in lens.surfaces]
    ymax = max(sds)
    fig = new_figure(8.6, 4.6)
    ax = fig.add_subplot()
    for poly in element_outlines(lens):
        ax.fill(poly[:, 0], poly[:, 1], color="#cfe3f4", zorder=1)
        ax.plot(poly[:, 0], poly[:, 1], color="#1b3a57", lw=1.0, zorder=3)
    for i, s in enumerate(lens.surfaces):
        r = np.linspace(-sds[i], sds[i], 81)
        if i == lens.stop_index and not s.mirror:
            for sgn in (1, -1):
                bz, by = to_plane(lens, i, np.array([sgn * sds[i], sgn * 1.25 * sds[i]]), np.zeros(2))
                ax.plot(bz, by, color="k", lw=3, solid_capstyle="butt", zorder=4)
            tz, ty = to_plane(lens, i, np.array([1.25 * sds[i]]), np.zeros(1))
            ax.annotate("stop", (float(tz[0]), float(ty[0])), xytext=(0, 4), textcoords="offset points", ha="center",
                        fontsize=8)
        if s.is_plane and s.transform_before is not None and not s.mirror and not s.apertures \
                and s.material == (lens.surfaces[i - 1].material if i else lens.object_material):
            continue  # a coordinate break: a frame change, nothing to draw
        _draw_obscurations(ax, lens, i)
        lone = i != lens.stop_index and s.material.is_air and (i == 0 or lens.surfaces[i - 1].material.is_air)
        if s.mirror or (lone and not (s.is_plane and s.apertures and all(a.obscuration for a in s.apertures))):
            pz, py_ = _profile(lens, i, r)  # a lone surface (a mirror drawn thicker); not a plane that only obscures
            ax.plot(pz, py_, color="#1b3a57", lw=2.0 if s.mirror else 1.0, zorder=3)
    for k, fan in enumerate(fans):
        colour = _FIELD_COLOURS[k % len(_FIELD_COLOURS)]
        if fan.vignetted:
            ax.plot([], [], color=colour, ls=":", label=f"{fan.label}: every ray vignetted")
        for zz, yy, labelled in fan.polylines:
            ax.plot(zz, yy, color=colour, lw=0.7, alpha=0.9, zorder=2, label=fan.label if labelled else None)
    hi = max(image_height_mm, ymax) * 1.1
    iz, iy = to_plane(lens, n, np.array([-hi, hi]), np.zeros(2))
    ax.plot(iz, iy, color="k", lw=1.2, zorder=3)
    ax.annotate("image", (float(iz[1]), float(iy[1])), xytext=(0, 3), textcoords="offset points", ha="center",
                fontsize=8)
    ax.axhline(0.0, color="0.5", lw=0.6, ls=(0, (8, 3, 2, 3)), zorder=0)
    ax.set_aspect("equal")
    ax.set(xlabel="z (mm, from the first vertex)", ylabel="y (mm)")
    if lens.is_centred:
        ax.set_ylim(-1.3 * hi, 1.3 * hi)
    else:  # folded or tilted: the drawing leaves the axis; size the figure to it
        ylo, yhi = ax.get_ylim()
        hi = 0.5 * (yhi - ylo) / 1.3
    ax.set_title(title or f"{lens.name or 'lens'}: layout, {wl:g} nm", fontsize=10)
    ax.legend(title="field", fontsize=8, title_fontsize=8, loc="lower right")
    ax.grid(alpha=0.2)
    # size the figure to the drawing (equal aspect): long lenses get a low figure, not white bands
    z0, z1 = ax.get_xlim()
    width = 8.6
    height = (width - 1.0) * (2.6 * hi) / max(z1 - z0, 1e-9) + 1.2
    fig.set_size_inches(width, min(max(height, 3.0), 6.5))
    return save_figure(fig, path)


def _traced_with_records(lens: Lens, batches: list, device: str | None) -> list:
    """(batch, its result) of each batch traced in float64 with clipping and every surface's intersection
    recorded, all in one trace."""
    from ...trace import RayBatch, trace
    if not batches:
        return []
    joined = RayBatch(np.concatenate([b.origin_mm for b in batches]), np.concatenate([b.direction for b in batches]),
                      np.concatenate([b.wavelength_nm for b in batches]))
    res = trace(lens, joined, "float64", device, clip=True, record=True)
    ends = np.cumsum([0] + [len(b) for b in batches])
    return [(b, res.part(int(i), int(j))) for b, i, j in zip(batches, ends[:-1], ends[1:])]
