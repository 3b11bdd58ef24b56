"""Plots of zoom and focus: focus breathing (AFoV against focus distance), the focal-length curve and the MTF
per configuration."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .figure import drawn_by_workers, new_figure, save_figure

__all__ = ["plot_breathing", "plot_breathing_family", "plot_zoom_curve", "plot_zoom_mtf"]


@drawn_by_workers
def plot_breathing(path: str | Path, curve: dict, title: str = "") -> Path:
    """AFoV (deg) against focus distance (m): real rays for the lens's mechanism and the unit-focus formula."""
    fig = new_figure(6.0, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    d = np.asarray(curve["distance_mm"], dtype=np.float64)
    x = np.where(np.isinf(d), np.nan, d / 1000.0)
    finite = np.isfinite(x)
    ax.plot(x[finite], np.asarray(curve["afov_real_deg"])[finite], "o-", label="real rays, " + curve["mechanism"])
    ax.plot(x[finite], np.asarray(curve["afov_unit_focus_formula_deg"])[finite], "s--",
            label="unit-focus formula (Field Guide p. 18)")
    if not finite.all():
        ax.axhline(float(np.asarray(curve["afov_real_deg"])[~finite][0]), color="C0", lw=0.6, ls=":",
                   label="real rays at infinity")
    ax.set_xscale("log")
    ax.set_xlabel("focus distance from the first vertex (m)")
    ax.set_ylabel(f"diagonal angle of view (deg), d = {curve['sensor_diagonal_mm']:.2f} mm")
    ax.set_title(title or "focus breathing", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


@drawn_by_workers
def plot_breathing_family(path: str | Path, curves: Sequence[dict], title: str = "") -> Path:
    """AFoV (deg) against focus distance (m) of several configurations: real rays solid, the unit-focus formula
    dashed, one colour per configuration (each curve a ``focus_breathing(...).to_dict()`` with a ``name``)."""
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    for k, c in enumerate(curves):
        d = np.asarray(c["distance_mm"], dtype=np.float64)
        x = np.where(np.isinf(d), np.nan, d / 1000.0)
        fin = np.isfinite(x)
        ax.plot(x[fin], np.asarray(c["afov_real_deg"])[fin], "o-", color=f"C{k}", label=f"{c['name']}: real rays")
        ax.plot(x[fin], np.asarray(c["afov_unit_focus_formula_deg"])[fin], "--", color=f"C{k}", lw=0.8)
        if not fin.all():  # infinity: a short tick at the right edge
            ax.axhline(float(np.asarray(c["afov_real_deg"])[~fin][0]), xmin=0.97, xmax=1.0, color=f"C{k}", lw=2)
    ax.plot([], [], "k--", lw=0.8, label="unit-focus formula (p. 18)")
    ax.set_xscale("log")
    ax.set_xlabel("focus distance from the first vertex (m); right-edge ticks: infinity")
    ax.set_ylabel("diagonal angle of view (deg)")
    ax.set_title((title or "focus breathing per configuration").replace(": ", ":\n", 1), fontsize=8)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    return save_figure(fig, path)


@drawn_by_workers
def plot_zoom_curve(path: str | Path, names: Sequence[str], efl_mm: Sequence[float], f_number: Sequence[float],
                    title: str = "") -> Path:
    """EFL and f-number per configuration."""
    fig = new_figure(6.0, 3.5)
    ax = fig.add_subplot(1, 1, 1)
    k = np.arange(len(names))
    ax.plot(k, efl_mm, "o-", color="C0")
    ax.set_xticks(k, list(names))
    ax.set_ylabel("EFL (mm)", color="C0")
    ax2 = ax.twinx()
    ax2.plot(k, f_number, "s--", color="C1")
    ax2.set_ylabel("f-number", color="C1")
    ax.set_title(title or "focal length per configuration")
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


@drawn_by_workers
def plot_zoom_mtf(path: str | Path, mtf: Sequence[dict], title: str = "") -> Path:
    """Sagittal (solid) and tangential (dashed) MTF per configuration, one panel per reference frequency,
    one colour per field point (``mtf``: :func:`lensrt.analysis.configurations.configuration_mtf`)."""
    freqs, fields = mtf[0]["freqs_cpmm"], mtf[0]["fields"]
    fig = new_figure(3.0 * len(freqs) + 0.5, 3.5)
    k = np.arange(len(mtf))
    for i, fr in enumerate(freqs):
        ax = fig.add_subplot(1, len(freqs), i + 1)
        for j, hy in enumerate(fields):
            s = [float(np.asarray(m["sagittal"])[j, i]) for m in mtf]
            t = [float(np.asarray(m["tangential"])[j, i]) for m in mtf]
            ax.plot(k, s, "o-", color=f"C{j}", label=f"Hy {hy:g}")
            ax.plot(k, t, "s--", color=f"C{j}")
        ax.set_xticks(k, [m["name"] for m in mtf], fontsize=7, rotation=30)
        ax.set_ylim(0.0, 1.0)
        ax.set_title(f"{fr:.3g} cycles/mm", fontsize=9)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.set_ylabel("MTF (S solid, T dashed)")
            ax.legend(fontsize=7)
    fig.suptitle(title or "MTF per configuration", fontsize=9)
    return save_figure(fig, path)
