"""The lens cross-section with traced ray bundles (PNG via matplotlib's Agg canvas; imported lazily).

Surfaces are drawn to their clear semi-diameters; the two faces of an element
(glass between them) are joined at the rim by a flat flange and an edge parallel
to the axis, and the element is shaded. The stop is drawn as two blades outside
its clear radius; the image surface as a line. Meridional rays of each field point
(aimed at the real stop) are spread evenly across the meridional extent of the
real, vignetted pupil (found by tracing 97 probe rays with every aperture), so the
drawn bundle is the one that reaches the image.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ...prescription.model import Lens

from .figure import new_figure, save_figure

__all__ = ["plot_layout", "element_outlines"]

_FIELD_COLOURS = ("#1f4fb4", "#2a9d3b", "#d2361f", "#8b3fb0", "#c98a00", "#138c8c")


def _profile(lens: Lens, i: int, r: np.ndarray) -> np.ndarray:
    """Global z of surface i at heights r (mm)."""
    s = lens.surfaces[i]
    return lens.vertex_z_mm()[i] + np.asarray(s.sag(np.minimum(np.abs(r), s.max_semi_diameter_mm)))


def element_outlines(lens: Lens) -> list[np.ndarray]:
    """Closed (z, y) outlines of each element: glass between surfaces i and i + 1 (upper and lower halves)."""
    out = []
    for i in range(lens.n_surfaces - 1):
        if lens.surfaces[i].material.is_air:
            continue
        sd1 = lens.surfaces[i].semi_diameter_mm or 1.0
        sd2 = lens.surfaces[i + 1].semi_diameter_mm or 1.0
        rim = max(sd1, sd2)
        y1 = np.linspace(-sd1, sd1, 61)
        y2 = np.linspace(sd2, -sd2, 61)
        z1, z2 = _profile(lens, i, y1), _profile(lens, i + 1, y2)
        zt1, zt2 = float(_profile(lens, i, np.array([sd1]))[0]), float(_profile(lens, i + 1, np.array([sd2]))[0])
        # front face, up its flange to the rim, along the edge, down the back flange, back face, and back
        z = np.concatenate([z1, [zt1, zt2, zt2], z2, [zt2, zt2, zt1, zt1]])
        y = np.concatenate([y1, [rim, rim, sd2], y2, [-sd2, -rim, -rim, -sd1]])
        out.append(np.stack([z, y], axis=1))
    return out


def plot_layout(path: str | Path, lens: Lens, hy: Sequence[float] | None = None, wavelength_nm: float | None = None,
                rays_per_field: int = 9, device: str | None = None, title: str = "") -> Path:
    """Cross-section of ``lens`` (y-z plane) with meridional ray bundles at normalised fields ``hy``."""
    from ...analysis.raysets import aim_batch, field_spec, object_field_point
    from ...trace import trace
    from ...trace.status import OK, TIR, VIGNETTED
    hy = [0.0, 0.7, 1.0] if hy is None else list(hy)
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    vz = lens.vertex_z_mm()
    n = lens.n_surfaces
    sds = [s.semi_diameter_mm or 1.0 for s in lens.surfaces]
    ymax = max(sds)
    length = float(vz[-1] - vz[0])
    z_start = -0.25 * max(length, 4 * ymax)
    fig = new_figure(8.6, 4.6)
    ax = fig.add_subplot()
    for poly in element_outlines(lens):
        ax.fill(poly[:, 0], poly[:, 1], color="#cfe3f4", zorder=1)
        ax.plot(poly[:, 0], poly[:, 1], color="#1b3a57", lw=1.0, zorder=3)
    for i, s in enumerate(lens.surfaces):
        r = np.linspace(-sds[i], sds[i], 81)
        if i == lens.stop_index:
            z0 = vz[i]
            for sgn in (1, -1):
                ax.plot([z0, z0], [sgn * sds[i], sgn * 1.25 * sds[i]], color="k", lw=3, solid_capstyle="butt",
                        zorder=4)
            ax.annotate("stop", (z0, 1.25 * sds[i]), xytext=(0, 4), textcoords="offset points", ha="center",
                        fontsize=8)
        elif s.material.is_air and (i == 0 or lens.surfaces[i - 1].material.is_air):
            ax.plot(_profile(lens, i, r), r, color="#1b3a57", lw=1.0, zorder=3)  # a lone surface
    # rays
    img_h = 0.0
    for k, h in enumerate(hy):
        spec = field_spec(lens, h)
        fp = object_field_point(lens, spec.object_value)
        # the meridional extent of the real (vignetted) pupil, then rays spread evenly across it
        probe = np.linspace(-1.2, 1.2, 97)
        pr = aim_batch(lens, fp, np.zeros_like(probe), probe, wl, "real", device)
        ok = trace(lens, pr, "float64", device, clip=True).ok & pr.aimed
        colour = _FIELD_COLOURS[k % len(_FIELD_COLOURS)]
        if not ok.any():
            ax.plot([], [], color=colour, ls=":", label=f"{spec.label}: every ray vignetted")
            continue
        lo, hi_py = probe[ok].min(), probe[ok].max()
        step = probe[1] - probe[0]
        py = np.linspace(lo + 0.02 * step, hi_py - 0.02 * step, rays_per_field)
        rays = aim_batch(lens, fp, np.zeros_like(py), py, wl, "real", device)
        res = trace(lens, rays, "float64", device, clip=True, record=True)
        for j in range(len(py)):
            st, where = int(res.status[j]), int(res.surface[j])
            rows = n + 1 if st == OK else (where + 1 if st in (VIGNETTED, TIR) else max(where, 0))
            if rows == 0:
                continue
            rec = res.records[j, :rows]
            z = rec[:, 2] + vz[:rows]
            y = rec[:, 1]
            o, d = rays.origin_mm[j], rays.direction[j]
            if fp.infinite:
                t = (z_start - o[2]) / d[2]
                start = o + t * d
            else:
                start = o
            zz = np.concatenate([[start[2]], z])
            yy = np.concatenate([[start[1]], y])
            ax.plot(zz, yy, color=colour, lw=0.7, alpha=0.9, zorder=2,
                    label=spec.label if j == 0 else None)
            if st == OK:
                img_h = max(img_h, abs(y[-1]))
    hi = max(img_h, ymax) * 1.1
    ax.plot([lens.image_z_mm] * 2, [-hi, hi], color="k", lw=1.2, zorder=3)
    ax.annotate("image", (lens.image_z_mm, hi), xytext=(0, 3), textcoords="offset points", ha="center", fontsize=8)
    ax.axhline(0.0, color="0.5", lw=0.6, ls=(0, (8, 3, 2, 3)), zorder=0)
    ax.set_aspect("equal")
    ax.set(xlabel="z (mm, from the first vertex)", ylabel="y (mm)")
    ax.set_ylim(-1.3 * hi, 1.3 * hi)
    ax.set_title(title or f"{lens.name or 'lens'}: layout, {wl:g} nm", fontsize=10)
    ax.legend(title="field", fontsize=8, title_fontsize=8, loc="lower right")
    ax.grid(alpha=0.2)
    # size the figure to the drawing (equal aspect): long lenses get a low figure, not white bands
    z0, z1 = ax.get_xlim()
    width = 8.6
    height = (width - 1.0) * (2.6 * hi) / max(z1 - z0, 1e-9) + 1.2
    fig.set_size_inches(width, min(max(height, 3.0), 6.5))
    return save_figure(fig, path)
