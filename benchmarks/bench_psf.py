"""PSF-map speed: a grid of geometric PSFs over a sensor, 3 wavelengths, on the CPU or one GPU.

Usage (from the repository root)::

    python benchmarks/bench_psf.py --device cuda                  # the issue's case: 9x9, 1e7 rays, 3 wavelengths
    python benchmarks/bench_psf.py --device cpu --grid 3 --rays 1e6
    python benchmarks/bench_psf.py --device cuda --json > psf_bench.json

What it runs, on the 50 mm f/2 double Gauss of the library (``dgauss_50mm_f2``,
the lens file's three wavelengths 486/588/656 nm, its image surface) over a
full-frame sensor:

1. **map job** -- exactly what ``lensrt psf --grid 9x9`` runs on one device: the
   field mapping through the real chief ray done once before (timed on its own),
   then one work item holding every field (:mod:`lensrt.analysis.psf.groups`):
   batched set-up (real pupil boxes, chief rays, pilot rays for the grids), one
   stream launch of all fields (float32, Sobol', 32 batches with per-batch
   128 x 128 histograms, each field its own layer and bin size), and the host
   analysis (unit-volume PSF, jackknife standard errors of centroid, RMS,
   EE50/EE80 radii and the MTF at 10/20/40 lp/mm). Reported: wall time of the
   job; the **GPU time** of the stream launches ("kernel", CUDA events: the
   issue's "< 1 s of GPU time" for 8.1e8 rays); wall time of the host set-up and
   of the analysis (fields analysed side by side in threads);
2. **one field per item** -- the same map as 81 work items of one field each
   (the path before grouping, still what ``--groups 81`` gives): the same bits,
   the per-launch costs visible;
3. **stream only** -- every field as one source of a single stream call without
   per-batch histograms: the kernel time of the map's rays alone.

Timings exclude Warp kernel compilation (a warm-up runs first). Rays count every
ray launched (vignetted ones too). "wall s" of the map includes everything the
job does; kernel/set-up/analysis are its parts (they need not add up: the host
waits for the device while it copies results).
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lensrt.device import describe_device, resolve_device, warp  # noqa: E402
from lensrt.io.table import dumps_json, format_table  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    p.add_argument("--grid", type=int, default=None, help="fields per side (default 9 on CUDA, 3 on the CPU)")
    p.add_argument("--rays", type=float, default=None, help="rays per field (default 1e7 on CUDA, 1e6 on the CPU)")
    p.add_argument("--pixels", type=int, default=128, help="PSF grid pixels per side (default 128)")
    p.add_argument("--lens", default="dgauss_50mm_f2")
    p.add_argument("--sensor", default="full-frame")
    p.add_argument("--precision", default="float32", choices=["float32", "float64"])
    p.add_argument("--sampler", default="sobol", choices=["random", "stratified", "sobol", "r2"])
    p.add_argument("--repeat", type=int, default=2, help="timed runs (the best is shown; default 2)")
    p.add_argument("--skip-per-field", action="store_true", help="leave out the one-field-per-item run")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)

    wp = warp()
    wp.config.log_level = wp.LOG_WARNING
    from lensrt.analysis.fields import sensor_grid_fields
    from lensrt.analysis.psf.map import run_psf_map
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.loading import load_lens
    from lensrt.parallel.local import LocalExecutor
    from lensrt.trace.stream import Grid, StreamSource, stream

    dev = resolve_device(args.device)
    on_gpu = dev.startswith("cuda")
    g = args.grid or (9 if on_gpu else 3)
    rays = int(args.rays or (1e7 if on_gpu else 1e6))
    lens = load_lens(args.lens)
    setup = make_setup(lens, None, "image", dev, rays=rays, pixels=args.pixels, precision=args.precision,
                       sampler=args.sampler)
    from lensrt.analysis import fields as fields_mod
    t0 = time.perf_counter()
    fields = sensor_grid_fields(lens, args.sensor, (g, g), setup.plane_z_mm, dev)
    mapping_cold_s = time.perf_counter() - t0   # with the first use of the float64 kernels (compilation)
    fields_mod._table.cache_clear()
    t0 = time.perf_counter()
    fields = sensor_grid_fields(lens, args.sensor, (g, g), setup.plane_z_mm, dev)
    mapping_s = time.perf_counter() - t0

    # warm-up: compile / load the kernels, touch every code path once
    with LocalExecutor(dev) as ex:
        run_psf_map(setup.with_(rays=setup.batches * 256), fields[:2], 0, ex)

    def timed(groups: int) -> dict:
        best = None
        for _ in range(max(1, args.repeat)):
            with LocalExecutor(dev) as ex:
                t0 = time.perf_counter()
                pmap = run_psf_map(setup, fields, 0, ex, grid_shape=(g, g), sensor=args.sensor, groups=groups)
                wall = time.perf_counter() - t0
            if best is None or wall < best["wall_s"]:
                # per work item (group of fields): GPU time of its launches, wall time of its set-up and
                # of its analysis (fields analysed side by side in threads)
                items = {}
                for r in pmap.results:
                    items.setdefault(r.metadata.get("group_id"), r.metadata)
                md = list(items.values())
                best = {"wall_s": wall, "pmap": pmap,
                        "kernel_s": sum(m["group_kernel_seconds"] for m in md),
                        "setup_s": sum(m["group_setup_seconds"] for m in md),
                        "analysis_s": sum(m["group_analysis_seconds"] for m in md)}
        return best

    best = timed(1)
    per_field = timed(len(fields)) if not args.skip_per_field else None
    pmap = best["pmap"]
    if per_field is not None:
        from lensrt.analysis.psf.map import map_arrays
        a, b = map_arrays(pmap.results), map_arrays(per_field["pmap"].results)
        same = all(np.array_equal(a[k], b[k]) for k in a)
    else:
        same = None

    # stream only: all fields as sources of one stream call (kernel time of the whole map's rays)
    from lensrt.analysis.psf.geometric import prepare_fields
    geoms = prepare_fields(setup, fields, dev)
    sources = [StreamSource(gm.fp, gm.box, setup.plane_z_mm, gm.reference_mm, k, "lambertian",
                            pixel_mm=r.grid.pitch_mm) for k, (gm, r) in enumerate(zip(geoms, pmap.results))]
    sgrid = Grid(args.pixels, args.pixels, pmap.results[0].grid.pitch_mm)
    spec = setup.spectrum.trace_spectrum()
    stream(lens, sources[:1], sgrid, setup.batches * 256, spectrum=spec, sampler=args.sampler, seed=0,
           batches=setup.batches, precision=args.precision, device=dev)
    one = min((stream(lens, sources, sgrid, rays, spectrum=spec, sampler=args.sampler, seed=0,
                      batches=setup.batches, precision=args.precision, device=dev)
               for _ in range(max(1, args.repeat))), key=lambda r: r.extra["kernel_seconds"])

    n_rays = rays * len(fields)
    rms = [r.estimates["rms_radius_mm"] for r in pmap.results]

    def row(d: dict) -> dict:
        return {"wall_s": d["wall_s"], "kernel_s": d["kernel_s"], "setup_s": d["setup_s"],
                "analysis_s": d["analysis_s"],
                "kernel_rays_per_s": n_rays / d["kernel_s"], "wall_rays_per_s": n_rays / d["wall_s"]}

    out = {
        "device": describe_device(dev), "warp": wp.config.version, "platform": platform.platform(),
        "lens": lens.name, "grid": f"{g}x{g}", "sensor": args.sensor, "fields": len(fields), "rays_per_field": rays,
        "rays_total": n_rays, "wavelengths_nm": list(setup.spectrum.lines_nm), "pixels": args.pixels,
        "precision": args.precision, "sampler": args.sampler, "batches": setup.batches,
        "field_mapping_s": mapping_s, "field_mapping_first_call_s": mapping_cold_s, "map_job": row(best),
        "one_field_per_item": None if per_field is None else row(per_field),
        "same_bits_grouped_and_per_field": same,
        "stream_only": {"kernel_s": one.extra["kernel_seconds"], "wall_s": one.seconds,
                        "rays_per_s": one.rays_total / one.extra["kernel_seconds"], "launches": one.launches},
        "rms_radius_um": {"min": 1e3 * min(e.value for e in rms), "max": 1e3 * max(e.value for e in rms),
                          "max_relative_stderr": max(e.stderr / e.value for e in rms)},
    }
    if args.json:
        sys.stdout.write(dumps_json(out) + "\n")
        return 0
    print(f"{out['device']}, warp {out['warp']}; {lens.name}; {g}x{g} fields over {args.sensor}, {rays:.3g} rays each, "
          f"{len(setup.spectrum.lines_nm)} wavelengths, {args.pixels}^2 px, {args.precision}, {args.sampler}")
    rows = [[f"map job (lensrt psf --grid {g}x{g})"] + [out["map_job"][k] for k in
                                                        ("wall_s", "kernel_s", "setup_s", "analysis_s",
                                                         "kernel_rays_per_s", "wall_rays_per_s")]]
    if per_field is not None:
        rows.append(["one field per work item"] + [out["one_field_per_item"][k] for k in
                                                   ("wall_s", "kernel_s", "setup_s", "analysis_s",
                                                    "kernel_rays_per_s", "wall_rays_per_s")])
    rows.append(["stream only, one launch", one.seconds, one.extra["kernel_seconds"], 0.0, 0.0,
                 one.rays_total / one.extra["kernel_seconds"], one.rays_total / one.seconds])
    print(format_table(rows, ["run", "wall s", "GPU/kernel s", "set-up s", "analysis s", "kernel rays/s",
                              "wall rays/s"], digits=3))
    print(f"field mapping (chief-ray table, once per map): {mapping_s:.3g} s ({mapping_cold_s:.3g} s on first use, "
          f"kernel compilation included); grouped map and one field per item "
          f"give the same bits: {same}; RMS radius {out['rms_radius_um']['min']:.3g} .. "
          f"{out['rms_radius_um']['max']:.3g} um, largest relative standard error "
          f"{out['rms_radius_um']['max_relative_stderr']:.2g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
