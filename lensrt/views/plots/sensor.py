"""Plots of the sensor stage: EMVA 1288 photon transfer and SNR, raw and output histograms (matplotlib)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ...io.paths import output_dir, output_file

__all__ = ["plot_emva", "plot_histograms"]


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_emva(result: Any, folder: str | Path) -> list[Path]:
    """Photon-transfer (variance vs mean) and SNR-vs-photons plots of an :class:`EmvaResult`; returns the files."""
    plt = _plt()
    folder = output_dir(folder)
    c = result.snr_curve
    files = []
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(c["mu_y"], c["var_y"], "o", ms=3, label="simulated pairs")
    x = np.linspace(c["mu_y"].min(), c["mu_y"].max(), 50)
    ax.plot(x, result.system_gain_dn_per_e * (x - result.meta["mu_y_dark"]) + result.meta["var_y_dark"], "-", lw=1,
            label=f"K = {result.system_gain_dn_per_e:.4g} DN/e-")
    ax.set_xlabel("mean mu_y (DN)")
    ax.set_ylabel("temporal variance sigma_y^2 (DN^2)")
    ax.set_title(f"Photon transfer (EMVA 1288), {result.meta['channel']} at {result.meta['wavelength_nm']:g} nm, ISO {result.meta['iso']:g}")
    ax.legend()
    files.append(folder / "photon_transfer.png")
    fig.savefig(files[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ok = np.isfinite(c["snr"])
    ax.loglog(c["mu_p"][ok], c["snr"][ok], "o", ms=3, label="measured")
    ax.loglog(c["mu_p"], c["snr_model"], "-", lw=1, label="linear model (EMVA)")
    ax.loglog(c["mu_p"], c["snr_ideal"], "--", lw=1, label="ideal sqrt(mu_p)")
    ax.set_xlabel("photons per photosite mu_p")
    ax.set_ylabel("SNR")
    ax.set_title("SNR curve")
    ax.legend()
    files.append(folder / "snr.png")
    fig.savefig(files[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)
    return files


def plot_histograms(raw_hist: dict, out_hist: dict | None, path: str | Path) -> Path:
    """Raw (per CFA channel, DN) and output (per channel, DOL) histograms in one figure (p. 69)."""
    plt = _plt()
    n = 2 if out_hist else 1
    fig, axes = plt.subplots(1, n, figsize=(6 * n, 4))
    axes = np.atleast_1d(axes)
    for hist, ax, label in ((raw_hist, axes[0], "raw value (DN)"), (out_hist, axes[-1], "output level (DOL)")):
        if hist is None:
            continue
        e = hist["edges"]
        centres = 0.5 * (e[1:] + e[:-1])
        for ch, col in zip("RGB", ("tab:red", "tab:green", "tab:blue")):
            ax.plot(centres, hist[ch], color=col, lw=1, label=ch)
        ax.set_xlabel(label)
        ax.set_ylabel("count")
        ax.set_yscale("log")
        ax.legend()
    axes[0].set_title("raw histogram")
    if out_hist:
        axes[-1].set_title("output histogram")
    path = output_file(path)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path
