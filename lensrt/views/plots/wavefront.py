"""Wavefront figures: the OPD map over the pupil beside the Zernike coefficients (Noll order) of one field."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figure import new_figure, save_figure

__all__ = ["plot_wavefront"]


def plot_wavefront(metrics, label: str, path: str | Path) -> Path:
    """OPD map (waves, as referred) and a bar chart of the Noll Zernike coefficients (waves RMS per term)."""
    fig = new_figure(10.0, 4.2)
    ax, bx = fig.subplots(1, 2, width_ratios=[1.0, 1.4])
    opd = np.asarray(metrics.opd_waves, dtype=np.float64)
    lim = float(np.nanmax(np.abs(opd))) if np.isfinite(opd).any() else 1.0
    im = ax.imshow(opd, extent=(-1, 1, -1, 1), cmap="RdBu_r", vmin=-lim, vmax=lim, origin="upper")
    fig.colorbar(im, ax=ax, label="OPD (waves)")
    ax.set_xlabel("pupil x")
    ax.set_ylabel("pupil y")
    ax.set_title(f"{label}, {metrics.wavelength_nm:g} nm: RMS {metrics.rms_waves:.3f}, PV {metrics.pv_waves:.3f} "
                 f"waves, Strehl {metrics.strehl:.3f}", fontsize=9)
    c = np.asarray(metrics.zernike_noll_waves)
    j = np.arange(1, c.size + 1)
    bx.bar(j, c, color=np.where(c >= 0, "tab:red", "tab:blue"))
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_xlabel("Noll index j")
    bx.set_ylabel("coefficient (waves RMS)")
    bx.set_title(f"Zernike (Noll, unit RMS), reference {metrics.reference}; fit residual "
                 f"{metrics.zernike_noll_residual_rms_waves:.1e} waves", fontsize=9)
    return save_figure(fig, path)
