"""Render passes: the picklable set-up of a render, its per-device preparation, one pass, and the reduction.

A render is a sequence of *passes*; pass ``p`` traces ``spp_per_pass`` camera paths through every
pixel with the Warp seed of work item ``p`` of the render's seed
(:func:`lensrt.parallel.item_seed_sequence`), so it is the same image whichever device or
worker runs it. Passes are summed in pass order in float64 (exact conversions of the float32
pass images, one rounding per addition), on the device in a one-device run and on the host when
passes come back from several devices (:class:`PassSum`): both give the same bits. The spread of
the per-pass XYZ images gives each pixel's standard error by batch means
(:func:`lensrt.stats.batch_means`); squares of float32 values are exact in float64, so these
sums are bit-identical too.

Everything here works for the camera-path integrator; :mod:`lensrt.render.splat` is the
light-side path of point-source scenes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..parallel.work import WARP_SEED_MASK, item_seed_sequence
from .camera import Camera
from .plan import Plan
from ..colour import cie_xyz_cmfs

__all__ = ["RenderSetup", "Prepared", "PassResult", "PassSum", "pass_seed", "prepare_setup", "render_pass",
           "run_pass_item", "device_pass", "RecordedPasses", "sensor_frame", "moments_stderr", "REGIONS"]

#: image regions whose mean Y (and its standard error) every render reports: (name, row0, row1, col0, col1)
#: as fractions of the image (the whole image first); the corners are 10 % x 10 % boxes
REGIONS = (("image", 0.0, 1.0, 0.0, 1.0), ("centre", 0.45, 0.55, 0.45, 0.55), ("top left", 0.0, 0.1, 0.0, 0.1),
           ("top right", 0.0, 0.1, 0.9, 1.0), ("bottom left", 0.9, 1.0, 0.0, 0.1),
           ("bottom right", 0.9, 1.0, 0.9, 1.0))


def pass_seed(seed: int, index: int) -> int:
    """Warp seed of pass ``index`` of a render seeded ``seed`` (the seed of work item ``index``)."""
    return int(item_seed_sequence(int(seed), int(index)).generate_state(1, dtype=np.uint32)[0]) & WARP_SEED_MASK


@dataclass(frozen=True, eq=False)
class RenderSetup:
    """Everything a device needs to render passes (picklable: no device arrays)."""

    scene: Any
    camera: Camera
    plan: Plan
    pupil_boxes: np.ndarray          # (bins, 4) exit-pupil table
    pupil_inv_dr: float
    wavelength_cdf: np.ndarray       # over the grid intervals (spectral) or [0, 1]
    band0_nm: float
    band_width_nm: float
    n_bands: int
    spp_per_pass: int
    seed: int
    window: tuple[int, int, int, int] | None = None   # (row0, row1, col0, col1) of the sensor's pixels

    @property
    def shape(self) -> tuple[int, int]:
        if self.window is None:
            return self.camera.sensor.shape
        r0, r1, c0, c1 = self.window
        return (r1 - r0, c1 - c0)

    def affine(self) -> tuple[float, float, float, float]:
        """The sensor map of :meth:`SensorGrid.affine`, shifted to the window's first row and column."""
        x0, dx, y0, dy = self.camera.sensor.affine()
        if self.window is None:
            return x0, dx, y0, dy
        return x0 + dx * self.window[2], dx, y0 + dy * self.window[0], dy

    @property
    def n_pixels(self) -> int:
        return self.shape[0] * self.shape[1]

    def band_centres_nm(self) -> np.ndarray:
        if not self.plan.spectral:
            return np.array([float(self.plan.wavelength_nm)])
        return self.band0_nm + (np.arange(self.n_bands) + 0.5) * self.band_width_nm


@dataclass
class Prepared:
    """A :class:`RenderSetup` on one device: the packed reversed lens and scene, the pupil boxes, the
    wavelength CDF and colour-matching functions as device arrays, and the kernels."""

    setup: RenderSetup
    device: str
    lens: Any            # PackedLens of the reversed lens (float32)
    scene: Any           # PackedScene (keeps the wp.Mesh alive)
    boxes: Any
    cdf: Any
    cmf: Any
    table: Any
    rec: Any
    kernels: Any
    frame: Any = None    # the camera kernel's sensor variant (CentredSensor, or TiltedSensor for a tilt-shift camera)


def prepare_setup(setup: RenderSetup, device: str) -> Prepared:
    """Pack the set-up for ``device`` (once per device; read-only afterwards)."""
    from ..device import warp
    from ..trace.pack import pack_lens
    from ..trace.reverse import reversed_lens
    from .integrator_kernels import get_render_kernels
    from .scene.pack import pack_scene
    wp = warp()
    cam = setup.camera
    rev = reversed_lens(cam.lens, 0.0)
    packed = pack_lens(rev, "float32", device, stop_radius_mm=cam.stop_radius_mm)
    scn = pack_scene(setup.scene, device)
    return Prepared(setup, device, packed, scn,
                    wp.array(setup.pupil_boxes.astype(np.float32), dtype=wp.vec4, device=device),
                    wp.array(setup.wavelength_cdf.astype(np.float32), dtype=float, device=device),
                    wp.array(cie_xyz_cmfs(setup.scene.grid).astype(np.float32), dtype=float, ndim=2, device=device),
                    wp.zeros((1, 1), dtype=float, device=device), wp.zeros((1, 1, 9), dtype=float, device=device),
                    get_render_kernels(), sensor_frame(cam))


def sensor_frame(camera: Camera):
    """The camera kernel's ``frame`` argument: ``CentredSensor`` for the plain camera, ``TiltedSensor`` (the moved
    lens's frame in the camera frame) for a tilt-shift camera."""
    from .integrator_kernels import CentredSensor, TiltedSensor
    if not camera.is_tilt_shift:
        return CentredSensor()
    from ..device import warp
    wp = warp()
    origin, rot = camera.lens_frame()
    f = TiltedSensor()
    f.origin = wp.vec3(*(float(v) for v in origin))
    f.rot = wp.mat33(*(float(v) for v in np.asarray(rot, dtype=np.float64).ravel()))
    f.sensor_z = float(camera.sensor_z_mm)
    f.z_last = float(camera.rear_vertex_z_mm)
    return f


@dataclass
class DevicePass:
    """One pass's device arrays: spectral sums (pixels * bands), XYZ sums (pixels), paths through the lens."""

    spec: Any
    xyz: Any
    hits: Any


def device_pass(prep: Prepared, index: int, out: DevicePass | None = None,
                pixels: tuple[int, int] | None = None) -> DevicePass:
    """Run pass ``index`` on ``prep.device`` into ``out`` (allocated when None), for every pixel or for the
    pixel range ``pixels`` = (first, end) (a tile: ``out`` holds that range only; its pixels are the same
    bits as in the whole image). The camera kernel adds each path into ``out.spec`` (zeroed here) and
    writes every pixel's ``xyz`` and ``hits`` (so a reused ``out`` needs no zeroing of those: one memset
    per pass instead of three)."""
    from ..device import warp
    from .pupil_table import launch_sliced
    wp = warp()
    s = prep.setup
    dev = prep.device
    p0, p1 = (0, s.n_pixels) if pixels is None else (int(pixels[0]), int(pixels[1]))
    n = p1 - p0
    if out is None:
        out = DevicePass(wp.zeros(n * s.n_bands, dtype=float, device=dev), wp.zeros(n, dtype=wp.vec3, device=dev),
                         wp.zeros(n, dtype=wp.int32, device=dev))
    else:
        out.spec.zero_()
    kernel, inputs_of = _camera_launch(prep, index, p0, out)
    launch_sliced(kernel, n, inputs_of, dev)
    return out


def _camera_launch(prep: Prepared, index: int, p0: int, out: DevicePass):
    """The camera kernel of ``prep`` and its inputs (a function of the slice's first thread id) for pass
    ``index`` of the pixels from ``p0`` on, into ``out``."""
    from ..units import LUMINOUS_EFFICACY_LM_PER_W
    s = prep.setup
    cam = s.camera
    ax0, ax1, ay0, ay1 = s.affine()
    plan = s.plan
    lam_fixed = float(plan.wavelength_nm) if not plan.spectral else 0.0
    inv_band = 1.0 / s.band_width_nm if plan.spectral else 1.0
    common = [prep.lens.surf, prep.lens.media, prep.lens.iris, cam.lens.n_surfaces, prep.table, prep.rec,
              float(cam.rear_vertex_z_mm - cam.sensor_z_mm), float(cam.rear_distance_mm),
              int(s.shape[1]), ax0, ax1, ay0, ay1, prep.boxes, float(s.pupil_inv_dr),
              int(s.pupil_boxes.shape[0]), prep.scene.data, int(plan.spectral), lam_fixed, prep.cdf,
              float(s.band0_nm), float(inv_band), int(s.n_bands), prep.cmf, float(LUMINOUS_EFFICACY_LM_PER_W),
              int(s.spp_per_pass), pass_seed(s.seed, index)]
    frame = prep.frame if prep.frame is not None else sensor_frame(cam)
    kernel = prep.kernels.camera_pass_tilted if cam.is_tilt_shift else prep.kernels.camera_pass
    return kernel, lambda base: common + [int(base) + p0, p0, out.spec, out.xyz, out.hits, frame]


class RecordedPasses:
    """Pass after pass of the camera kernel over the pixels [p0, p1) into one :class:`DevicePass`, its
    arguments packed once (Warp's recorded launches): a pass sets the seed, zeroes the spectral sums
    and replays the launch -- the bits of :func:`device_pass`, without packing some thirty arguments
    per pass under the interpreter lock (several device threads share it)."""

    def __init__(self, prep: Prepared, pixels: tuple[int, int]) -> None:
        from ..device import warp
        from .pupil_table import record_sliced
        wp = warp()
        s = prep.setup
        self.prep, p0 = prep, int(pixels[0])
        n = int(pixels[1]) - p0
        self.out = DevicePass(wp.zeros(n * s.n_bands, dtype=float, device=prep.device),
                              wp.zeros(n, dtype=wp.vec3, device=prep.device),
                              wp.zeros(n, dtype=wp.int32, device=prep.device))
        kernel, inputs_of = _camera_launch(prep, 0, p0, self.out)
        self.cmds = record_sliced(kernel, n, inputs_of, prep.device)

    def run(self, index: int) -> DevicePass:
        """Pass ``index`` into :attr:`out` (returned)."""
        from .pupil_table import replay_sliced
        self.out.spec.zero_()
        seed = pass_seed(self.prep.setup.seed, index)
        for _, cmd in self.cmds:
            cmd.set_param_by_name("seed", seed)
        replay_sliced(self.cmds)
        return self.out


@dataclass
class PassResult:
    """One pass on the host: float32 spectral sums (pixels * bands), XYZ sums (pixels, 3), paths through."""

    index: int
    spec: np.ndarray
    xyz: np.ndarray
    hits: int
    seconds: float = 0.0


def render_pass(prep: Prepared, index: int) -> PassResult:
    """Run pass ``index`` and bring it to the host."""
    import time
    t0 = time.perf_counter()
    dp = device_pass(prep, index)
    return PassResult(index, dp.spec.numpy(), dp.xyz.numpy().astype(np.float32),
                      int(dp.hits.numpy().astype(np.int64).sum()), time.perf_counter() - t0)


def run_pass_item(item, prep: Prepared, device: str) -> PassResult:
    """The ``run`` of a render Job: ``item.params`` is the global pass index."""
    return render_pass(prep, int(item.params))


@dataclass
class PassSum:
    """Sums over passes in pass order: float64 spectral sum, XYZ sums and sums of squares, region means.

    ``add_spec=False`` when the spectral sum is kept on the device (one-device runs)."""

    n_pixels: int
    n_bands: int
    shape: tuple[int, int]
    spp_per_pass: int
    spec: np.ndarray | None = None
    xyz1: np.ndarray = field(default=None)  # type: ignore[assignment]
    xyz2: np.ndarray = field(default=None)  # type: ignore[assignment]
    passes: int = 0
    hits: int = 0
    region_means: list = field(default_factory=list)   # per pass: Y mean per region
    pass_hits: list = field(default_factory=list)      # per pass: paths that got through the lens

    def __post_init__(self) -> None:
        self.xyz1 = np.zeros((self.n_pixels, 3))
        self.xyz2 = np.zeros((self.n_pixels, 3))

    def add(self, xyz: np.ndarray, hits: int, spec: np.ndarray | None = None) -> None:
        """Fold in one pass (XYZ sums of its paths per pixel, paths through the lens, spectral sums)."""
        x = np.asarray(xyz, dtype=np.float32).reshape(self.n_pixels, 3).astype(np.float64)
        self.xyz1 += x
        self.xyz2 += x * x          # squares of float32 values are exact in float64
        if spec is not None:
            s = np.asarray(spec, dtype=np.float32).reshape(-1).astype(np.float64)
            if self.spec is None:
                self.spec = s
            else:
                self.spec += s
        self.add_counts(x[:, 1], hits)

    def add_counts(self, y: np.ndarray, hits: int) -> None:
        """Count one pass whose per-pixel sums are kept elsewhere (on the device): its Y sums give the
        per-pass region means."""
        self.passes += 1
        self.hits += int(hits)
        self.pass_hits.append(int(hits))
        yy = np.asarray(y, dtype=np.float64).reshape(self.shape) / self.spp_per_pass
        self.region_means.append([float(yy[r0:r1, c0:c1].mean()) for r0, r1, c0, c1 in region_slices(self.shape)])

    @property
    def samples_per_pixel(self) -> int:
        return self.passes * self.spp_per_pass

    def xyz_mean(self) -> np.ndarray:
        """Per-pixel XYZ (rows, cols, 3): the mean over all paths."""
        return (self.xyz1 / max(self.samples_per_pixel, 1)).reshape(self.shape + (3,))

    def xyz_stderr(self) -> np.ndarray:
        """Per-pixel standard error of :meth:`xyz_mean` by batch means over passes (inf with one pass)."""
        return moments_stderr(self.xyz1, self.xyz2, self.passes, self.spp_per_pass).reshape(self.shape + (3,))


def moments_stderr(xyz1: np.ndarray, xyz2: np.ndarray, passes: int, spp_per_pass: int) -> np.ndarray:
    """Standard error of the mean per path from the sums over ``passes`` passes of the per-pass values
    (``xyz1``) and of their squares (``xyz2``), by batch means (inf with one pass). Element by element,
    so any split of the pixels gives the same bits."""
    p = int(passes)
    if p < 2:
        return np.full(np.shape(xyz1), np.inf)
    mean = xyz1 / p
    var = np.maximum(xyz2 - p * mean * mean, 0.0) / (p - 1)
    return np.sqrt(var / p) / spp_per_pass


def region_slices(shape: tuple[int, int]) -> list[tuple[int, int, int, int]]:
    """Pixel boxes (row0, row1, col0, col1) of :data:`REGIONS` for an image of ``shape`` (at least one pixel)."""
    rows, cols = shape
    out = []
    for _, a, b, c, d in REGIONS:
        r0 = min(int(a * rows), rows - 1)
        c0 = min(int(c * cols), cols - 1)
        out.append((r0, max(r0 + 1, int(round(b * rows))), c0, max(c0 + 1, int(round(d * cols)))))
    return out
