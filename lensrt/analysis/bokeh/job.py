"""A bokeh image as a :class:`lensrt.parallel.Job`: items are chunks of sources, the reduction pastes windows.

Registered as the workload ``"bokeh-map"`` (:func:`bokeh_map_workload`) for
``benchmarks/bench_multigpu.py``. Each item traces its sources' pupil boxes and
streams them (:mod:`.bokeh_trace`) on its device and returns one window per
source; the reduction adds the windows into the frame in item and source order
(float64 on the host). Each source draws its own random numbers (seed, source index),
so the image is bit-identical for any number of devices or workers on the same kind
of device and for any chunking of the sources into items.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ...errors import LensrtError
from ...prescription.model import Iris, Lens
from .trace import Frame, pupil_boxes, stream_windows

__all__ = ["BokehSetup", "bokeh_job", "bokeh_map_workload", "WORKLOAD_PRESETS", "MIN_CELLS_ACROSS_PUPIL"]

#: a map's coarse pupil-box grid has at least this many cells across the paraxial entrance pupil (up to
#: 128 per side): a front element much wider than the pupil (wide angles, fisheyes) gets a finer grid
MIN_CELLS_ACROSS_PUPIL = 16


@dataclass(frozen=True)
class BokehSetup:
    """What every source of one bokeh image shares (the job's context; picklable).

    ``focus`` is a :class:`lensrt.analysis.bokeh.entry.Focus`; ``light`` a spectrum name
    (:data:`lensrt.analysis.bokeh.light.SPECTRUM_HELP`); ``iris``/``stop_radius_mm``
    override the lens's (None: the lens file's).
    """

    lens: Lens
    focus: object
    frame: Frame
    light: str = "D65"
    intensity_cd: float = 1.0
    iris: Iris | None = None
    stop_radius_mm: float | None = None
    rays_per_source: int = 1_000_000
    sampler: str = "sobol"
    batches: int = 32
    precision: str = "float32"
    batch_noise: bool = False
    #: pupil-box search grids (coarse, fine): maps use 64 x 64 (more, up to 128, when the front element
    #: is much wider than the pupil: 16 cells across it) then 48 x 48 rays per source (host work grows
    #: with them); :func:`lensrt.trace.stream.pupil_box` and spots use 128 and 64
    box_grid: tuple[int, int] = (64, 48)
    #: progressive: add rays until every source's disc noise (RMS relative standard error of Y) is at
    #: most this (``rays_per_source`` is then the cap)
    target_error: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.intensity_cd) and self.intensity_cd > 0):
            raise LensrtError(f"luminous intensity {self.intensity_cd!r} cd must be a positive number")

    def iris_used(self) -> Iris:
        return self.lens.iris if self.iris is None else self.iris

    def stop_radius_used(self) -> float:
        if self.stop_radius_mm is not None:
            return float(self.stop_radius_mm)
        return float(self.lens.surfaces[self.lens.stop_index].semi_diameter_mm)

    def settings(self) -> dict:
        """JSON-ready description (for metadata)."""
        from .light import bokeh_light
        iris = self.iris_used()
        return {"lens": self.lens.name, "lens_path": self.lens.path, "focus": self.focus.to_dict(),
                "light": bokeh_light(self.light, self.lens).to_dict(), "intensity_cd": self.intensity_cd,
                "iris": {"blades": iris.blades, "rotation_deg": math.degrees(iris.rotation_rad),
                         "roundness": iris.roundness},
                "stop_radius_mm": self.stop_radius_used(), "rays_per_source": self.rays_per_source,
                "sampler": self.sampler, "batches": self.batches, "precision": self.precision,
                "pixel_pitch_um": self.frame.pitch_mm * 1000.0, "pixels": [self.frame.nx, self.frame.ny],
                "pupil_box_grids": list(self.box_grid), "target_error": self.target_error,
                "emitter": "isotropic point source",
                "units": "CIE 1931 XYZ (2 deg); Y = illuminance on the sensor in lux"}


def _prepare(setup: BokehSetup, device: str) -> dict:
    from .light import bokeh_light
    return {"setup": setup, "light": bokeh_light(setup.light, setup.lens)}


def box_wavelengths(setup: BokehSetup, light) -> list[float]:
    """Wavelengths the pupil boxes are traced at: the spectrum's ends and the focus wavelength."""
    lo, hi = light.wavelength_range_nm
    wl = setup.focus.wavelength_nm
    mid = wl if lo <= wl <= hi else 0.5 * (lo + hi)
    return sorted({lo, mid, hi})


def _run(item, prepared: dict, device: str) -> dict:
    """One work item: a chunk of object points -> pupil boxes -> stream launches -> windows."""
    setup: BokehSetup = prepared["setup"]
    light = prepared["light"]
    obj = np.asarray(item.params["object_mm"], dtype=np.float64)
    t0 = time.perf_counter()
    boxes, foot = pupil_boxes(setup.lens, obj, box_wavelengths(setup, light), setup.focus.sensor_z_mm,
                              iris=setup.iris, stop_radius_mm=setup.stop_radius_mm, device=device,
                              coarse=setup.box_grid[0], fine=setup.box_grid[1],
                              min_cells_across_pupil=MIN_CELLS_ACROSS_PUPIL)
    t_box = time.perf_counter() - t0
    outs = stream_windows(setup.lens, obj, boxes, foot, setup.frame, setup.focus.sensor_z_mm, light,
                          setup.rays_per_source, intensity_cd=item.params["intensity_cd"], iris=setup.iris,
                          stop_radius_mm=setup.stop_radius_mm, sampler=setup.sampler, seed=int(item.params["seed"]),
                          batches=setup.batches, precision=setup.precision, device=device,
                          batch_noise=setup.batch_noise, target_error=setup.target_error,
                          source_ids=range(int(item.params["first"]), int(item.params["first"]) + len(obj)))
    return {"outs": outs, "first": int(item.params["first"]), "box_seconds": t_box,
            "seconds": time.perf_counter() - t0}


class _Paste:
    """The reduction: add each source's window into the frame, in item (and source) order."""

    def __init__(self, setup: BokehSetup, meta: list[dict]) -> None:
        self.setup, self.meta = setup, meta

    def start(self) -> dict:
        f = self.setup.frame
        return {"xyz": np.zeros((3, f.ny, f.nx)), "var": np.zeros((f.ny, f.nx)), "records": [],
                "box_seconds": 0.0, "item_seconds": 0.0}

    def add(self, acc: dict, index: int, result: dict) -> dict:
        f = self.setup.frame
        for o in result["outs"]:
            rec = dict(self.meta[result["first"] + o.index])
            rec.update(o.stats)
            acc["records"].append(rec)
            if o.xyz is None:
                continue
            wy, wx = o.xyz.shape[1:]
            y1, x1 = min(o.iy0 + wy, f.ny), min(o.ix0 + wx, f.nx)
            acc["xyz"][:, o.iy0:y1, o.ix0:x1] += o.xyz[:, :y1 - o.iy0, :x1 - o.ix0]
            acc["var"][o.iy0:y1, o.ix0:x1] += o.var_y[:y1 - o.iy0, :x1 - o.ix0]
        acc["box_seconds"] += result["box_seconds"]
        acc["item_seconds"] += result["seconds"]
        return acc

    def finish(self, acc: dict):
        from .image import BokehImage
        rays = sum(r.get("rays", 0) for r in acc["records"])
        return BokehImage(acc["xyz"], acc["var"], self.setup.frame, acc["records"], rays, 0.0,
                          self.setup.settings(), {"box_seconds": acc["box_seconds"],
                                                  "item_seconds": acc["item_seconds"]})


def bokeh_job(setup: BokehSetup, sources: Sequence[dict], seed: int = 0, sources_per_item: int = 32):
    """The :class:`lensrt.parallel.Job` that renders ``sources`` into ``setup.frame``.

    ``sources`` are dicts with at least ``object_mm`` (x, y, z in the lens frame) and optionally
    ``intensity_cd`` (default ``setup.intensity_cd``); every key is copied into the image's
    per-source record. Items are chunks of ``sources_per_item``
    sources in order. Every source draws its random numbers from (seed, its index in ``sources``)
    (:func:`lensrt.analysis.bokeh.trace.stream_windows`), so the image is the same bits for any
    ``sources_per_item`` and any number of devices or workers of one kind (fixed ray counts).
    """
    from ...parallel import Job, make_items
    from ...trace.pupil_boxes import coarse_grid
    if not sources:
        raise LensrtError("a bokeh image needs at least one source")
    n = max(1, int(sources_per_item))
    # one coarse pupil-box grid for all the sources, whatever items they fall in (the boxes do not depend on
    # the chunking)
    obj = np.array([s["object_mm"] for s in sources], dtype=np.float64)
    setup = replace(setup, box_grid=(coarse_grid(setup.lens, obj, setup.box_grid[0], MIN_CELLS_ACROSS_PUPIL),
                                     setup.box_grid[1]))
    params = [{"first": i, "seed": int(seed),
               "object_mm": [[float(v) for v in s["object_mm"]] for s in sources[i:i + n]],
               "intensity_cd": [float(s.get("intensity_cd", setup.intensity_cd)) for s in sources[i:i + n]]}
              for i in range(0, len(sources), n)]
    meta = [dict(s) for s in sources]
    return Job(make_items(params, int(seed)), _run, _Paste(setup, meta), context=setup, prepare=_prepare,
               name="bokeh-map")


#: workload sizes for benchmarks/bench_multigpu.py (key=value pairs override "tiny")
WORKLOAD_PRESETS = {
    "tiny": {"cols": 3, "rows": 2, "depths": 1, "pixels_x": 240, "rays": 20000, "focus_mm": 2000.0},
    "small": {"cols": 8, "rows": 5, "depths": 2, "pixels_x": 750, "rays": 1000000, "focus_mm": 2000.0},
    "large": {"cols": 15, "rows": 10, "depths": 3, "pixels_x": 1500, "rays": 10000000, "focus_mm": 2000.0},
}


def bokeh_map_workload(size: str, seed: int):
    """Workload factory ``(size, seed) -> Job``: a full-frame map of the default lens focused at 2 m,
    depths 1, 5 (and 20) m; sizes tiny / small / large or key=value (cols, rows, depths,
    pixels_x, rays, focus_mm)."""
    from ...loading import load_lens
    from ...parallel.workloads import parse_size
    from .focus import focus_lens
    from .image import sensor_frame
    from .sources import map_sources
    p = parse_size(size, WORKLOAD_PRESETS)
    lens = load_lens(None)
    focus = focus_lens(lens, p["focus_mm"])
    frame = sensor_frame((36.0, 24.0), (int(p["pixels_x"]), int(round(p["pixels_x"] * 24.0 / 36.0))))
    depths = [1000.0, 5000.0, 20000.0][:max(1, min(3, int(p["depths"])))]
    sources = map_sources(lens, focus, frame, (int(p["cols"]), int(p["rows"])), depths)
    setup = BokehSetup(lens, focus, frame, rays_per_source=int(p["rays"]))
    return bokeh_job(setup, sources, seed)
