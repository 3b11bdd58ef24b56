"""Renders as :mod:`lensrt.parallel` Jobs: items are sample passes, or image tiles with all their passes.

``render_job(setup, passes)`` is the Job of ``passes`` passes of a prepared render
(:func:`lensrt.render.integrator.prepare_render`); its value is the same bits on any number of
devices (each pass is deterministic on its device; :class:`PassReduction` folds passes in index
order in float64). Each item returns a whole image, so the host's share grows with the passes.

``render_tiles_job(setup, passes, tiles)`` splits the image into row bands instead: an item
renders every pass of its tile and sums them on its device (the float64 pass sums and moment
sums of :mod:`lensrt.render.passes`, in pass order), returning the tile's sums once. The host
only places tiles, and the value is the same bits as :func:`render_job` 's (a pixel's paths
depend on the pixel index and the pass seed only). A tile also returns, per pass, its paths through
the lens and the sums of Y over its part of each region of
:func:`lensrt.render.passes.region_slices`, both counted on the device while the passes run
(:mod:`lensrt.render.tile_kernels`: no device wait and no host work between passes, so several
devices driven from one process do not queue for the interpreter lock pass by pass), so that the
reduced :class:`lensrt.render.passes.PassSum` carries the per-pass data of a pass-by-pass render:
the same hit counts, and region means equal to about 1e-15 relative (row-segment sums added tile by
tile instead of one sum over the region).

The image is written in place: each run of the job makes its image arrays once in the parent
(:class:`lensrt.parallel.shm.SharedArrays`, named by the job's token, which every item carries), and a
tile that finds them -- a device thread of the parent, or a worker process or Dask worker on the same
machine -- copies its sums from the device straight into its rows and computes its XYZ mean and
standard error there, returning only its per-pass counts. The parent's work per tile is then a few
hundred bytes whatever the tile's size (before: unpacking ~32 MB of a large-render tile from shared
memory and copying it into the image, serially for every device, with the last round's tiles
unpacked one after the other after the last device had finished). A tile that finds no arrays (a
worker on another machine) returns its sums as before and the reduction places them: the same bits.
:func:`lensrt.render.integrator.render` runs this job for a fixed sample count on an executor;
``render_workload`` registers it as the ``render`` workload of ``benchmarks/bench_multigpu.py``.
"""
from __future__ import annotations

import uuid
from dataclasses import dataclass

import numpy as np

from .passes import REGIONS, PassSum, RenderSetup, moments_stderr, prepare_setup, region_slices, run_pass_item

__all__ = ["PassReduction", "RenderSums", "render_job", "render_tiles_job", "TileResult", "TileReduction",
           "run_tile_item", "region_cuts", "region_sums_from_segments", "render_workload", "WORKLOAD_SIZES",
           "image_layout"]


@dataclass
class RenderSums:
    """A reduced render: spectral sum over passes (pixels * bands, float64), per-pixel XYZ mean and stderr;
    ``pass_sum`` the :class:`PassSum` they come from (per-pass hits and region means included)."""

    spec_sum: np.ndarray
    xyz: np.ndarray
    xyz_stderr: np.ndarray
    passes: int
    samples_per_pixel: int
    hits: int
    pass_sum: PassSum | None = None

    @classmethod
    def of(cls, acc: PassSum) -> "RenderSums":
        return cls(acc.spec, acc.xyz_mean(), acc.xyz_stderr(), acc.passes, acc.samples_per_pixel, acc.hits, acc)

    def irradiance(self, shape: tuple[int, int], n_bands: int) -> np.ndarray:
        """The mean over all paths as float32 (times 1 / samples, as the one-device render's finalize kernel)."""
        return (self.spec_sum * (1.0 / self.samples_per_pixel)).astype(np.float32).reshape(shape + (n_bands,))


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
        return RenderSums.of(acc)


def render_job(setup: RenderSetup, passes: int, first: int = 0):
    """The Job of passes ``first .. first + passes - 1`` of ``setup``."""
    from ..parallel import Job, make_items
    items = make_items(range(first, first + int(passes)), setup.seed)
    red = PassReduction(setup.n_pixels, setup.n_bands, setup.shape, setup.spp_per_pass)
    return Job(items, run_pass_item, red, context=setup, prepare=prepare_setup, name=f"render-{setup.scene.name}")


@dataclass
class TileResult:
    """One tile's sums over all passes (float64): spectral (pixels * bands), XYZ and XYZ squared, paths through;
    per pass: ``pass_hits`` (passes,) paths through the lens and ``region_y`` (passes, regions) the sums of
    the per-pixel Y sums over the tile's part of each region (:func:`region_sums_from_segments`).
    ``placed``: the tile wrote its sums, XYZ mean and standard error into the run's image arrays itself
    (:func:`image_layout`); then ``spec_sum``, ``xyz1`` and ``xyz2`` are None."""

    first: int
    end: int
    spec_sum: np.ndarray | None
    xyz1: np.ndarray | None
    xyz2: np.ndarray | None
    hits: int
    pass_hits: np.ndarray
    region_y: np.ndarray
    seconds: float = 0.0
    placed: bool = False


def image_layout(n_pixels: int, n_bands: int) -> dict:
    """The arrays of a tiled render's image (a :data:`lensrt.parallel.shm.Layout`): spectral sums, XYZ sums and
    sums of squares, XYZ mean and its standard error, per pixel, float64."""
    px3 = ((int(n_pixels), 3), "float64")
    return {"spec": ((int(n_pixels) * int(n_bands),), "float64"), "xyz1": px3, "xyz2": px3, "xyz": px3,
            "stderr": px3}


def _place_moments(image: dict, p0: int, p1: int, passes: int, spp_per_pass: int) -> None:
    """XYZ mean and standard error of pixels [p0, p1) from the sums already in ``image`` (element by element:
    the bits of the whole-image computation)."""
    x1, x2 = image["xyz1"][p0:p1], image["xyz2"][p0:p1]
    image["xyz"][p0:p1] = x1 / max(int(passes) * int(spp_per_pass), 1)
    image["stderr"][p0:p1] = moments_stderr(x1, x2, int(passes), int(spp_per_pass))


def _copy_to_host(dest: np.ndarray, src) -> None:
    """Device array ``src`` into the host array ``dest`` (same shape and dtype, C-contiguous), without an
    intermediate host array; returns when the copy is done."""
    from ..device import warp
    wp = warp()
    host = wp.array(dest, dtype=src.dtype, shape=src.shape, device="cpu", copy=False)
    wp.copy(host, src)
    if src.device.is_cuda:
        wp.synchronize_stream(src.device.stream)


#: the longest column segment of :func:`region_cuts` (one device thread sums one segment of a row)
SEGMENT_COLS = 128


def region_cuts(shape: tuple[int, int], longest: int = SEGMENT_COLS) -> np.ndarray:
    """Column cuts 0 = c_0 < c_1 < ... < c_m = cols such that every region of :func:`region_slices` spans
    whole segments [c_k, c_k+1) and no segment is longer than ``longest`` columns (int32)."""
    cols = int(shape[1])
    cuts = {0, cols}
    for _, _, c0, c1 in region_slices(shape):
        cuts.update((c0, c1))
    cuts.update(range(0, cols, max(1, int(longest))))
    return np.array(sorted(cuts), dtype=np.int32)


def region_sums_from_segments(seg: np.ndarray, row0: int, shape: tuple[int, int], cuts: np.ndarray) -> np.ndarray:
    """Region sums from row-segment sums: ``seg`` (..., rows, segments) holds, for image rows row0,
    row0 + 1, ..., the sums over the columns [cuts[k], cuts[k + 1]) (0 outside the pixels summed); the
    result (..., regions) sums the segments inside each region of :func:`region_slices`."""
    seg = np.asarray(seg, dtype=np.float64)
    rb = row0 + seg.shape[-2]
    out = np.zeros(seg.shape[:-2] + (len(REGIONS),))
    for k, (r0, r1, c0, c1) in enumerate(region_slices(shape)):
        a, b = max(r0, row0), min(r1, rb)
        ks = np.flatnonzero((cuts[:-1] >= c0) & (cuts[1:] <= c1))
        if a < b and len(ks):
            out[..., k] = seg[..., a - row0:b - row0, ks[0]:ks[-1] + 1].sum(axis=(-2, -1))
    return out


def run_tile_item(item, prep, device: str) -> TileResult:
    """The ``run`` of a tiled render Job: ``item.params`` = (first pixel, end pixel, passes, image token);
    every pass of the tile summed on the device in pass order (the arithmetic of the one-device render),
    with each pass's paths through the lens and Y sums over the tile's part of the regions kept on the
    device (:mod:`lensrt.render.tile_kernels`): the passes are queued without a wait between them, and
    the tile comes to the host once, at its end -- into the run's image arrays when this process finds
    them (:func:`lensrt.parallel.shm.attach_shared`), else into the result. Per pass: the camera kernel
    and one :func:`lensrt.render.tile_kernels.tile_pass_sums` launch, both recorded once per tile
    (:class:`lensrt.render.passes.RecordedPasses`) and replayed."""
    import time
    from ..device import warp
    from ..parallel.shm import attach_shared
    from .passes import RecordedPasses
    from .pupil_table import launch_sliced
    from .tile_kernels import tile_pass_sums
    wp = warp()
    t0 = time.perf_counter()
    p0, p1, passes = (int(v) for v in item.params[:3])
    token = item.params[3] if len(item.params) > 3 else None
    s = prep.setup
    n = p1 - p0
    cols = s.shape[1]
    ra, rb = p0 // cols, -(-p1 // cols)
    cuts_h = region_cuts(s.shape)
    cuts = wp.array(cuts_h, dtype=wp.int32, device=device)
    n_segs = len(cuts_h) - 1
    n_cells = (rb - ra) * n_segs
    n_spec = n * s.n_bands
    spec_sum = wp.zeros(n_spec, dtype=wp.float64, device=device)
    s1 = wp.zeros((n, 3), dtype=wp.float64, device=device)
    s2 = wp.zeros((n, 3), dtype=wp.float64, device=device)
    seg_y = wp.zeros((passes, rb - ra, n_segs), dtype=wp.float64, device=device)
    seg_hits = wp.zeros((passes, rb - ra, n_segs), dtype=wp.int64, device=device)
    # both launches of a pass recorded once (arguments packed once), replayed with the pass's seed and slot
    camera = RecordedPasses(prep, (p0, p1))
    buf = camera.out
    for index in range(passes):
        camera.run(index)
        # launched, not replayed: a recorded launch of this kernel crashed the process now and then on the CPU
        # (segmentation fault in Warp's invoke, 2026-11-26, cause not found)
        launch_sliced(tile_pass_sums, max(n_spec, n, n_cells),
                      lambda base, index=index: [int(base), buf.spec, spec_sum, n_spec, buf.xyz, s1, s2, buf.hits, p0,
                                                 p1, ra, cols, cuts, n_segs, n_cells, index, seg_y, seg_hits], device)
    pass_hits = seg_hits.numpy().sum(axis=(1, 2))
    region_y = region_sums_from_segments(seg_y.numpy(), ra, s.shape, cuts_h)
    image = attach_shared(token, image_layout(s.n_pixels, s.n_bands))
    if image is None:
        return TileResult(p0, p1, spec_sum.numpy(), s1.numpy(), s2.numpy(), int(pass_hits.sum()), pass_hits,
                          region_y, time.perf_counter() - t0)
    _copy_to_host(image["spec"][p0 * s.n_bands:p1 * s.n_bands], spec_sum)
    _copy_to_host(image["xyz1"][p0:p1], s1)
    _copy_to_host(image["xyz2"][p0:p1], s2)
    _place_moments(image, p0, p1, passes, s.spp_per_pass)
    del image  # a worker process unmaps the run's segment when its views are gone
    return TileResult(p0, p1, None, None, None, int(pass_hits.sum()), pass_hits, region_y,
                      time.perf_counter() - t0, placed=True)


@dataclass(frozen=True)
class TileReduction:
    """Places :class:`TileResult` s into the image and adds their per-pass counts in tile order; finishes as
    :class:`RenderSums` whose ``pass_sum`` has the per-pass hits and region means (a
    :class:`lensrt.parallel.Reduction`). With a ``token`` each run makes the image as
    :class:`lensrt.parallel.shm.SharedArrays` of that name, which tiles fill in place (module docstring);
    a tile that returns its sums instead is placed here, its XYZ mean and standard error computed as it
    is placed (element by element: the bits of the whole-image computation), so that the end of the
    job, which no device overlaps, only wraps the arrays."""

    n_pixels: int
    n_bands: int
    shape: tuple[int, int]
    spp_per_pass: int
    passes: int
    token: str | None = None

    def start(self) -> dict:
        layout = image_layout(self.n_pixels, self.n_bands)
        if self.token:
            from ..parallel.shm import SharedArrays
            shared = SharedArrays(self.token, layout)
            acc = dict(shared.arrays, shared=shared)
        else:
            acc = {name: np.zeros(shape, dtype=dt) for name, (shape, dt) in layout.items()}
        acc["pass_hits"] = np.zeros(self.passes, dtype=np.int64)
        acc["region_y"] = np.zeros((self.passes, len(REGIONS)))
        return acc

    def add(self, acc: dict, index: int, result: TileResult) -> dict:
        if not result.placed:
            acc["spec"][result.first * self.n_bands:result.end * self.n_bands] = result.spec_sum
            acc["xyz1"][result.first:result.end] = result.xyz1
            acc["xyz2"][result.first:result.end] = result.xyz2
            _place_moments(acc, result.first, result.end, self.passes, self.spp_per_pass)
        acc["pass_hits"] += result.pass_hits
        acc["region_y"] += result.region_y
        return acc

    def finish(self, acc: dict) -> RenderSums:
        if acc.get("shared") is not None:
            acc.pop("shared").release()  # the name goes; the arrays stay (they map the segment)
        ps = PassSum(self.n_pixels, self.n_bands, self.shape, self.spp_per_pass)
        ps.spec, ps.xyz1, ps.xyz2, ps.passes = acc["spec"], acc["xyz1"], acc["xyz2"], self.passes
        ps.pass_hits = [int(h) for h in acc["pass_hits"]]
        ps.hits = sum(ps.pass_hits)
        counts = np.array([(r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in region_slices(self.shape)], dtype=np.float64)
        ps.region_means = (acc["region_y"] / (counts * self.spp_per_pass)).tolist()
        return RenderSums(ps.spec, acc["xyz"].reshape(self.shape + (3,)), acc["stderr"].reshape(self.shape + (3,)),
                          ps.passes, ps.samples_per_pixel, ps.hits, ps)


def render_tiles_job(setup: RenderSetup, passes: int, tiles: int, in_place: bool = True):
    """The Job of ``passes`` passes of ``setup`` in ``tiles`` row bands (module docstring); ``in_place=False``:
    every tile returns its sums and the reduction places them (the path of a worker on another machine)."""
    from ..parallel import Job, make_items
    rows, cols = setup.shape
    n = max(1, min(int(tiles), rows))
    bounds = [rows * t // n * cols for t in range(n + 1)]
    token = f"lensrt-img-{uuid.uuid4().hex[:16]}" if in_place else None
    items = make_items([(bounds[t], bounds[t + 1], int(passes), token) for t in range(n)], setup.seed,
                       costs=[float(bounds[t + 1] - bounds[t]) for t in range(n)])
    red = TileReduction(setup.n_pixels, setup.n_bands, setup.shape, setup.spp_per_pass, int(passes), token)
    return Job(items, run_tile_item, red, context=setup, prepare=prepare_setup, name=f"render-tiles-{setup.scene.name}")


#: workload sizes: scene, image width, samples per pixel per pass, passes, tiles (0: one item per pass,
#: each returning the whole image -- the host reduction then grows with the passes). "large" keeps one
#: H100 busy for seconds (1920 x 1080 x 512 paths per pixel: 2.8 s measured, 1.1e9 paths).
#: ``in_place=0``: tiles return their sums to the reduction instead of writing the image in place (the path
#: before in-place writes, kept for comparison and for workers on other machines).
WORKLOAD_SIZES = {
    "tiny": {"scene": "default", "width": 64, "spp_per_pass": 2, "passes": 4, "tiles": 4, "in_place": 1},
    "small": {"scene": "still_life_mesh", "width": 480, "spp_per_pass": 8, "passes": 8, "tiles": 8, "in_place": 1},
    "large": {"scene": "still_life_mesh", "width": 1920, "spp_per_pass": 8, "passes": 64, "tiles": 16,
              "in_place": 1},
}


def render_workload(size: str, seed: int):
    """Workload factory for ``benchmarks/bench_multigpu.py --workload render`` (sizes: :data:`WORKLOAD_SIZES`,
    or ``scene=...,width=...,spp_per_pass=...,passes=...,tiles=...,in_place=0|1``). The set-up (focus,
    exit-pupil table) runs here, on the first device Warp sees."""
    from ..parallel.workloads import parse_size
    from .setup import RenderOptions, prepare_render
    from .scene.load import load_scene
    p = parse_size(size, WORKLOAD_SIZES)
    scene = load_scene(p["scene"])
    opts = RenderOptions(width=int(p["width"]), spp_per_pass=int(p["spp_per_pass"]),
                         samples_per_pixel=int(p["spp_per_pass"]) * int(p["passes"]), seed=int(seed))
    setup, _ = prepare_render(scene, None, opts)
    if int(p["tiles"]) > 0:
        return render_tiles_job(setup, int(p["passes"]), int(p["tiles"]), in_place=bool(p["in_place"]))
    return render_job(setup, int(p["passes"]))
