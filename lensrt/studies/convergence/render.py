"""``lensrt converge --quantity render``: error against run time of a render's pixel region.

:class:`RenderRegion` is a :class:`lensrt.studies.convergence.study.Quantity`: the mean illuminance Y
(lux) over a window of a small render (default: the central 8 x 8 pixels of the default scene at
72 pixels wide), from the render's own passes (:mod:`lensrt.render.passes`), its standard error by
batch means over the passes. The camera, plan and exit-pupil table are prepared once; each run
packs the scene for its seed and paths per pass and times the passes only.

Samplers (the render kernel has one sampler; what varies is how a pass stratifies):

``random``
    one path per pixel per pass: plain Monte Carlo (a pass of one path has nothing to stratify).
``stratified``
    ``lensrt render``'s default, spp / 8 paths per pixel per pass, stratified within the pass
    over the pixel, the exit-pupil box and the wavelength.

The render kernel runs in float32 only. The reference (``--reference N``) is a ``random`` run of
N paths per pixel.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ...errors import LensrtError
from ...stats import Estimate, batch_means

__all__ = ["RenderRegion", "default_window"]


def default_window(shape: tuple[int, int], size: int = 8) -> tuple[int, int, int, int]:
    """The central ``size`` x ``size`` pixels (row0, row1, col0, col1) of an image of ``shape``."""
    rows, cols = shape
    h, w = min(size, rows), min(size, cols)
    r0, c0 = (rows - h) // 2, (cols - w) // 2
    return r0, r0 + h, c0, c0 + w


class RenderRegion:
    """``render``: mean Y over a window of a small render (module docstring)."""

    name = "render"
    unit, display_unit, display_scale = "lux", "lux", 1.0
    sample_unit = "paths per pixel"
    samplers, precisions = ("random", "stratified"), ("float32",)
    reference_sampler, reference_precision = "random", "float32"
    min_samples = 8

    def __init__(self, scene, lens=None, width: int = 72, window: tuple[int, int, int, int] | None = None,
                 device: str | None = None) -> None:
        from ...device import resolve_device
        from ...render.setup import RenderOptions, prepare_render, scale_pixels
        scene = scale_pixels(scene, width)
        if window is None:
            window = default_window((scene.sensor.pixels_y, scene.sensor.pixels_x))
        self.device = resolve_device(device)
        self.setup, _ = prepare_render(scene, lens, RenderOptions(window=window, samples_per_pixel=1,
                                                                  spp_per_pass=1), self.device)
        if self.setup.plan.variant.splat:
            raise LensrtError("this scene renders by light splatting, not camera paths",
                              hint="a scene with surfaces (e.g. the default scene)")
        self.window = tuple(int(v) for v in window)
        r0, r1, c0, c1 = self.window
        self.label = (f"render: mean Y over pixels rows {r0}-{r1 - 1}, columns {c0}-{c1 - 1} of "
                      f"{scene.name} at {scene.sensor.pixels_x} x {scene.sensor.pixels_y} px")

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        from ...render.passes import PassSum, device_pass, prepare_setup
        if precision != "float32":
            raise LensrtError("the render kernel runs in float32 only")
        spp = int(samples)
        ppp = 1 if sampler == "random" else max(1, spp // 8)
        passes = max(2, spp // ppp)
        s = dataclasses.replace(self.setup, spp_per_pass=ppp, seed=int(seed))
        prep = prepare_setup(s, self.device)
        acc = PassSum(s.n_pixels, s.n_bands, s.shape, ppp)
        buf = None
        t0 = time.perf_counter()
        for p in range(passes):
            buf = device_pass(prep, p, buf)
            acc.add_counts(buf.xyz.numpy()[:, 1], 0)
        seconds = time.perf_counter() - t0
        v, se = batch_means(np.asarray(acc.region_means)[:, 0])
        return Estimate(float(v), float(se), passes * ppp, seconds, f"batch means over {passes} passes", "lux")

    def closed_form(self):
        return None, "a rendered scene has no closed form here"
