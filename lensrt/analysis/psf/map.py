"""PSF maps as a parallel job: work items are groups of field points, reduced in field order.

:func:`psf_map_job` builds a :class:`lensrt.parallel.Job` whose context is the
shared :class:`~lensrt.analysis.psf.setup.PsfSetup` and whose items are groups of
field points (:class:`~lensrt.analysis.fields.FieldSpec`): on one device one group
holds every field (one batched set-up, one stream launch:
:mod:`lensrt.analysis.psf.groups`); for several devices or workers the fields are
split into groups (``groups``). Each field's PSF is seeded by the seed of its field
index -- a function of (job seed, field index) only, the seed a one-field item of
that index would have -- and a group gives each field exactly the rays, sums and
analysis it would get alone, so the map is bit-identical whatever the grouping, in
one thread, one thread per GPU, or on a Dask cluster (tested on CPU threads).
:func:`psf_at` is the per-field dispatcher (geometric, diffraction, or ``auto``'s
choice, see :mod:`lensrt.analysis.psf.diffraction`); ``auto``/``diffraction`` and progressive
maps run field by field inside each group.

The benchmark workload ``"psf-map"`` (:func:`psf_map_workload`) is registered
in :mod:`lensrt.parallel.workloads`; its reduction keeps only the arrays and
values that must be bit-identical (no timings).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ...errors import LensrtError
from ...parallel.work import Job, WorkItem, make_items
from ..fields import FieldSpec
from .result import PsfResult
from .setup import PsfSetup

if TYPE_CHECKING:
    from .geometric import FieldGeometry

__all__ = ["PsfMap", "psf_at", "psf_map_job", "run_psf_item", "run_psf_group", "prepare_psf", "collect_map",
           "map_arrays", "psf_map_workload", "run_psf_map", "default_groups", "field_seeds", "WORKLOAD_PRESETS"]


def psf_at(setup: PsfSetup, f: FieldSpec, seed: int, device: str | None = None,
           geom: FieldGeometry | None = None, chief=None) -> PsfResult:
    """The PSF of one field point by ``setup.method`` (``auto``: per the rules of :mod:`.diffpsf`);
    ``geom``, ``chief``: the field's :func:`~lensrt.analysis.psf.geometric.prepare_fields` geometry and
    :func:`~lensrt.analysis.pupil_rays.chief_rays_at_many` entry when already found."""
    from .geometric import geometric_psf_at, prepare_field
    if setup.method == "geometric":
        return geometric_psf_at(setup, f, seed, device, geom)
    from .diffraction import WavefrontSet, choose_method, diffraction_psf_at
    t0 = time.perf_counter()
    geom = prepare_field(setup, f, device) if geom is None else geom
    wset = WavefrontSet(setup, geom, device, chief)
    method, reason = choose_method(setup, wset)
    if method == "geometric":
        res = geometric_psf_at(setup, f, seed, device, geom, reason=reason)
        res.metadata["auto_seconds"] = time.perf_counter() - t0 - res.seconds
        return res
    return diffraction_psf_at(setup, f, device, geom, wset, method, reason)


def prepare_psf(setup: PsfSetup, device: str) -> PsfSetup:
    """Per (process, device): load the stream kernels of the setup's precision once (compile/cache)."""
    from ...trace.kernels import get_kernels
    if setup.method != "diffraction":
        get_kernels(setup.precision)
    get_kernels("float64")
    return setup


def field_seeds(n: int, seed: int) -> list[int]:
    """The seed of each field index 0 .. n-1 of a map seeded ``seed`` (that of a one-field work item)."""
    return [it.seed for it in make_items(range(n), int(seed))]


def run_psf_group(setup: PsfSetup, fields: Sequence[FieldSpec], seeds: Sequence[int],
                  device: str | None = None) -> list[PsfResult]:
    """The PSFs of a group of fields: batched (:func:`~lensrt.analysis.psf.groups.geometric_psfs`) for
    geometric maps, field by field otherwise."""
    if setup.method == "geometric":
        from .groups import geometric_psfs
        return geometric_psfs(setup, fields, seeds, device)
    from ..pupil_rays import chief_rays_at_many
    from .diffraction import wavefront_chief_wavelengths
    from .geometric import prepare_fields
    # the pupil boxes and chief rays of every field in one batched search, and the wavefronts' chief rays
    # at every wavelength in another (the same as field by field)
    geoms = prepare_fields(setup, list(fields), device)
    chiefs = chief_rays_at_many(setup.lens, [g.fp for g in geoms], wavefront_chief_wavelengths(setup),
                                setup.plane_z_mm, device)
    if setup.method != "auto":
        return [psf_at(setup, f, int(s), device, g, c) for f, s, g, c in zip(fields, seeds, geoms, chiefs)]
    from .auto import auto_psfs
    return auto_psfs(setup, list(fields), [int(s) for s in seeds], device, geoms, chiefs)


def run_psf_item(item: WorkItem, setup: PsfSetup, device: str) -> PsfResult | list[PsfResult]:
    """``run`` of the PSF-map job: a group ``item.params = [(field index, FieldSpec, seed), ...]`` gives
    its list of PSFs; a single FieldSpec (a one-field item) its PSF with seed ``item.seed``."""
    if isinstance(item.params, FieldSpec):
        return psf_at(setup, item.params, item.seed, device)
    fields = [f for _, f, _ in item.params]
    return run_psf_group(setup, fields, [s for _, _, s in item.params], device)


def _flat(results: list) -> list[PsfResult]:
    out: list[PsfResult] = []
    for r in results:
        out.extend(r if isinstance(r, list) else [r])
    return out


@dataclass
class PsfMap:
    """The PSFs of a run, in field order, with how they were made."""

    setup: PsfSetup
    fields: list[FieldSpec]
    results: list[PsfResult]
    seed: int
    grid_shape: tuple[int, int] | None = None
    sensor: str | None = None
    run: dict = field(default_factory=dict)

    @property
    def seconds(self) -> float:
        return float(self.run.get("seconds", sum(r.seconds for r in self.results)))

    @property
    def rays(self) -> int:
        return int(sum(r.samples for r in self.results))

    def to_dict(self) -> dict:
        out = {"lens": self.setup.lens.name, "setup": self.setup.to_dict(), "seed": self.seed,
               "sensor": self.sensor, "grid": list(self.grid_shape) if self.grid_shape else None,
               "rays_total": self.rays, "seconds": self.seconds, "run": self.run,
               "fields": []}
        for f, r in zip(self.fields, self.results):
            d = r.to_dict()
            d["field_spec"] = f.to_dict()
            out["fields"].append(d)
        return out


def collect_map(results: list) -> list[PsfResult]:
    """Reduction of the CLI's job: the results in field order (groups flattened)."""
    return _flat(results)


def map_arrays(results: list[PsfResult]) -> dict[str, np.ndarray]:
    """Reduction of the benchmark workload: the deterministic part of the map (no timings).

    ``psf`` (n, rows, cols) float64, ``estimates`` (n, k) values of the scalar estimates and
    their standard errors, ``reference_mm`` (n, 2).
    """
    results = _flat(results)
    keys = sorted(k for k, e in results[0].estimates.items() if np.ndim(e.value) == 0)
    est = np.array([[float(r.estimates[k].value) for k in keys] + [float(r.estimates[k].stderr) for k in keys]
                    for r in results])
    shapes = {r.psf.shape for r in results}
    psf = np.stack([r.psf for r in results]) if len(shapes) == 1 else np.array([], dtype=np.float64)
    return {"psf": psf, "estimates": est, "reference_mm": np.array([r.reference_mm for r in results]),
            "samples": np.array([r.samples for r in results], dtype=np.int64)}


def psf_map_job(setup: PsfSetup, fields: Sequence[FieldSpec], seed: int = 0, name: str = "psf-map",
                reduce: Any = None, groups: int = 1) -> Job:
    """A :class:`~lensrt.parallel.Job` whose items are ``groups`` groups of consecutive field points
    (module docstring); the value is the same whatever ``groups``."""
    if not fields:
        raise LensrtError("a PSF map needs at least one field point")
    fields = list(fields)
    seeds = field_seeds(len(fields), seed)
    n = max(1, min(int(groups), len(fields)))
    bounds = [len(fields) * g // n for g in range(n + 1)]
    params = [[(k, fields[k], seeds[k]) for k in range(bounds[g], bounds[g + 1])] for g in range(n)]
    items = make_items(params, int(seed), costs=[float(len(p)) for p in params])
    return Job(items, run_psf_item, reduce or collect_map, context=setup, prepare=prepare_psf, name=name,
               uses_device=True)


def default_groups(executor: Any, n_fields: int) -> int:
    """Groups for a map on ``executor``: one per device slot is the fewest launches, four per slot
    keep every device busy to the end (items differ in cost); one on a single device."""
    slots = len(getattr(executor, "devices", [None]) or [None])
    if callable(getattr(executor, "n_workers", None)):
        slots = max(slots, int(executor.n_workers()))
    return 1 if slots <= 1 else min(n_fields, 4 * slots)


def run_psf_map(setup: PsfSetup, fields: Sequence[FieldSpec], seed: int = 0, executor: Any = None,
                progress: Any = None, grid_shape: tuple[int, int] | None = None,
                sensor: str | None = None, groups: int | None = None) -> PsfMap:
    """Run the map on ``executor`` (default: this process, one thread on the default device), in
    ``groups`` work items (default: :func:`default_groups`)."""
    if executor is None:
        from ...parallel.local import LocalExecutor
        with LocalExecutor(None) as ex:
            job = psf_map_job(setup, fields, seed, groups=groups or default_groups(ex, len(fields)))
            res = ex.run(job, progress=progress)
    else:
        job = psf_map_job(setup, fields, seed, groups=groups or default_groups(executor, len(fields)))
        res = executor.run(job, progress=progress)
    return PsfMap(setup, list(fields), list(res.value), int(seed), grid_shape, sensor, res.summary())


#: sizes of the benchmark workload (``--size``): key=value pairs override the "tiny" preset; ``groups``
#: work items (groups of fields; the map is the same bits for any number). "large" keeps one H100
#: busy for about 7.6 s (8.1e10 rays at 1.07e10 rays/s): 9.5 s in all on one H100, the rest host
#: set-up and analysis (benchmarks/results/bench_multigpu_1gpu_h100.txt).
WORKLOAD_PRESETS: dict[str, dict] = {
    "tiny": {"lens": "dgauss_50mm_f2", "grid": 3, "rays": 1 << 14, "wavelengths": 1, "pixels": 32,
             "sensor": "full-frame", "precision": "float32", "sampler": "sobol", "groups": 3},
    "small": {"lens": "dgauss_50mm_f2", "grid": 5, "rays": 1_000_000, "wavelengths": 3, "pixels": 64,
              "sensor": "full-frame", "precision": "float32", "sampler": "sobol", "groups": 5},
    "large": {"lens": "dgauss_50mm_f2", "grid": 9, "rays": 1_000_000_000, "wavelengths": 3, "pixels": 128,
              "sensor": "full-frame", "precision": "float32", "sampler": "sobol", "groups": 18},
}


def workload_setup(params: dict, device: str | None = "cpu") -> tuple[PsfSetup, list[FieldSpec]]:
    """The setup and field list of a workload preset (the lens's focus plane; a grid over the sensor)."""
    from ...loading import load_lens
    from ..fields import sensor_grid_fields
    from .setup import make_setup
    from .spectrum import lens_spectrum, line_spectrum
    lens = load_lens(params["lens"])
    spec = lens_spectrum(lens) if int(params["wavelengths"]) >= len(lens.wavelengths.nm) \
        else line_spectrum([lens.wavelengths.primary_nm])
    setup = make_setup(lens, spec, "image", device, rays=int(params["rays"]), pixels=int(params["pixels"]),
                       precision=params["precision"], sampler=params["sampler"])
    g = int(params["grid"])
    fields = sensor_grid_fields(lens, params["sensor"], (g, g), setup.plane_z_mm, device)
    return setup, fields


def psf_map_workload(size: str, seed: int) -> Job:
    """Workload factory for ``benchmarks/bench_multigpu.py --workload psf-map`` (sizes: :data:`WORKLOAD_PRESETS`).

    Host set-up (field mapping) runs on the CPU; the items run on whatever device the executor gives them.
    """
    from ...parallel.workloads import parse_size
    params = parse_size(size, WORKLOAD_PRESETS)
    setup, fields = workload_setup(params, "cpu")
    return psf_map_job(setup, fields, seed, name="psf-map", reduce=map_arrays, groups=int(params["groups"]))
