"""Figures for PSFs and MTFs (PNG via matplotlib's Agg canvas; no pyplot global state).

matplotlib is imported inside each function, so importing this module is cheap.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...units import UM_PER_MM

if TYPE_CHECKING:  # pragma: no cover
    from ...analysis.psf.result import PsfResult

from .figure import drawn_by_workers, new_figure, save_figure

__all__ = ["plot_mtf_curves", "plot_mtf_vs_field", "plot_through_focus", "plot_psf", "plot_psf_mosaic",
           "nice_length", "mosaic_axes_boxes", "plot_system_mtf", "plot_convergence", "PsfTile", "draw_psf", "draw_psf_mosaic"]


def nice_length(span: float) -> float:
    """A 1-2-5 round number near a quarter of ``span`` (for scale bars)."""
    target = max(span / 4.0, 1e-12)
    e = 10.0 ** math.floor(math.log10(target))
    return max(m * e for m in (1.0, 2.0, 5.0) if m * e <= target)


@drawn_by_workers
def plot_mtf_curves(path: str | Path, freqs_cpmm: np.ndarray, curves: Sequence[tuple[str, np.ndarray, np.ndarray]],
                    diffraction: np.ndarray | None = None, nyquist_cpmm: float | None = None,
                    title: str = "") -> Path:
    """Sagittal (solid) and tangential (dashed) MTF against frequency, one colour per curve pair.

    ``curves`` holds (label, sagittal, tangential); ``diffraction`` is the
    diffraction limit on the same frequencies (drawn in grey); the sensor
    Nyquist frequency is a vertical line.
    """
    fig = new_figure(6.4, 4.2)
    ax = fig.add_subplot()
    if diffraction is not None:
        ax.plot(freqs_cpmm, diffraction, color="0.55", lw=2.5, alpha=0.6, label="diffraction limit")
    for i, (label, sag, tan) in enumerate(curves):
        c = f"C{i % 10}"
        ax.plot(freqs_cpmm, sag, color=c, lw=1.5, label=f"{label} S")
        ax.plot(freqs_cpmm, tan, color=c, lw=1.5, ls="--", label=f"{label} T")
    if nyquist_cpmm is not None:
        ax.axvline(nyquist_cpmm, color="k", lw=1, ls=":")
        ax.annotate(f"Nyquist {nyquist_cpmm:.0f}", (nyquist_cpmm, 0.98), rotation=90, ha="right", va="top",
                    fontsize=8)
    ax.set(xlim=(0, float(np.max(freqs_cpmm))), ylim=(0, 1.02), xlabel="spatial frequency (cycles/mm)",
           ylabel="MTF", title=title or "MTF (S solid, T dashed)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncols=2)
    return save_figure(fig, path)


@drawn_by_workers
def plot_mtf_vs_field(path: str | Path, data: dict, title: str = "") -> Path:
    """MTF against image height at fixed frequencies (``lensrt.analysis.psf.otf.mtf_vs_field`` output)."""
    fig = new_figure(6.4, 4.2)
    ax = fig.add_subplot()
    h = data["image_height_mm"]
    for j, f in enumerate(data["freqs_cpmm"]):
        c = f"C{j % 10}"
        ax.plot(h, data["sagittal"][:, j], color=c, marker="o", ms=3, label=f"{f:.3g} c/mm S")
        ax.plot(h, data["tangential"][:, j], color=c, ls="--", marker="s", ms=3, label=f"{f:.3g} c/mm T")
    ax.set(xlim=(0, float(np.max(h)) if np.max(h) > 0 else 1.0), ylim=(0, 1.02), xlabel="image height (mm)",
           ylabel="MTF", title=title or "MTF against field (S solid, T dashed)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncols=2)
    return save_figure(fig, path)


@drawn_by_workers
def plot_through_focus(path: str | Path, data: dict, title: str = "") -> Path:
    """Through-focus MTF (``lensrt.analysis.psf.otf.through_focus_mtf`` output), focus shift in um."""
    fig = new_figure(6.4, 4.2)
    ax = fig.add_subplot()
    z_um = np.asarray(data["focus_mm"]) * UM_PER_MM
    for j, f in enumerate(data["freqs_cpmm"]):
        c = f"C{j % 10}"
        ax.plot(z_um, data["sagittal"][:, j], color=c, label=f"{f:.3g} c/mm S")
        ax.plot(z_um, data["tangential"][:, j], color=c, ls="--", label=f"{f:.3g} c/mm T")
    ax.set(ylim=(0, 1.02), xlabel="focus shift (um)", ylabel="MTF", title=title or "Through-focus MTF")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncols=2)
    return save_figure(fig, path)


@drawn_by_workers
def plot_through_focus_spots(path: str | Path, spots, title: str = "") -> Path:
    """A row of spot diagrams (``lensrt.analysis.psf.focus_spots.FocusSpots``), one per focus shift, on one um
    scale, each with its RMS radius about its centroid; wavelengths in colour."""
    k = len(spots.focus_mm)
    fig = new_figure(min(2.0 * k + 0.6, 18.0), 2.6)
    axes = np.atleast_1d(fig.subplots(1, k, sharex=True, sharey=True))
    lim = max(float(np.max(np.abs(np.concatenate([np.concatenate(x) for x in spots.x_mm] +
                                                   [np.concatenate(y) for y in spots.y_mm])))), 1e-6) * UM_PER_MM
    for i, ax in enumerate(axes):
        for j, wl in enumerate(spots.wavelengths_nm):
            ax.scatter(spots.x_mm[i][j] * UM_PER_MM, spots.y_mm[i][j] * UM_PER_MM, s=0.5, color=f"C{j % 10}",
                       label=f"{wl:g} nm" if i == 0 else None)
        ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal")
        ax.set_title(f"{spots.focus_mm[i] * UM_PER_MM:+.0f} um\nRMS {spots.rms_radius_mm[i] * UM_PER_MM:.3g} um",
                     fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("y about centroid (um)", fontsize=8)
    if len(spots.wavelengths_nm) > 1:
        axes[0].legend(fontsize=6, markerscale=8, loc="lower left")
    fig.suptitle(title or f"Through-focus spot diagrams, {spots.label}", fontsize=9)
    return save_figure(fig, path)


@dataclass(frozen=True)
class PsfTile:
    """What a PSF figure draws of a :class:`~lensrt.analysis.psf.result.PsfResult`: the PSF image (rows
    top-down), the grid's extent (left, right, bottom, top; mm) and the reference point (mm) -- a few
    arrays that a figure worker process receives instead of the whole result."""
    psf: np.ndarray
    extent_mm: tuple[float, float, float, float]
    reference_mm: tuple[float, float]

    @classmethod
    def of(cls, result: "PsfResult") -> "PsfTile":
        return cls(np.asarray(result.psf), tuple(result.grid.extent_mm), tuple(result.reference_mm))


def _tile_image(tile: PsfTile, log: bool) -> tuple[np.ndarray, list[float], float, float]:
    """The tile's picture: the PSF peak-normalised (``log``: log10 down to 1e-6), its extent about the reference
    point (left, right, bottom, top; um) and the colour scale's limits."""
    l, r, b, t = tile.extent_mm
    cx, cy = tile.reference_mm
    ext_um = [(l - cx) * UM_PER_MM, (r - cx) * UM_PER_MM, (b - cy) * UM_PER_MM, (t - cy) * UM_PER_MM]
    img = np.asarray(tile.psf, dtype=np.float64)
    img = img / img.max() if img.max() > 0 else img
    if log:
        img = np.log10(np.clip(img, 1e-6, None))
    return img, ext_um, (-6.0 if log else 0.0), (0.0 if log else 1.0)


def _psf_axes(ax, tile: PsfTile, log: bool) -> None:
    img, ext_um, vmin, vmax = _tile_image(tile, log)
    ax.imshow(img, extent=ext_um, origin="upper", cmap="inferno", vmin=vmin, vmax=vmax, interpolation="nearest")
    span = ext_um[1] - ext_um[0]
    bar = nice_length(span)
    x0, y0 = ext_um[0] + 0.06 * span, ext_um[2] + 0.06 * (ext_um[3] - ext_um[2])
    ax.plot([x0, x0 + bar], [y0, y0], color="w", lw=3, solid_capstyle="butt")
    ax.text(x0 + bar / 2, y0 + 0.03 * span, f"{bar:g} um", color="w", ha="center", va="bottom", fontsize=8)
    ax.set(xlabel="x - x_ref (um)", ylabel="y - y_ref (um)")


def plot_psf(path: str | Path, result: "PsfResult", log: bool = False, title: str = "") -> Path:
    """One PSF image (peak-normalised; ``log``: log10 down to 1e-6) with a um scale bar."""
    rms = result.estimates.get("rms_radius_mm")
    wl = ", ".join(f"{w:g}" for w in result.wavelengths_nm)
    sub = f"{result.kind}, {wl} nm, pitch {result.grid.pitch_um:g} um"
    if rms is not None:
        err = f" +- {rms.stderr * UM_PER_MM:.2g}" if rms.stderr else ""
        sub += f"\nRMS radius {rms.value * UM_PER_MM:.3g}{err} um"
    return draw_psf(path, PsfTile.of(result), log, (title + "\n" if title else "") + sub)


@drawn_by_workers
def draw_psf(path: str | Path, tile: PsfTile, log: bool, title: str) -> Path:
    """The figure of :func:`plot_psf` from its tile and full title."""
    fig = new_figure(5.0, 4.4)
    ax = fig.add_subplot()
    _psf_axes(ax, tile, log)
    ax.set_title(title, fontsize=9)
    return save_figure(fig, path)


def plot_psf_mosaic(path: str | Path, results: Sequence["PsfResult"], ncols: int | None = None,
                    log: bool = False, title: str = "") -> Path:
    """PSF map: one tile per field point (each peak-normalised), labelled with its image position."""
    if len(results) == 0:
        raise ValueError("no PSFs to draw")
    return draw_psf_mosaic(path, [PsfTile.of(r) for r in results], ncols, log,
                           title or f"PSF map ({results[0].kind}, tiles peak-normalised)")


#: the PSF mosaic's geometry (inches): a cell per field, the side margin, the band above each tile for its
#: title and the gap under it, the bottom margin, and the height of one line of the figure's title
_CELL_IN, _SIDE_IN, _TITLE_IN, _GAP_IN, _BOTTOM_IN, _LINE_IN = 1.6, 0.2, 0.17, 0.05, 0.05, 0.19


def mosaic_axes_boxes(nrows: int, ncols: int, title_lines: int = 1) -> list[tuple[float, float, float, float]]:
    """The PSF mosaic's tile boxes (left, bottom, width, height as fractions of the figure), row by row from the
    top: fixed positions on a figure of ``1.6 * ncols + 0.4`` by ``1.6 * nrows + 0.6`` inches under a title of
    ``title_lines`` lines, each tile a square under a band for its label (smaller where a long title leaves
    less room). Placing the tiles here instead of by Matplotlib's constrained layout makes the 7 x 7 map
    about three times cheaper to draw (that layout measures every label and tick again and again)."""
    w_in, h_in = _CELL_IN * ncols + 2 * _SIDE_IN, _CELL_IN * nrows + 0.6
    top_in = 0.1 + _LINE_IN * max(title_lines, 1)
    cell_h = (h_in - top_in - _BOTTOM_IN) / nrows
    side = min(_CELL_IN, cell_h) - _TITLE_IN - _GAP_IN
    boxes = []
    for i in range(nrows):
        top = h_in - top_in - i * cell_h - _TITLE_IN  # the tile's top edge, under its label
        for j in range(ncols):
            left = _SIDE_IN + j * _CELL_IN + (_CELL_IN - side) / 2
            boxes.append((left / w_in, (top - side) / h_in, side / w_in, side / h_in))
    return boxes


def _mosaic_tile(ax, box_in: tuple[float, float, float, float], tile: PsfTile, log: bool) -> None:
    """Draw ``tile`` into ``box_in`` (left, bottom, width, height in inches, the data units of ``ax``): the
    picture fitted to the box at its own aspect, a frame, a um scale bar and the image position above it."""
    from matplotlib.patches import Rectangle
    img, ext_um, vmin, vmax = _tile_image(tile, log)
    span, rise = ext_um[1] - ext_um[0], ext_um[3] - ext_um[2]
    left, bottom, side, _ = box_in
    w, h = (side, side * rise / span) if rise <= span else (side * span / rise, side)
    left, bottom = left + (side - w) / 2, bottom + (side - h) / 2
    ax.imshow(img, extent=(left, left + w, bottom, bottom + h), origin="upper", cmap="inferno", vmin=vmin,
              vmax=vmax, interpolation="nearest")
    ax.add_patch(Rectangle((left, bottom), w, h, fill=False, lw=0.8, ec="k"))
    in_per_um = w / span
    bar = nice_length(span)
    x0, y0 = left + 0.06 * w, bottom + 0.06 * h
    ax.plot([x0, x0 + bar * in_per_um], [y0, y0], color="w", lw=3, solid_capstyle="butt")
    ax.text(x0 + bar * in_per_um / 2, y0 + 0.03 * w, f"{bar:g} um", color="w", ha="center", va="bottom",
            fontsize=8)
    x, y = tile.reference_mm
    ax.text(left + w / 2, bottom + h + 0.04, f"({x:.1f}, {y:.1f}) mm", ha="center", va="bottom", fontsize=7)


@drawn_by_workers
def draw_psf_mosaic(path: str | Path, tiles: Sequence[PsfTile], ncols: int | None, log: bool, title: str) -> Path:
    """The figure of :func:`plot_psf_mosaic` from its tiles and title: the tiles drawn at the fixed positions of
    :func:`mosaic_axes_boxes` into one axes that spans the figure in inches (no axes, ticks or constrained
    layout per tile: the same pictures, frames, scale bars and labels at a fraction of the cost), cells
    without a tile left empty."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    n = len(tiles)
    ncols = ncols or int(math.ceil(math.sqrt(n)))
    nrows = int(math.ceil(n / ncols))
    w_in, h_in = _CELL_IN * ncols + 2 * _SIDE_IN, _CELL_IN * nrows + 0.6
    fig = Figure(figsize=(w_in, h_in), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    for (l, b, w, h), tile in zip(mosaic_axes_boxes(nrows, ncols, title.count("\n") + 1), tiles):
        _mosaic_tile(ax, (l * w_in, b * h_in, w * w_in, h * h_in), tile, log)
    ax.set(xlim=(0.0, w_in), ylim=(0.0, h_in), aspect="auto")
    ax.set_axis_off()
    fig.suptitle(title, fontsize=10, y=1 - 0.08 / h_in, va="top")
    return save_figure(fig, path)


@drawn_by_workers
def plot_system_mtf(path: str | Path, curves: dict, title: str = "") -> Path:
    """Lens, OLPF, detector and system MTF of one field point (``lensrt.analysis.psf.mtf_curves.mtf_curves``
    output with a detector), sagittal solid, tangential dashed, the diffraction limit and Nyquist marked."""
    fig = new_figure(6.4, 4.2)
    ax = fig.add_subplot()
    f = np.asarray(curves["freqs_cpmm"])
    ax.plot(f, curves["diffraction_limit"], color="0.55", lw=2.5, alpha=0.6,
            label=f"diffraction limit f/{curves['diffraction_f_number']:.3g}")
    parts = [("lens", "C0"), ("olpf", "C2"), ("detector", "C1"), ("system", "k")]
    for name, c in parts:
        if f"{name}_sagittal" not in curves:
            continue
        ax.plot(f, curves[f"{name}_sagittal"], color=c, lw=1.5, label=f"{name} S")
        ax.plot(f, curves[f"{name}_tangential"], color=c, lw=1.5, ls="--", label=f"{name} T")
    if "nyquist_cpmm" in curves:
        nq = curves["nyquist_cpmm"]
        ax.axvline(nq, color="k", lw=1, ls=":")
        ax.annotate(f"Nyquist {nq:.0f}", (nq, 0.98), rotation=90, ha="right", va="top", fontsize=8)
    ax.set(xlim=(0, float(f.max())), ylim=(0, 1.02), xlabel="spatial frequency (cycles/mm)", ylabel="MTF",
           title=title or "System MTF = lens x OLPF x detector (S solid, T dashed)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncols=2)
    return save_figure(fig, path)


def plot_convergence(path: str | Path, data: dict, title: str = "") -> Path:
    """Error against run time of ``lensrt.studies.convergence.study.converge_psf`` (or ``converge``) output:
    :func:`lensrt.views.plots.convergence.plot_error_vs_time`."""
    from .convergence import plot_error_vs_time
    return plot_error_vs_time(path, data, title)
