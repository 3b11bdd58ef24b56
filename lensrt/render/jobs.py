"""Renders as :mod:`lensrt.parallel` Jobs: items are sample passes, reduced in pass order.

``render_job(setup, passes)`` is the Job of ``passes`` passes of a prepared render
(:func:`lensrt.render.integrator.prepare_render`); its value is the same bits on any number of
devices (each pass is deterministic on its device; :class:`PassReduction` folds passes in index
order in float64). ``render_workload`` registers it as the ``render`` workload of
``benchmarks/bench_multigpu.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .passes import PassSum, RenderSetup, prepare_setup, run_pass_item

__all__ = ["PassReduction", "RenderSums", "render_job", "render_workload", "WORKLOAD_SIZES"]


@dataclass
class RenderSums:
    """A reduced render: spectral sum over passes (pixels * bands, float64), per-pixel XYZ mean and stderr."""

    spec_sum: np.ndarray
    xyz: np.ndarray
    xyz_stderr: np.ndarray
    passes: int
    samples_per_pixel: int
    hits: int

    def irradiance(self, shape: tuple[int, int], n_bands: int) -> np.ndarray:
        return (self.spec_sum / self.samples_per_pixel).astype(np.float32).reshape(shape + (n_bands,))


@dataclass(frozen=True)
class PassReduction:
    """Folds :class:`lensrt.render.passes.PassResult` s in pass order (a :class:`lensrt.parallel.Reduction`)."""

    n_pixels: int
    n_bands: int
    shape: tuple[int, int]
    spp_per_pass: int

    def start(self) -> PassSum:
        return PassSum(self.n_pixels, self.n_bands, self.shape, self.spp_per_pass)

    def add(self, acc: PassSum, index: int, result) -> PassSum:
        acc.add(result.xyz, result.hits, result.spec)
        return acc

    def finish(self, acc: PassSum) -> RenderSums:
        return RenderSums(acc.spec, acc.xyz_mean(), acc.xyz_stderr(), acc.passes, acc.samples_per_pixel, acc.hits)


def render_job(setup: RenderSetup, passes: int, first: int = 0):
    """The Job of passes ``first .. first + passes - 1`` of ``setup``."""
    from ..parallel import Job, make_items
    items = make_items(range(first, first + int(passes)), setup.seed)
    red = PassReduction(setup.n_pixels, setup.n_bands, setup.shape, setup.spp_per_pass)
    return Job(items, run_pass_item, red, context=setup, prepare=prepare_setup, name=f"render-{setup.scene.name}")


#: workload sizes: scene, image width, samples per pixel per pass, passes
WORKLOAD_SIZES = {
    "tiny": {"scene": "default", "width": 64, "spp_per_pass": 2, "passes": 4},
    "small": {"scene": "still_life_mesh", "width": 480, "spp_per_pass": 8, "passes": 8},
    "large": {"scene": "still_life_mesh", "width": 1920, "spp_per_pass": 8, "passes": 8},
}


def render_workload(size: str, seed: int):
    """Workload factory for ``benchmarks/bench_multigpu.py --workload render`` (sizes: :data:`WORKLOAD_SIZES`,
    or ``scene=...,width=...,spp_per_pass=...,passes=...``). The set-up (focus, exit-pupil table) runs here, on
    the first device Warp sees."""
    from ..parallel.workloads import parse_size
    from .integrator import RenderOptions, prepare_render
    from .scene import load_scene
    p = parse_size(size, WORKLOAD_SIZES)
    scene = load_scene(p["scene"])
    opts = RenderOptions(width=int(p["width"]), spp_per_pass=int(p["spp_per_pass"]),
                         samples_per_pixel=int(p["spp_per_pass"]) * int(p["passes"]), seed=int(seed))
    setup, _ = prepare_render(scene, None, opts)
    return render_job(setup, int(p["passes"]))
