"""Renders as :mod:`lensrt.parallel` Jobs: items are sample passes, or image tiles with all their passes.

``render_job(setup, passes)`` is the Job of ``passes`` passes of a prepared render
(:func:`lensrt.render.integrator.prepare_render`); its value is the same bits on any number of
devices (each pass is deterministic on its device; :class:`PassReduction` folds passes in index
order in float64). Each item returns a whole image, so the host's share grows with the passes.

``render_tiles_job(setup, passes, tiles)`` splits the image into row bands instead: an item
renders every pass of its tile and sums them on its device (the float64 pass sums and moment
sums of :mod:`lensrt.render.passes`, in pass order), returning the tile's sums once. The host
only places tiles, and the value is the same bits as :func:`render_job` 's (a pixel's paths
depend on the pixel index and the pass seed only). ``render_workload`` registers the tiled job
as the ``render`` workload of ``benchmarks/bench_multigpu.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .passes import PassSum, RenderSetup, prepare_setup, run_pass_item

__all__ = ["PassReduction", "RenderSums", "render_job", "render_tiles_job", "TileResult", "TileReduction",
           "run_tile_item", "render_workload", "WORKLOAD_SIZES"]


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


@dataclass
class TileResult:
    """One tile's sums over all passes (float64): spectral (pixels * bands), XYZ and XYZ squared, paths through."""

    first: int
    end: int
    spec_sum: np.ndarray
    xyz1: np.ndarray
    xyz2: np.ndarray
    hits: int
    seconds: float = 0.0


def run_tile_item(item, prep, device: str) -> TileResult:
    """The ``run`` of a tiled render Job: ``item.params`` = (first pixel, end pixel, passes); every pass of
    the tile summed on the device in pass order (the arithmetic of the one-device render)."""
    import time
    from ..device import warp
    from .passes import device_pass
    from .pupil_table import launch_sliced
    wp = warp()
    t0 = time.perf_counter()
    p0, p1, passes = (int(v) for v in item.params)
    s = prep.setup
    n = p1 - p0
    k = prep.kernels
    spec_sum = wp.zeros(n * s.n_bands, dtype=wp.float64, device=device)
    s1 = wp.zeros((n, 3), dtype=wp.float64, device=device)
    s2 = wp.zeros((n, 3), dtype=wp.float64, device=device)
    hits = 0
    buf = None
    for index in range(passes):
        buf = device_pass(prep, index, buf, (p0, p1))
        launch_sliced(k.accumulate, n * s.n_bands, lambda base: [buf.spec[base:], spec_sum[base:]], device)
        wp.launch(k.accumulate_moments, dim=n, inputs=[buf.xyz, s1, s2], device=device)
        hits += int(buf.hits.numpy().astype(np.int64).sum())
    return TileResult(p0, p1, spec_sum.numpy(), s1.numpy(), s2.numpy(), hits, time.perf_counter() - t0)


@dataclass(frozen=True)
class TileReduction:
    """Places :class:`TileResult` s into the image; finishes as :class:`RenderSums`
    (a :class:`lensrt.parallel.Reduction`)."""

    n_pixels: int
    n_bands: int
    shape: tuple[int, int]
    spp_per_pass: int
    passes: int

    def start(self) -> dict:
        return {"spec": np.zeros(self.n_pixels * self.n_bands), "xyz1": np.zeros((self.n_pixels, 3)),
                "xyz2": np.zeros((self.n_pixels, 3)), "hits": 0}

    def add(self, acc: dict, index: int, result: TileResult) -> dict:
        acc["spec"][result.first * self.n_bands:result.end * self.n_bands] = result.spec_sum
        acc["xyz1"][result.first:result.end] = result.xyz1
        acc["xyz2"][result.first:result.end] = result.xyz2
        acc["hits"] += int(result.hits)
        return acc

    def finish(self, acc: dict) -> RenderSums:
        ps = PassSum(self.n_pixels, self.n_bands, self.shape, self.spp_per_pass)
        ps.xyz1, ps.xyz2, ps.passes, ps.hits = acc["xyz1"], acc["xyz2"], self.passes, acc["hits"]
        return RenderSums(acc["spec"], ps.xyz_mean(), ps.xyz_stderr(), ps.passes, ps.samples_per_pixel, ps.hits)


def render_tiles_job(setup: RenderSetup, passes: int, tiles: int):
    """The Job of ``passes`` passes of ``setup`` in ``tiles`` row bands (module docstring)."""
    from ..parallel import Job, make_items
    rows, cols = setup.shape
    n = max(1, min(int(tiles), rows))
    bounds = [rows * t // n * cols for t in range(n + 1)]
    items = make_items([(bounds[t], bounds[t + 1], int(passes)) for t in range(n)], setup.seed,
                       costs=[float(bounds[t + 1] - bounds[t]) for t in range(n)])
    red = TileReduction(setup.n_pixels, setup.n_bands, setup.shape, setup.spp_per_pass, int(passes))
    return Job(items, run_tile_item, red, context=setup, prepare=prepare_setup, name=f"render-tiles-{setup.scene.name}")


#: workload sizes: scene, image width, samples per pixel per pass, passes, tiles (0: one item per pass,
#: each returning the whole image -- the host reduction then grows with the passes). "large" keeps one
#: H100 busy for seconds (1920 x 1080 x 512 paths per pixel: 2.8 s measured, 1.1e9 paths).
WORKLOAD_SIZES = {
    "tiny": {"scene": "default", "width": 64, "spp_per_pass": 2, "passes": 4, "tiles": 4},
    "small": {"scene": "still_life_mesh", "width": 480, "spp_per_pass": 8, "passes": 8, "tiles": 8},
    "large": {"scene": "still_life_mesh", "width": 1920, "spp_per_pass": 8, "passes": 64, "tiles": 16},
}


def render_workload(size: str, seed: int):
    """Workload factory for ``benchmarks/bench_multigpu.py --workload render`` (sizes: :data:`WORKLOAD_SIZES`,
    or ``scene=...,width=...,spp_per_pass=...,passes=...,tiles=...``). The set-up (focus, exit-pupil table) runs
    here, on the first device Warp sees."""
    from ..parallel.workloads import parse_size
    from .integrator import RenderOptions, prepare_render
    from .scene import load_scene
    p = parse_size(size, WORKLOAD_SIZES)
    scene = load_scene(p["scene"])
    opts = RenderOptions(width=int(p["width"]), spp_per_pass=int(p["spp_per_pass"]),
                         samples_per_pixel=int(p["spp_per_pass"]) * int(p["passes"]), seed=int(seed))
    setup, _ = prepare_render(scene, None, opts)
    if int(p["tiles"]) > 0:
        return render_tiles_job(setup, int(p["passes"]), int(p["tiles"]))
    return render_job(setup, int(p["passes"]))
