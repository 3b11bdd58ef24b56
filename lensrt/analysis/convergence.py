"""Error against run time for geometric PSFs: samplers and precisions compared (``lensrt psf --converge``).

For one field point the RMS spot radius is estimated at growing ray counts
N = 2^k with each sampler (plain random, stratified, scrambled Sobol', R2) and
precision, with the same grid and seed. Each run reports its value, its
jackknife standard error over the batches, and its trace seconds (the stream
kernel's wall-clock time); the error against a reference -- a Sobol' float64
run with ``reference_factor`` times the largest N -- is reported beside it.
Slopes are least-squares fits of log(standard error) against log(seconds)
and against log(rays) (:func:`lensrt.stats.fit_loglog_slope`): about -0.5 for
plain Monte Carlo; stratified and low-discrepancy sampling fall faster (down
to about -0.75 for a pupil with sharp edges), which is what they buy.
Seconds include fixed launch overheads, so at small N the slope against
seconds is shallower than against rays.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..stats import fit_loglog_slope
from .fields import FieldSpec
from .grid import ImageGrid
from .psf_setup import PsfSetup

__all__ = ["converge_psf", "default_ray_counts"]


def default_ray_counts(max_rays: int, batches: int, n_points: int = 7) -> list[int]:
    """Powers of two from about max_rays / 2^(n_points - 1) to max_rays (at least 64 rays per batch)."""
    top = max(int(max_rays), batches * 64)
    k_hi = int(math.floor(math.log2(top)))
    k_lo = max(int(math.ceil(math.log2(batches * 64))), k_hi - n_points + 1)
    return [1 << k for k in range(k_lo, k_hi + 1)]


def converge_psf(setup: PsfSetup, f: FieldSpec, samplers: Sequence[str] = ("random", "stratified", "sobol"),
                 precisions: Sequence[str] = ("float32", "float64"), ray_counts: Sequence[int] | None = None,
                 reference_factor: int = 8, seed: int = 0, device: str | None = None) -> dict:
    """The convergence study of the module docstring; JSON-ready dict with ``runs``, ``slopes``, ``reference``."""
    from .raypsf import _rms_rel_error, prepare_field, psf_window, run_stream
    geom = prepare_field(setup, f, device)
    pitch_um, pixels, _ = psf_window(setup, geom, device)
    grid = ImageGrid.centred((pixels, pixels), pitch_um, geom.reference_mm)
    counts = list(ray_counts) if ray_counts else default_ray_counts(setup.rays, setup.batches)
    base = setup.with_(target_error=None, time_budget_s=None)
    ref_setup = base.with_(sampler="sobol", precision="float64", rays=int(reference_factor * max(counts)))
    tot, _ = run_stream(ref_setup, geom, grid, seed + 1_000_003, device)
    ref_value, ref_rel = _rms_rel_error(tot.moments)
    ref_rays = int(tot.rays)
    runs, slopes = [], []
    for prec in precisions:
        for samp in samplers:
            pts = []
            for n in counts:
                tot, _ = run_stream(base.with_(sampler=samp, precision=prec, rays=int(n)), geom, grid, seed, device)
                value, rel = _rms_rel_error(tot.moments)
                pts.append({"rays": tot.rays, "seconds": tot.trace_seconds, "value_mm": value,
                            "stderr_mm": rel * value, "error_mm": abs(value - ref_value)})
                runs.append({"sampler": samp, "precision": prec, **pts[-1]})
            sec = [p["seconds"] for p in pts]
            se = [p["stderr_mm"] for p in pts]
            err = [p["error_mm"] for p in pts]
            slopes.append({"sampler": samp, "precision": prec,
                           "slope_stderr_vs_seconds": fit_loglog_slope(sec, se),
                           "slope_stderr_vs_rays": fit_loglog_slope([p["rays"] for p in pts], se),
                           "slope_error_vs_seconds": fit_loglog_slope(sec, err) if np.all(np.asarray(err) > 0)
                           else None})
    return {"quantity": "rms_radius_mm", "field": f.to_dict(), "reference_mm": list(geom.reference_mm),
            "grid": grid.to_dict(), "ray_counts": counts, "batches": setup.batches, "seed": seed,
            "reference": {"value_mm": ref_value, "stderr_mm": ref_rel * ref_value, "rays": ref_rays,
                          "sampler": "sobol", "precision": "float64"},
            "runs": runs, "slopes": slopes}
