"""Error-against-run-time figures (``lensrt converge``, ``lensrt psf --converge``).

Left: the measured RMS error (over the repeats, against the reference) against Monte Carlo
seconds, log-log, one line per sampler (colour) and precision (solid float32, dashed float64),
with a slope -1/2 guide. Right: measured RMS error (solid) and the RMS of the reported standard
errors (dotted) against the sample count, for the first precision -- where they agree the
reported errors are honest. A high-sample reference's own standard error is drawn as a grey
line (points near it are reference-limited).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_error_vs_time"]

_ORDER = ["random", "stratified", "sobol", "r2"]


def plot_error_vs_time(path: str | Path, data: dict, title: str = "") -> Path:
    """The figure of the module docstring from :func:`lensrt.studies.convergence.study.converge` output."""
    from .figure import new_figure as _figure, save_figure as _save
    scale = float(data.get("display_scale", 1.0))
    unit = data.get("display_unit", "")
    fig = _figure(10.0, 4.4)
    ax_t, ax_n = fig.subplots(1, 2)
    samplers = sorted({r["sampler"] for r in data["runs"]}, key=lambda s: _ORDER.index(s) if s in _ORDER else 9)
    colours = {s: f"C{i}" for i, s in enumerate(samplers)}
    styles = {"float32": "-", "float64": "--"}
    precisions = list(dict.fromkeys(r["precision"] for r in data["runs"]))
    slopes = {(s["sampler"], s["precision"]): s for s in data["slopes"]}
    for (samp, prec), sl in slopes.items():
        pts = [r for r in data["runs"] if r["sampler"] == samp and r["precision"] == prec]
        t = np.array([p["seconds"] for p in pts])
        e = np.array([p["rms_error"] for p in pts]) * scale
        s = sl.get("error_vs_seconds")
        lab = f"{samp} {prec}" + (f": slope {s:.2f}" if s is not None else "")
        ax_t.loglog(t, e, styles.get(prec, "-"), color=colours[samp], marker="o", ms=3, label=lab)
        if prec == precisions[0]:
            n = np.array([p["samples"] for p in pts])
            se = np.array([p["rms_stderr"] for p in pts]) * scale
            sn = sl.get("error_vs_samples")
            ax_n.loglog(n, e, "-", color=colours[samp], marker="o", ms=3,
                        label=f"{samp}" + (f": slope {sn:.2f}" if sn is not None else ""))
            ax_n.loglog(n, se, ":", color=colours[samp], marker="o", ms=3, mfc="none")
    base = [r for r in data["runs"] if r["sampler"] == samplers[0] and r["precision"] == precisions[0]]
    if base:
        for ax, key in ((ax_t, "seconds"), (ax_n, "samples")):
            x0, e0 = base[0][key], base[0]["rms_error"] * scale
            xx = np.array([x0, max(r[key] for r in data["runs"])])
            ax.loglog(xx, e0 * (xx / x0) ** -0.5, color="0.6", lw=1, ls=":", label="slope -1/2")
    ref = data["reference"]
    if ref.get("stderr", 0) > 0:
        for ax in (ax_t, ax_n):
            ax.axhline(ref["stderr"] * scale, color="0.5", lw=0.8, ls="-.", label="reference's standard error")
    ylab = f"RMS error ({unit})" if unit else "RMS error"
    ax_t.set(xlabel="Monte Carlo seconds", ylabel=ylab, title="measured error against run time")
    ax_n.set(xlabel=data.get("sample_unit", "samples"), ylabel=ylab,
             title=f"measured (solid) and reported (dotted), {precisions[0]}")
    for ax in (ax_t, ax_n):
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    rk = "closed form" if ref["kind"] == "closed form" else f"{ref['samples']:.3g} {data.get('sample_unit', '')}"
    fig.suptitle(title or f"{data['label']}\n{data['repeats']} repeats per point; reference: {rk}", fontsize=9)
    return _save(fig, path)
