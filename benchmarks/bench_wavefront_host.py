"""Host time of pupil functions from traced wavefronts: rays triangulated by Delaunay (qhull) against along
their ray grid (``lensrt.analysis.wave.ray_mesh``).

Usage (from the repository root)::

    PYTHONPATH=. python benchmarks/bench_wavefront_host.py --device cpu
    PYTHONPATH=. python benchmarks/bench_wavefront_host.py --device cuda --repeat 5

Traces, once, the wavefronts of the report's MTF fields on the default lens (nine real image heights from
the centre to the corner of the full-frame sensor, best focus): at the primary wavelength with the
wavefront-error table's set-up (``lensrt report``'s "Wavefront error and Strehl ratio against field",
64 x 64 pupil cells), and at the lens's three lines with the MTF's (``--method diffraction``, 128 x 128).
Then times, in this thread, ``--repeat`` times each and alternating, the host work on them two ways:

* **delaunay** -- every ray set triangulated by qhull (``RayWavefront.grid_index`` dropped: the path
  before the ray grid was used);
* **grid** -- the traced wavefronts as they are: triangles cut from the ray grid, one point location
  shared by the aperture, the OPD and the amplitude.

``table`` is :func:`~lensrt.analysis.wave.metrics.wavefront_metrics` of the nine fields (what the report's
table computes after tracing), ``mtf pupils`` the pupil functions of the nine fields at three wavelengths
(what a diffraction MTF grids before its FFTs). Caches of triangulations are emptied before each run
(fresh copies of the wavefronts, which keep their ray mesh).
It prints the least wall and CPU seconds of each and the largest differences of the table's numbers.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def traced(device: str):
    """(table wavefronts, MTF wavefront sets) of the report's MTF fields on the default lens."""
    from lensrt.analysis.fields import image_height_fields
    from lensrt.analysis.psf.diffraction import wavefront_sets
    from lensrt.analysis.psf.focus import focus_plane
    from lensrt.analysis.psf.geometric import prepare_fields
    from lensrt.analysis.psf.setup import make_setup
    from lensrt.analysis.psf.spectrum import line_spectrum
    from lensrt.loading import load_lens
    from lensrt.paraxial.photographic import sensor_format
    from lensrt.report.options import ReportOptions
    lens = load_lens(None)
    foc = focus_plane(lens, "best", device)
    half = 0.5 * sensor_format(ReportOptions().sensor).diagonal_mm
    heights = [round(float(v), 3) for v in np.linspace(0.0, half, 9)]
    table = make_setup(lens, line_spectrum([lens.wavelengths.primary_nm]), foc, device, method="diffraction",
                       pupil_samples=64)
    mtf = make_setup(lens, None, foc, device, method="diffraction")
    out = []
    for setup in (table, mtf):
        fields = image_height_fields(lens, heights, setup.plane_z_mm, device)
        out.append(wavefront_sets(setup, prepare_fields(setup, fields, device), device))
    return [w.wavefronts[0] for w in out[0]], out[1]


def _fresh() -> None:
    from lensrt.analysis.wave.pupil_grid import TriLinear
    from lensrt.analysis.wave.ray_mesh import GridLinear
    TriLinear._recent.clear()
    GridLinear._recent.clear()


def _timed(fn) -> tuple[float, float, object]:
    _fresh()
    t, c = time.perf_counter(), time.process_time()
    got = fn()
    return time.perf_counter() - t, time.process_time() - c, got


def main(argv: list[str] | None = None) -> int:
    from lensrt.analysis.wave.metrics import wavefront_metrics
    from lensrt.analysis.wave.wavefront import pupil_function_from_wavefront
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    table, sets = traced(args.device)

    def delaunay(w):
        return dataclasses.replace(w, grid_m=0, grid_index=None)

    jobs = {
        "table": (lambda ws: [wavefront_metrics(w, n_terms=4, pupil_samples=64) for w in ws], table),
        "mtf pupils": (lambda ws: [pupil_function_from_wavefront(w, 128) for w in ws],
                       [w for s in sets for w in s.wavefronts]),
    }
    best: dict = {}
    results: dict = {}
    for _ in range(max(1, args.repeat)):
        for name, (fn, wfs) in jobs.items():
            # fresh copies each time: a wavefront keeps its ray mesh once built
            for path, ws in (("delaunay", [delaunay(w) for w in wfs]), ("grid", [dataclasses.replace(w) for w in wfs])):
                wall, cpu, got = _timed(lambda: fn(ws))
                key = (name, path)
                prev = best.get(key, (np.inf, np.inf))
                best[key] = (min(prev[0], wall), min(prev[1], cpu))
                results[key] = got
    print(f"host work on traced wavefronts (default lens, 9 fields), least of {args.repeat}; device {args.device}")
    print("| work | delaunay wall s | delaunay CPU s | grid wall s | grid CPU s | wall ratio |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in jobs:
        d, g = best[(name, "delaunay")], best[(name, "grid")]
        print(f"| {name} | {d[0]:.3f} | {d[1]:.3f} | {g[0]:.3f} | {g[1]:.3f} | {d[0] / g[0]:.1f} |")
    old, new = results[("table", "delaunay")], results[("table", "grid")]
    for key in ("rms_waves_no_tilt", "pv_waves", "strehl"):
        diff = max(abs(getattr(a, key) - getattr(b, key)) for a, b in zip(old, new))
        print(f"table {key}: largest |grid - delaunay| = {diff:.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
