"""Progressive rendering's bookkeeping: when to stop, the error measure, per-pass history rows and the
region estimates (shared by camera-path renders and light splats)."""
from __future__ import annotations

import numpy as np

from ..stats import Estimate, StopRule, batch_means
from .passes import REGIONS, PassSum
from .setup import RenderOptions

__all__ = ["MAX_SPP_OPEN", "stop_rule", "relative_error", "regions", "history_row"]

#: most samples per pixel a render started with a time budget or target error but no count may take
MAX_SPP_OPEN = 65536


def stop_rule(scene, options: RenderOptions, n_pixels: int) -> StopRule:
    budget = options.time_budget_s if options.time_budget_s is not None else scene.render.time_budget_s
    target = options.target_rel_error if options.target_rel_error is not None else scene.render.target_rel_error
    spp = options.samples_per_pixel
    if spp is None:
        spp = MAX_SPP_OPEN if (options.time_budget_s or options.target_rel_error) else scene.render.samples_per_pixel
    return StopRule(max_samples=int(spp) * n_pixels, target_error=target, time_budget_s=budget, relative=True,
                    min_batches=4)


def relative_error(acc: PassSum) -> float | None:
    """The render's error measure: RMS over lit pixels of the relative standard error of Y.

    Lit pixels: Y above 5 % of the 99th percentile of Y over the pixels that received light.
    ``None`` before two passes or when no pixel received light.
    """
    if acc.passes < 2:
        return None
    y = acc.xyz_mean()[..., 1]
    se = acc.xyz_stderr()[..., 1]
    pos = y[y > 0]
    if pos.size == 0:
        return None
    lit = y > 0.05 * float(np.percentile(pos, 99))
    return float(np.sqrt(np.mean((se[lit] / y[lit]) ** 2)))


def regions(acc: PassSum, samples: int, seconds: float) -> dict[str, Estimate]:
    out = {}
    if acc.passes < 2:
        return out
    means = np.asarray(acc.region_means)
    for k, (name, *_rest) in enumerate(REGIONS):
        v, se = batch_means(means[:, k])
        out[name] = Estimate(float(v), float(se), samples, seconds, f"batch means over {acc.passes} passes", "lux")
    return out


def history_row(acc: PassSum, n_pixels: int, seconds: float, err: float | None) -> dict:
    row = {"passes": acc.passes, "samples_per_pixel": acc.samples_per_pixel, "samples": acc.samples_per_pixel * n_pixels,
           "seconds": seconds, "rel_error": err}
    if acc.passes >= 2:
        means = np.asarray(acc.region_means)
        for k, (name, *_rest) in enumerate(REGIONS):
            v, se = batch_means(means[:, k])
            row[f"Y_{name.replace(' ', '_')}"] = [float(v), float(se)]
    return row
