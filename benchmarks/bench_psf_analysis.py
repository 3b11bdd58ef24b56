"""PSF-map analysis speed: the per-field reference against the passes over all fields at once (bulk).

Usage (from the repository root)::

    python benchmarks/bench_psf_analysis.py --device cpu --grid 9 --rays 1e5
    python benchmarks/bench_psf_analysis.py --device cuda            # 9x9 fields, 1e7 rays each

Traces the map of ``benchmarks/bench_psf.py`` once (``dgauss_50mm_f2``, its three wavelengths,
full-frame sensor, 128^2 px, 32 batches; the stream launch as ``lensrt psf --grid`` makes it) and
keeps every field's per-batch histograms; then times, in one thread, the host analysis of all fields
two ways, ``--repeat`` times each, alternating, and prints the least wall and CPU seconds:

* **per-field reference** -- ``geometric_psf`` and ``add_mtf_estimates`` without ``sums``: every pass
  over a field's histograms made field by field (the analysis before ``lensrt.analysis.psf.bulk``);
* **bulk** -- ``bulk.field_sums`` over runs of ``FIELDS_PER_PASS`` fields, then the same two calls
  with each field's sums (what a map runs on the CPU, less its analysis threads);
* **device sums** -- ``device_sums.device_field_sums`` over all fields at once, on ``--device`` (the
  histograms uploaded there once beforehand, as the stream leaves them: int64, untimed), then the same
  two calls with each field's sums (what a map runs on a GPU, less its analysis threads).

It also prints the largest relative difference between the two over every estimate (values and
standard errors) and the PSFs' per-pixel errors.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    p.add_argument("--grid", type=int, default=9, help="fields per side (default 9)")
    p.add_argument("--rays", type=float, default=None, help="rays per field (default 1e7 on CUDA, 1e5 on the CPU)")
    p.add_argument("--repeat", type=int, default=3, help="timed runs of each way (least shown; default 3)")
    args = p.parse_args(argv)

    from lensrt.analysis.fields import sensor_grid_fields
    from lensrt.analysis.psf import bulk, geometric, groups
    from lensrt.analysis.psf.map import field_seeds
    from lensrt.analysis.psf.result import geometric_psf
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.device import describe_device, resolve_device, warp
    from lensrt.loading import load_lens

    warp().config.log_level = warp().LOG_WARNING
    dev = resolve_device(args.device)
    rays = int(args.rays or (1e7 if dev.startswith("cuda") else 1e5))
    lens = load_lens("dgauss_50mm_f2")
    setup = make_setup(lens, None, "image", dev, rays=rays, pixels=128)
    fields = sensor_grid_fields(lens, "full-frame", (args.grid, args.grid), setup.plane_z_mm, dev)
    # the map, keeping each field's traced totals as finish_geometric receives them
    kept: list = []
    finish = geometric.finish_geometric

    def keep(setup_, f, seed, geom, grid, half, tot, *rest, **kw):
        kept.append((grid, geom.reference_mm, tot))
        return finish(setup_, f, seed, geom, grid, half, tot, *rest, **kw)
    geometric.finish_geometric = keep
    # the host path of the map, whatever LENSRT_PSF_ANALYSIS says: the per-batch histograms must come down
    # to the host for the reference and bulk ways (the device path keeps them on the device and hands
    # finish_geometric zero stand-ins, which the reference cannot analyse)
    mode = os.environ.get("LENSRT_PSF_ANALYSIS")
    os.environ["LENSRT_PSF_ANALYSIS"] = "host"
    try:
        groups.geometric_psfs(setup, fields, field_seeds(len(fields), 0), dev)
    finally:
        geometric.finish_geometric = finish
        if mode is None:
            del os.environ["LENSRT_PSF_ANALYSIS"]
        else:
            os.environ["LENSRT_PSF_ANALYSIS"] = mode
    stack = np.stack([t.hist for _, _, t in kept])
    offs = np.stack([t.off_grid for _, _, t in kept])

    def one(grid, ref, tot, sums=None):
        r = geometric_psf(tot.hist, grid, moment_sums=tot.moments, off_grid=tot.off_grid, reference_mm=ref,
                          ee_fractions=setup.ee_fractions, sums=sums)
        geometric.add_mtf_estimates(r, tot.hist, setup.mtf_freqs_cpmm, setup.mtf_curve_cpmm, sums=sums)
        return r

    def reference() -> list:
        return [one(*k) for k in kept]

    def batched() -> list:
        out, n = [], bulk.FIELDS_PER_PASS
        for a in range(0, len(kept), n):
            part = kept[a:a + n]
            sums = bulk.field_sums(stack[a:a + n], offs[a:a + n], [k[0] for k in part], [k[1] for k in part], setup)
            out += [one(*k, sums=s) for k, s in zip(part, sums)]
        return out

    # the histograms as the stream leaves them on the device: int64 fixed point, (fields, batches, 1, ny, nx),
    # rows bottom-up
    from lensrt.analysis.psf.device_sums import DeviceHistograms, device_field_sums
    from lensrt.trace.kernels import FIXED_POINT_BITS
    unit = 1.0 / float(2 ** FIXED_POINT_BITS)
    fixed = np.ascontiguousarray(np.rint(stack[:, :, None, ::-1, :] / unit).astype(np.int64))
    dh = DeviceHistograms(warp().array(fixed.ravel(), dtype=warp().int64, device=dev), range(len(kept)),
                          stack.shape[1], 1, stack.shape[2], stack.shape[3], unit, dev)
    shape = bulk.shape_only(*stack.shape[1:])

    def on_device() -> list:
        sums = device_field_sums(dh, range(len(kept)), offs, [k[0] for k in kept], [k[1] for k in kept], setup)
        return [one(g, ref, type(tot)(shape, tot.moments, tot.off_grid), sums=s)
                for (g, ref, tot), s in zip(kept, sums)]

    ways = (("per-field reference", reference), ("bulk", batched), ("device sums", on_device))
    times: dict[str, list] = {name: [] for name, _ in ways}
    on_device()  # kernels loaded (compiled on first use)
    for _ in range(max(1, args.repeat)):
        for name, fn in ways:
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times[name].append((time.perf_counter() - t0, time.process_time() - c0))
    worst = {"bulk": 0.0, "device sums": 0.0}
    for a, b, c in zip(reference(), batched(), on_device()):
        for name, new in (("bulk", b), ("device sums", c)):
            for k, e in a.estimates.items():
                for part in ("value", "stderr"):
                    u, v = np.asarray(getattr(e, part), float), np.asarray(getattr(new.estimates[k], part), float)
                    worst[name] = max(worst[name], float(np.max(np.abs(u - v) / np.maximum(np.abs(u), 1e-300),
                                                                initial=0.0)))
            worst[name] = max(worst[name], float(np.max(np.abs(a.psf_stderr - new.psf_stderr)) / np.max(a.psf_stderr)))
    print(f"{describe_device(dev)}; {len(kept)} fields, {rays:.3g} rays each, 128^2 px, {setup.batches} batches; "
          f"analysis in one thread, least of {args.repeat}")
    for name, ts in times.items():
        w, c = min(t[0] for t in ts), min(t[1] for t in ts)
        print(f"  {name:20s} wall {w:.3f} s  CPU {c:.3f} s  ({1e3 * w / len(kept):.1f} ms per field)")
    print("  largest relative difference from the reference, every estimate and per-pixel error: "
          + ", ".join(f"{k} {v:.2g}" for k, v in worst.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
