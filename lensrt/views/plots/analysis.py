"""Figures of the paraxial-against-real analyses (PNG via matplotlib's Agg canvas; no pyplot state).

matplotlib is imported inside each function. Every axis carries its unit; each
figure says in its title what is plotted against what. :func:`write_compare_plots`
writes the set that ``lensrt compare --plot DIR`` produces.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...units import NM_PER_MM, UM_PER_MM
from ...io.paths import output_dir

if TYPE_CHECKING:  # pragma: no cover
    from ...analysis.compare.aberrations import RayFan, SpotDiagram
    from ...analysis.compare.comparison import Comparison
    from ...analysis.compare.distortion import DistortionCurve, GridDistortion
    from ...analysis.compare.focus import ChromaticFocalShift, FieldCurvature, LongitudinalAberration
    from ...analysis.compare.pupils import RealPupils
    from ...analysis.compare.vignetting import Vignetting

from .figure import drawn_by_workers, new_figure, save_figure

__all__ = ["plot_spots", "plot_ray_fans", "plot_opd_fans", "plot_field_curvature_distortion",
           "plot_grid_distortion", "plot_relative_illumination", "plot_longitudinal", "plot_pupils",
           "write_compare_plots", "wavelength_colour"]


def _fig110(width_in: float, height_in: float):
    """The analysis plots' figures (110 dpi)."""
    return new_figure(width_in, height_in, dpi=110)


def wavelength_colour(nm: float) -> str:
    """A colour that reads as the wavelength (blue ... red); grey outside 380-750 nm."""
    stops = [(400, "#5a2ca0"), (450, "#1f4fd0"), (490, "#1a9ec9"), (530, "#2a9d3b"), (575, "#b8a000"),
             (600, "#e07b00"), (640, "#d2361f"), (700, "#8b1a1a")]
    if nm < 380 or nm > 750:
        return "0.4"
    return min(stops, key=lambda s: abs(s[0] - nm))[1]


def _field_title(label: str) -> str:
    return f"field {label}"


@drawn_by_workers
def plot_spots(path: str | Path, spots: Sequence["SpotDiagram"], airy_radius_mm: float | None = None,
               title: str = "") -> Path:
    """Spot diagrams, one panel per field, wavelengths coloured, all panels on one scale (um)."""
    n = len(spots)
    if n == 0:
        raise ValueError("no spot diagrams to draw")
    fig = _fig110(max(2.9 * n + 0.4, 6.0), 3.9)
    axes = fig.subplots(1, n, squeeze=False)[0]
    half = max(max(s.geometric_radius_mm for s in spots), airy_radius_mm or 0.0) * UM_PER_MM * 1.08
    for ax, s in zip(axes, spots):
        for w, x, y in zip(s.wavelengths_nm, s.x_mm, s.y_mm):
            ax.plot(x * UM_PER_MM, y * UM_PER_MM, ".", ms=1.6, color=wavelength_colour(w), label=f"{w:g} nm")
        if airy_radius_mm:
            t = np.linspace(0, 2 * np.pi, 200)
            ax.plot(airy_radius_mm * UM_PER_MM * np.cos(t), airy_radius_mm * UM_PER_MM * np.sin(t), color="k",
                    lw=0.8, ls="--", label=f"Airy radius {airy_radius_mm * UM_PER_MM:.2g} um")
        ax.set_xlim(-half, half)
        ax.set_ylim(-half, half)
        ax.set_aspect("equal")
        ax.axhline(0, color="0.8", lw=0.5)
        ax.axvline(0, color="0.8", lw=0.5)
        e = s.estimates.get("rms_radius_mm")
        sub = f"RMS {e.value * UM_PER_MM:.2f} +- {e.stderr * UM_PER_MM:.2g} um" if e is not None else ""
        ax.set_title(f"{_field_title(s.label)}\n{sub}, geo {s.geometric_radius_mm * UM_PER_MM:.1f} um", fontsize=9)
        ax.set_xlabel("x - x_ref (um)")
    axes[0].set_ylabel("y - y_ref (um)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8, markerscale=4)
    ref = "primary chief ray" if spots[0].reference == "chief" else "centroid"
    fig.suptitle(title or f"Spot diagrams on the plane z = {spots[0].plane_z_mm:.3f} mm, relative to the {ref}",
                 fontsize=10)
    return save_figure(fig, path)


def _fan_axes(fig, fans, key_t: str, key_s: str, scale: float, ylabel: str, title: str):
    n = len(fans)
    axes = fig.subplots(n, 2, squeeze=False, sharey=True)
    vals = [np.abs(getattr(f, k)) for pair in fans for f, k in ((pair[0], key_t), (pair[1], key_s))]
    top = max((float(np.nanmax(v)) for v in vals if np.isfinite(v).any()), default=1.0) * scale * 1.1 or 1.0
    for r, (tan, sag) in enumerate(fans):
        for c, (fan, key, xl) in enumerate(((tan, key_t, "Py (tangential)"), (sag, key_s, "Px (sagittal)"))):
            ax = axes[r, c]
            data = getattr(fan, key)
            for i, w in enumerate(fan.wavelengths_nm):
                ax.plot(fan.pupil, data[i] * scale, color=wavelength_colour(w), lw=1.3, label=f"{w:g} nm")
            ax.axhline(0, color="0.6", lw=0.6)
            ax.axvline(0, color="0.6", lw=0.6)
            ax.set_ylim(-top, top)
            ax.set_xlim(-1.02 if c == 0 else -0.02, 1.02)
            ax.grid(alpha=0.25)
            ax.set_title(f"{_field_title(fan.label)}, {xl.split()[1][1:-1]}", fontsize=9)
            if r == n - 1:
                ax.set_xlabel(f"pupil coordinate {xl}")
            if c == 0:
                ax.set_ylabel(ylabel)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)


@drawn_by_workers
def plot_ray_fans(path: str | Path, fans: Sequence[tuple["RayFan", "RayFan"]], title: str = "") -> Path:
    """Transverse ray aberration (um) against pupil coordinate: tangential e_y(Py) and sagittal e_x(Px)."""
    if not fans:
        raise ValueError("no ray fans to draw")
    fig = _fig110(7.2, 2.3 * len(fans) + 0.6)
    _fan_axes(fig, fans, "ey_mm", "ex_mm", UM_PER_MM, "ray aberration (um)",
              title or f"Ray fans on z = {fans[0][0].plane_z_mm:.3f} mm: e_y against Py, e_x against Px\n"
                       "(relative to the primary wavelength's chief ray)")
    return save_figure(fig, path)


@drawn_by_workers
def plot_opd_fans(path: str | Path, fans: Sequence[tuple["RayFan", "RayFan"]], title: str = "") -> Path:
    """OPD (waves) against pupil coordinate, tangential and sagittal fans."""
    if not fans:
        raise ValueError("no OPD fans to draw")
    fig = _fig110(7.2, 2.3 * len(fans) + 0.6)
    _fan_axes(fig, fans, "opd_waves", "opd_waves", 1.0, "OPD (waves)",
              title or "OPD fans (waves): path to the reference sphere about the chief ray's image point\n"
                       "minus the chief ray's; + = longer path")
    return save_figure(fig, path)


@drawn_by_workers
def plot_field_curvature_distortion(path: str | Path, fc: "FieldCurvature", dist: "DistortionCurve",
                                    title: str = "") -> Path:
    """Field curvature (S, T, Petzval, third order; mm along z) and distortion (%) against field."""
    fig = _fig110(8.4, 4.2)
    a1, a2 = fig.subplots(1, 2, sharey=True)
    f = np.degrees(fc.object_value) if fc.infinite else fc.object_value
    flabel = "field angle (deg)" if fc.infinite else "object height (mm)"
    zp = fc.paraxial_image_z_mm
    a1.plot(fc.sagittal_z_mm - zp, f, color="#1f4fd0", lw=1.6, label="sagittal (real)")
    a1.plot(fc.tangential_z_mm - zp, f, color="#d2361f", lw=1.6, label="tangential (real)")
    a1.plot(fc.petzval_z_mm - zp, f, color="0.3", lw=1.0, ls=":", label="Petzval surface")
    a1.plot(fc.third_order_sagittal_z_mm - zp, f, color="#1f4fd0", lw=0.9, ls="--", label="sagittal, 3rd order")
    a1.plot(fc.third_order_tangential_z_mm - zp, f, color="#d2361f", lw=0.9, ls="--", label="tangential, 3rd order")
    if abs(fc.image_z_mm - zp) > 1e-9:
        a1.axvline(fc.image_z_mm - zp, color="k", lw=0.8, ls="-.", label="image surface")
    a1.axvline(0, color="0.6", lw=0.6)
    # the frame follows the real foci; third-order and Petzval curves may leave it (extrapolations)
    real = np.concatenate([fc.sagittal_z_mm - zp, fc.tangential_z_mm - zp, [fc.image_z_mm - zp]])
    real = real[np.isfinite(real)]
    if real.size:
        lo, hi = float(real.min()), float(real.max())
        pad = 0.35 * max(hi - lo, 1e-3)
        a1.set_xlim(lo - pad, hi + pad)
    a1.set(xlabel="focus from the paraxial image plane (mm, along z)", ylabel=flabel,
           title=f"Field curvature, {fc.wavelength_nm:g} nm")
    a1.set_ylim(0, float(np.nanmax(f)) * 1.02 if np.nanmax(f) > 0 else 1)
    a1.grid(alpha=0.25)
    a1.legend(fontsize=7)
    g = np.degrees(dist.object_value) if dist.infinite else dist.object_value
    a2.plot(dist.distortion_percent, g, color="k", lw=1.6, label="real vs paraxial (f tan theta)"
            if dist.infinite else "real vs paraxial (m h)")
    if np.nanmax(np.abs(dist.distortion_codev_percent - dist.distortion_percent)) > 1e-6:
        a2.plot(dist.distortion_codev_percent, g, color="k", lw=1.0, ls="--", label="CODE V definition")
    if dist.infinite and np.nanmax(g) > 45.0:
        for name, c in (("equidistant", "#2a9d3b"), ("equisolid", "#e07b00"), ("stereographic", "#8b3fb0")):
            a2.plot(dist.mapping_distortion_percent[name], g, color=c, lw=1.2, label=f"real vs {name}")
    a2.axvline(0, color="0.6", lw=0.6)
    fin = np.isfinite(dist.distortion_percent)
    span = float(np.nanmax(np.abs(dist.distortion_percent[fin]))) if fin.any() else 1.0
    if dist.infinite and np.nanmax(g) > 45.0:
        span = min(max(span, 5.0), 60.0)
    a2.set_xlim(-1.1 * span - 1e-3, 1.1 * span + 1e-3)
    a2.set(xlabel="distortion (%; < 0 barrel, > 0 pincushion)", title=f"Distortion, {dist.wavelength_nm:g} nm")
    a2.grid(alpha=0.25)
    a2.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


@drawn_by_workers
def plot_grid_distortion(path: str | Path, grid: "GridDistortion", title: str = "") -> Path:
    """Ideal grid (grey) and real chief-ray points (mm); displacements exaggerated when small (said in the title)."""
    fig = _fig110(5.6, 5.6)
    ax = fig.add_subplot()
    gx, gy = grid.ideal_x_mm, grid.ideal_y_mm
    dmax = grid.max_abs_distortion_percent
    k = 1.0 if not math.isfinite(dmax) or dmax >= 2.0 else float(10 ** math.ceil(math.log10(2.0 / max(dmax, 1e-6))))
    k = min(k, 100.0)
    rx = gx + k * (grid.real_x_mm - gx)
    ry = gy + k * (grid.real_y_mm - gy)
    rx, ry = np.where(grid.valid, rx, np.nan), np.where(grid.valid, ry, np.nan)
    for i in range(gx.shape[0]):
        ax.plot(gx[i], gy[i], color="0.7", lw=0.8)
        ax.plot(gx[:, i], gy[:, i], color="0.7", lw=0.8)
        ax.plot(rx[i], ry[i], color="#d2361f", lw=1.0)
        ax.plot(rx[:, i], ry[:, i], color="#d2361f", lw=1.0)
    ax.plot(rx, ry, "x", color="#d2361f", ms=3)
    ax.plot([], [], color="0.7", label=f"ideal ({grid.mapping})")
    ax.plot([], [], color="#d2361f", marker="x", label="real chief rays" + (f", displacement x{k:g}" if k > 1 else ""))
    ax.set_aspect("equal")
    ax.set(xlabel="x (mm)", ylabel="y (mm)")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=2)
    ax.set_title(title or f"Grid distortion, {grid.wavelength_nm:g} nm, z = {grid.plane_z_mm:.3f} mm; largest "
                          f"|distortion| {dmax:.3g} %", fontsize=9)
    return save_figure(fig, path)


@drawn_by_workers
def plot_relative_illumination(path: str | Path, vig: "Vignetting", title: str = "") -> Path:
    """Relative illumination (both methods) and the unvignetted fraction against field, with cos^4."""
    fig = _fig110(6.6, 4.3)
    ax = fig.add_subplot()
    f = np.degrees(vig.object_value) if vig.infinite else vig.object_value
    flabel = "field angle (deg)" if vig.infinite else "object height (mm)"
    dense = np.linspace(0, float(np.max(f)), 200)
    if vig.infinite:
        ax.plot(dense, np.cos(np.radians(dense)) ** 4, color="0.35", lw=1.2, ls="--", label="cos^4 (p. 32)")
    else:
        ax.plot(f, vig.cos4, color="0.35", lw=1.2, ls="--", label="cos^4 of the chief-ray angle")
    ri, se = vig.values("relative_illumination"), vig.stderrs("relative_illumination")
    ax.errorbar(f, ri, yerr=2 * se, color="#1f4fd0", lw=1.6, marker="o", ms=3.5, capsize=2,
                label="relative illumination (real rays, +-2 s.e.)")
    ax.plot(f, vig.relative_illumination_exit_pupil, color="#2a9d3b", lw=0, marker="s", ms=4, mfc="none",
            label="exit-pupil solid angle method")
    ax.plot(f, vig.values("vignetting_fraction"), color="#d2361f", lw=1.2, ls=":", marker=".",
            label="unvignetted fraction of the pupil")
    ax.set(xlabel=flabel, ylabel="relative to the axis", ylim=(0, 1.08),
           title=title or f"Relative illumination and vignetting, {vig.wavelength_nm:g} nm "
                          f"({vig.rays_per_field} rays per field)")
    ax.set_xlim(0, float(np.max(f)) * 1.02 if np.max(f) > 0 else 1)
    ax.grid(alpha=0.25)
    ax.legend(fontsize=8, loc="lower left")
    return save_figure(fig, path)


@drawn_by_workers
def plot_longitudinal(path: str | Path, lsa: "LongitudinalAberration", chrom: "ChromaticFocalShift",
                      title: str = "") -> Path:
    """Longitudinal spherical aberration against zone (per wavelength) and the chromatic focal shift."""
    fig = _fig110(8.4, 4.2)
    a1, a2 = fig.subplots(1, 2)
    for k, w in enumerate(lsa.wavelengths_nm):
        z = np.concatenate([[lsa.paraxial_focus_z_mm[k] - lsa.reference_z_mm], lsa.lsa_mm[k]])
        zone = np.concatenate([[0.0], lsa.zones])
        a1.plot(z, zone, color=wavelength_colour(w), lw=1.6, label=f"{w:g} nm")
    a1.plot(lsa.third_order_lsa_mm, lsa.zones, color="0.3", lw=0.9, ls="--", label=f"3rd order, {lsa.primary_nm:g} nm")
    a1.axvline(0, color="0.6", lw=0.6)
    a1.set(xlabel=f"focus from the paraxial focus at {lsa.primary_nm:g} nm (mm)",
           ylabel="pupil zone (fraction of the EP radius)", ylim=(0, 1.02),
           title=f"Longitudinal aberration ({lsa.correction()} SA)")
    span = float(np.nanmax(np.abs(np.concatenate([lsa.lsa_mm.ravel(), lsa.third_order_lsa_mm]))))
    a1.set_xlim(-1.1 * span, 1.1 * span)
    a1.grid(alpha=0.25)
    a1.legend(fontsize=7)
    a2.plot(chrom.wavelength_nm, chrom.paraxial_shift_mm, color="k", lw=1.4, label="paraxial focus")
    a2.plot(chrom.best_focus_wavelength_nm, chrom.best_focus_shift_mm, "o", color="#d2361f", ms=5,
            label="real best focus (minimum RMS)")
    a2.axhline(0, color="0.6", lw=0.6)
    a2.set(xlabel="wavelength (nm)", ylabel=f"focus from the paraxial focus at {chrom.primary_nm:g} nm (mm)",
           title="Chromatic focal shift")
    a2.grid(alpha=0.25)
    a2.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


@drawn_by_workers
def plot_pupils(path: str | Path, pupils: "RealPupils", title: str = "") -> Path:
    """The real entrance pupil seen from each field point (every aperture), across the beam (mm)."""
    fig = _fig110(5.8, 5.4)
    ax = fig.add_subplot()
    r = 0.5 * pupils.paraxial["entrance_pupil_diameter_mm"]
    t = np.linspace(0, 2 * np.pi, 300)
    ax.plot(r * np.cos(t), r * np.sin(t), color="0.4", ls="--", lw=1.0, label="paraxial entrance pupil")
    colours = ("#1f4fb4", "#2a9d3b", "#d2361f", "#8b3fb0", "#c98a00", "#138c8c")
    for k, o in enumerate(pupils.outlines):
        lab = next((l for l, v in zip(pupils.labels, pupils.object_value) if abs(v - o.object_value) < 1e-12), "")
        c = colours[k % len(colours)]
        ax.fill(np.append(o.a_mm, o.a_mm[0]), np.append(o.b_mm, o.b_mm[0]), color=c, alpha=0.12)
        ax.plot(np.append(o.a_mm, o.a_mm[0]), np.append(o.b_mm, o.b_mm[0]), color=c, lw=1.4,
                label=f"{lab}: {o.area_mm2:.1f} mm2")
    ax.set_aspect("equal")
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.set(xlabel="sagittal, across the beam (mm)", ylabel="tangential, across the beam (mm)")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(title or "Real entrance pupil seen from each field point (rays passing every aperture),\n"
                          "in the plane through the paraxial EP centre perpendicular to the beam", fontsize=9)
    lim = max([r] + [float(np.max(np.abs(np.concatenate([o.a_mm, o.b_mm])))) for o in pupils.outlines]) * 1.25
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    return save_figure(fig, path)


def write_compare_plots(c: "Comparison", directory: str | Path) -> list[Path]:
    """Every figure of ``lensrt compare --plot DIR``; returns the paths written."""
    from ...paraxial import first_order
    from .layout import plot_layout
    d = output_dir(directory)
    p = c.primary_nm
    name = c.lens.name or "lens"
    out = [plot_layout(d / "layout.png", c.lens, [s.hy for s in c.fields], p, device=c.device)]
    if c.spots:
        fo = first_order(c.lens, p)
        airy = 1.22 * p / NM_PER_MM * fo.working_f_number
        out.append(plot_spots(d / "spots.png", c.spots, airy_radius_mm=airy))
    if c.fans:
        out.append(plot_ray_fans(d / "ray_fans.png", c.fans))
        out.append(plot_opd_fans(d / "opd_fans.png", c.fans))
    out.append(plot_field_curvature_distortion(d / "field_curvature_distortion.png", c.field_curvature[p],
                                               c.distortion[p], title=name))
    if c.grid is not None:
        out.append(plot_grid_distortion(d / "grid_distortion.png", c.grid))
    out.append(plot_relative_illumination(d / "relative_illumination.png", c.vignetting))
    out.append(plot_longitudinal(d / "longitudinal.png", c.lsa, c.chromatic, title=name))
    if c.pupils.outlines:
        out.append(plot_pupils(d / "pupils.png", c.pupils))
    return out
