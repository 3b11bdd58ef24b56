"""Tracing rays: the Python side of the *store* kernel, and rays named by field and pupil.

>>> from lensrt import load_lens
>>> from lensrt.trace import trace, rays_from_pupil
>>> lens = load_lens("codev_dblgauss_100mm_f2")
>>> rays = rays_from_pupil(lens, hx=0, hy=1, px=0, py=[-1, 0, 1], aim="real")
>>> result = trace(lens, rays, precision="float64", device="cpu")
>>> result.counts["OK"]
3

``device=None`` means CUDA when Warp sees a GPU, else the CPU
(:func:`lensrt.device.resolve_device`; asking for CUDA where there is none is an
error, never a silent switch). Kernels compile once per precision and device;
lens packing is cached per (lens, precision, device).
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Iris, Lens
from .aiming import AIM_MODES, aim_many, field_point, pupil_geometry
from .kernels import RAY_IN_COLS, RAY_OUT_COLS, get_kernels, lens_variant
from .pack import pack_lens
from .status import GRAZING_COS, OK, count_statuses
from .specialised import DEFAULT_TUNING, GPU_TUNING, ready, store_kernel
from .kernels import N_RECORD
from .variants import choose_kernel, params, shape_and_constants
from ..core.telemetry import download, launch, upload

__all__ = ["RayBatch", "RayResult", "trace", "rays_from_pupil", "make_rays", "kernel_to_stop", "chief_ray"]


@dataclass
class RayBatch:
    """Rays to trace: origins (n, 3) mm in the lens frame, direction cosines (n, 3), wavelengths (n,) nm.

    ``aimed`` is False for rays whose iterated aiming did not converge.
    """

    origin_mm: np.ndarray
    direction: np.ndarray
    wavelength_nm: np.ndarray
    aimed: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.origin_mm = np.atleast_2d(np.asarray(self.origin_mm, dtype=np.float64))
        self.direction = np.atleast_2d(np.asarray(self.direction, dtype=np.float64))
        n = len(self.origin_mm)
        self.wavelength_nm = np.broadcast_to(np.asarray(self.wavelength_nm, dtype=np.float64), (n,)).copy()
        if self.origin_mm.shape != (n, 3) or self.direction.shape != (n, 3):
            raise LensrtError("rays need origins and directions of shape (n, 3)")
        if self.aimed is None:
            self.aimed = np.ones(n, dtype=bool)

    def __len__(self) -> int:
        return len(self.origin_mm)


@dataclass
class RayResult:
    """End state of traced rays (numpy, float64 whatever the kernel precision).

    ``position_mm`` (n, 3) is in the lens frame (z from the first vertex): on the
    image surface for OK rays, else where the ray stopped. ``surface`` is the
    0-based surface where a ray failed (-1 when OK); :attr:`grazing` flags rays that met or left a
    surface beyond 80 deg (incidence or refraction). ``records`` (when asked)
    holds per surface met: x, y, z (sag, vertex frame), L, M, N after refraction,
    incidence and refraction angles (rad) and the segment length (mm).
    """

    position_mm: np.ndarray
    direction: np.ndarray
    opl_mm: np.ndarray
    status: np.ndarray
    surface: np.ndarray
    wavelength_nm: np.ndarray
    precision: str
    device: str
    seconds: float
    records: np.ndarray | None = None
    aimed: np.ndarray | None = field(default=None)
    #: smallest cos of the angles of incidence and refraction over the surfaces the ray refracted at
    min_cos_incidence: np.ndarray | None = None
    #: the kernel variant that ran ('generic' or 'specialised', see lensrt.trace.variants)
    kernel: str = "generic"

    @property
    def ok(self) -> np.ndarray:
        return self.status == OK

    @property
    def grazing(self) -> np.ndarray:
        """Rays that met or left some surface beyond GRAZING_INCIDENCE_DEG (ill-conditioned; see status.py)."""
        return self.min_cos_incidence < GRAZING_COS

    @property
    def counts(self) -> dict[str, int]:
        """Number of rays per status name."""
        return count_statuses(self.status)

    def __len__(self) -> int:
        return len(self.status)

    def part(self, start: int, stop: int) -> RayResult:
        """Rays ``start`` .. ``stop - 1`` (several batches traced together in one launch, split again)."""
        n = len(self)

        def cut(v):
            return v[start:stop] if isinstance(v, np.ndarray) and v.ndim and len(v) == n else v
        return replace(self, **{f.name: cut(getattr(self, f.name)) for f in fields(self)})


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


_PLACEHOLDERS: dict = {}


def _placeholder(device: str, real, ndim: int):
    """A zero array of one element per (device, dtype, ndim), shared by every call: the store kernels take
    an index table and a record array they only read (the table with row -1 never; records only with
    ``record=True``, which gets its own array), so none is allocated and cleared per call."""
    key = (device, real, ndim)
    arr = _PLACEHOLDERS.get(key)
    if arr is None:
        from ..device import warp
        wp = warp()
        arr = wp.zeros((1, 1, N_RECORD) if ndim == 3 else (1, 1), dtype=real, device=device)
        _PLACEHOLDERS[key] = arr
    return arr


def _check_wavelengths(wavelength_nm: np.ndarray) -> None:
    if not np.all(np.isfinite(wavelength_nm)) or np.any(wavelength_nm < 200.0) or np.any(wavelength_nm > 20000.0):
        raise LensrtError("ray wavelengths must lie within 200..20000 nm")


def trace(lens: Lens, rays: RayBatch, precision: str = "float64", device: str | None = None, *,
          clip: bool = True, end: int | None = None, record: bool = False, iris: Iris | None = None,
          stop_radius_mm: float | None = None, plane_z_mm: float | None = None,
          kernel: str = "auto") -> RayResult:
    """Trace ``rays`` through ``lens`` with the store kernel.

    Parameters
    ----------
    lens : Lens
        A complete lens (see :func:`lensrt.load_lens`).
    rays : RayBatch
        Origins, directions and wavelengths (nm).
    precision : {'float64', 'float32'}
    device : str, optional
        'cpu', 'cuda', 'cuda:N' or None (auto).
    clip : bool
        Apply clear semi-diameters and the iris.
    end : int, optional
        Stop on surface ``end`` (0-based) without refracting there (default: the image surface).
    record : bool
        Keep every surface's intersection (for ``lensrt ray``; memory grows with rays x surfaces).
    iris, stop_radius_mm : optional
        Override the lens's iris and stop radius (mm).
    plane_z_mm : float, optional
        Trace to the plane z = plane_z_mm instead of the image surface.
    kernel : {'auto', 'generic', 'specialised'}
        Kernel variant (:mod:`lensrt.trace.variants`; records and early ends run the generic one).
    """
    from ..device import warp
    wp = warp()
    packed = pack_lens(lens, precision, device, iris, stop_radius_mm)
    k = get_kernels(precision)
    dev = packed.device
    n_surf = lens.n_surfaces
    end = n_surf if end is None else int(end)
    if not 0 <= end <= n_surf:
        raise LensrtError(f"end surface {end} is not within 0..{n_surf}")
    _check_wavelengths(rays.wavelength_nm)
    n = len(rays)
    plane_dz = 0.0 if plane_z_mm is None else float(plane_z_mm) - lens.image_z_mm
    host = np.empty((n, RAY_IN_COLS))
    host[:, 0:3] = rays.origin_mm
    host[:, 3:6] = rays.direction
    host[:, 6] = rays.wavelength_nm
    real = k.real
    t0 = time.perf_counter()
    arr = upload(host, real, dev)
    out = wp.empty((n, RAY_OUT_COLS), dtype=real, device=dev)
    status = wp.empty(n, dtype=wp.int32, device=dev)
    surface = wp.empty(n, dtype=wp.int32, device=dev)
    rec = wp.zeros((n, end + 1, N_RECORD), dtype=real, device=dev) if record else _placeholder(dev, real, 3)
    table = _placeholder(dev, real, 2)
    shape, consts = shape_and_constants(packed, clip)
    variant = choose_kernel(kernel, dev, shape, n, possible=end == n_surf and not record)
    store, _, lens_arg = lens_variant(k, packed.general)
    if variant == "specialised":
        sk = store_kernel(precision, shape, GPU_TUNING[precision] if dev.startswith("cuda") else DEFAULT_TUNING)
        ready(sk, dev)
        common = [params(sk, consts, dev), arr, real(plane_dz), table]
    else:
        common = [packed.surf, packed.media, packed.iris, n_surf, arr, end, int(clip), real(plane_dz), int(record),
                  table]
    # on the CPU, large batches run as slices on the cores this process may use (no shared writes)
    workers = 1 if dev.startswith("cuda") or n < 4096 else _cpu_count()
    bounds = [n * w // workers for w in range(workers + 1)]

    def run(w: int) -> None:
        if bounds[w + 1] <= bounds[w]:
            return
        if variant == "specialised":
            launch(sk.kernel, dim=bounds[w + 1] - bounds[w], device=dev,
                   inputs=common + [bounds[w], out, status, surface], slice_of=bounds[w])
        else:
            launch(store, dim=bounds[w + 1] - bounds[w], device=dev,
                   inputs=common + [bounds[w], out, status, surface, rec, lens_arg], slice_of=bounds[w])

    if workers == 1:
        run(0)
    else:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run, range(workers)))
    o = download(out).astype(np.float64, copy=False)
    st = download(status).astype(np.int32, copy=False)
    sf = download(surface).astype(np.int32, copy=False)
    seconds = time.perf_counter() - t0
    vz = lens.vertex_z_mm()
    frame = np.where(st == OK, end, np.clip(sf, 0, n_surf))
    z = o[:, 2] + vz[frame] + np.where(frame == n_surf, plane_dz, 0.0)
    pos = np.stack([o[:, 0], o[:, 1], z], axis=1)
    records = download(rec).astype(np.float64) if record else None
    return RayResult(pos, o[:, 3:6], o[:, 6], st, sf, rays.wavelength_nm.copy(), precision, dev, seconds,
                     records, rays.aimed.copy() if rays.aimed is not None else None, o[:, 7], variant)


def kernel_to_stop(lens: Lens, device: str | None = None):
    """A :data:`~lensrt.trace.aiming.ToStop` on the float64 store kernel (fast aiming for many rays)."""
    stop = lens.stop_index

    def to_stop(origins: np.ndarray, directions: np.ndarray, wavelength_nm: np.ndarray):
        r = trace(lens, RayBatch(origins, directions, wavelength_nm), "float64", device, clip=False, end=stop)
        return r.position_mm[:, 0], r.position_mm[:, 1], r.ok

    return to_stop


def make_rays(lens: Lens, hx, hy, px, py, wavelength_nm=None, aim: str = "paraxial",
              device: str | None = None, aim_tracer: str = "kernel") -> RayBatch:
    """Rays named by normalised field (hx, hy) and pupil (px, py) coordinates (broadcast together).

    ``wavelength_nm`` defaults to the lens's primary wavelength. ``aim`` is one of
    :data:`~lensrt.trace.aiming.AIM_MODES`; iterated aiming traces to the stop with
    the float64 kernel (``aim_tracer="kernel"``) or the reference tracer ("reference").
    """
    if aim not in AIM_MODES:
        raise LensrtError(f"unknown ray aiming {aim!r}", hint=f"use one of {', '.join(AIM_MODES)}")
    wl0 = lens.wavelengths.primary_nm if wavelength_nm is None else wavelength_nm
    hx, hy, px, py, wl = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, dtype=np.float64))
                                              for v in (hx, hy, px, py, wl0)))
    hx, hy, px, py, wl = (a.ravel() for a in (hx, hy, px, py, wl))
    _check_wavelengths(wl)
    to_stop = None
    if aim != "paraxial":
        to_stop = kernel_to_stop(lens, device) if aim_tracer == "kernel" else None
    geom = pupil_geometry(lens)
    keys = np.stack([hx, hy], axis=1)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    fps = [field_point(lens, float(fx), float(fy)) for fx, fy in uniq]
    origin, direction, aimed = aim_many(lens, fps, np.asarray(inv).ravel(), px, py, wl, aim, to_stop, geom)
    return RayBatch(origin, direction, wl, aimed)


def rays_from_pupil(lens: Lens, hx=0.0, hy=0.0, px=0.0, py=0.0, wavelength_nm=None, aim: str = "paraxial",
                    device: str | None = None) -> RayBatch:
    """Alias of :func:`make_rays` with keyword defaults (the chief ray of the axial field)."""
    return make_rays(lens, hx, hy, px, py, wavelength_nm, aim, device)


def chief_ray(lens: Lens, hx: float, hy: float, wavelength_nm: float | None = None, precision: str = "float64",
              device: str | None = None) -> RayResult:
    """The real chief ray (through the centre of the real stop) of field (hx, hy), traced without clipping."""
    rays = make_rays(lens, hx, hy, 0.0, 0.0, wavelength_nm, "real", device)
    return trace(lens, rays, precision, device, clip=False)
