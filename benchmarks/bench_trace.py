"""Real-ray tracing speed: store and stream kernels, float32 and float64, CPU and GPU; optiland beside.

Usage (from the repository root)::

    python benchmarks/bench_trace.py                      # CPU (and the GPU when Warp sees one)
    python benchmarks/bench_trace.py --device cuda --rays 1e9
    python benchmarks/bench_trace.py --device cpu --rays 2e6 --scaling
    python benchmarks/bench_trace.py --device cuda --rays 1e9 --no-optiland --compare-generic --scaling
    python benchmarks/bench_trace.py --aot 90 --scaling   # compile the GPU modules ahead (no GPU needed)

What it measures, on the 50 mm f/2 double Gauss of the library (``dgauss_50mm_f2``; the
CODE V 100 mm double Gauss when that file is missing) with a 7-blade iris:

* stream: Monte Carlo rays generated in the kernel (Owen-scrambled Sobol' pupil
  samples over the real pupil box, per-ray wavelengths drawn from a continuous
  400-700 nm spectrum -- every medium's index computed per ray from its dispersion
  formula), traced and binned into a 256 x 256 PSF histogram, on axis and at full
  field; also with the lens file's three wavelengths (index table);
* store: one thread per ray, every ray's end state written (rays prepared on the host,
  timing of the kernel alone);
* optiland (when installed): its NumPy tracer on the same lens (the same geometry and
  indices), the same number of rays, in the same run on the same CPU;
* with ``--scaling``: rays/s against the number of rays and against the number of
  surfaces (3..30, a stack of weak singlets).

Rays per second count every ray launched (vignetted ones included). Timings exclude
kernel compilation (a warm-up with the same kernel variant runs first; on a GPU one
untimed full-size run first brings the clocks up). ``kernel`` says which variant ran
(``--kernel auto``: lens-specialised on GPUs, see ``lensrt.trace.variants``);
``--compare-generic`` adds the generic kernel's rows.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lensrt.device import describe_device, resolve_device, warp  # noqa: E402
from lensrt.io.table import format_table  # noqa: E402
from lensrt.loading import load_lens  # noqa: E402
from lensrt.prescription.materials import AIR, ConstantIndex  # noqa: E402
from lensrt.prescription.model import Aperture, Fields, Iris, Lens, Surface, Wavelengths  # noqa: E402
from lensrt.trace import specialised  # noqa: E402
from lensrt.trace.kernels import RAY_IN_COLS, get_kernels, lens_variant, module_names  # noqa: E402
from lensrt.trace.pack import pack_lens  # noqa: E402
from lensrt.trace.sampling import SAMPLERS, spectrum_continuous  # noqa: E402
from lensrt.trace.specialised import StreamOptions, store_kernel, stream_kernel  # noqa: E402
from lensrt.trace.stream import Grid, stream, stream_source  # noqa: E402
from lensrt.trace.surfaces import N_RECORD  # noqa: E402
from lensrt.trace.variants import choose_kernel, params, shape_and_constants  # noqa: E402


def bench_lens() -> Lens:
    try:
        lens = load_lens("dgauss_50mm_f2")
    except Exception:  # noqa: BLE001 - the library lens may not exist yet
        lens = load_lens(Path(__file__).resolve().parent.parent / "lens_prescriptions" /
                         "codev_dblgauss_100mm_f2.toml")
    return lens.replace(iris=Iris(blades=7, rotation_rad=math.radians(10.0)))


def stack_lens(n_surfaces: int) -> Lens:
    """n surfaces: weak biconvex singlets (R = +-400 mm, 2 mm of n = 1.6) 1 mm apart, stop first."""
    surfaces = [Surface(thickness_mm=1.0, is_stop=True, semi_diameter_mm=10.0)]
    glass = ConstantIndex(1.6)
    k = 1
    while len(surfaces) < n_surfaces:
        front = k % 2 == 1
        surfaces.append(Surface(curvature_per_mm=(1 / 400.0 if front else -1 / 400.0),
                                thickness_mm=2.0 if front else 1.0, material=glass if front else AIR,
                                semi_diameter_mm=20.0))
        k += 1
    last = surfaces[-1]
    surfaces[-1] = Surface(curvature_per_mm=last.curvature_per_mm, thickness_mm=50.0, material=AIR,
                           semi_diameter_mm=20.0)
    return Lens(tuple(surfaces), aperture=Aperture("float_by_stop", 0.0), fields=Fields("angle", (0.0, 0.1)),
                wavelengths=Wavelengths((550.0,)), iris=Iris(blades=7))


def time_stream(lens: Lens, rays: int, precision: str, device: str, hy: float, spectral: bool,
                sources_cache: dict, kernel: str = "auto") -> tuple[float, float, str]:
    """Seconds and rays/s of one stream run, after a warm-up with the same kernel variant."""
    key = (id(lens), hy)
    if key not in sources_cache:
        sources_cache[key] = stream_source(lens, 0.0, hy, device=device)
    src = sources_cache[key]
    spec = spectrum_continuous([400.0, 700.0], [1.0]) if spectral else None
    shape, _ = shape_and_constants(pack_lens(lens, precision, device))
    variant = choose_kernel(kernel, device, shape, int(rays))
    kw = dict(spectrum=spec, sampler="sobol", seed=1, precision=precision, device=device, kernel=variant)
    if (key, precision, spectral, variant) not in sources_cache:
        stream(lens, [src], Grid(256, 256, 0.002), 1 << 12, **kw)
        sources_cache[(key, precision, spectral, variant)] = True
    res = stream(lens, [src], Grid(256, 256, 0.002), int(rays), **kw)
    return res.seconds, res.rays_total / res.seconds, res.extra["kernel"]


def time_store(lens: Lens, rays: int, precision: str, device: str, kernel: str = "auto") -> tuple[float, float, str]:
    """Seconds and rays/s of the store kernel alone (rays prepared on the host, on the device)."""
    wp = warp()
    k = get_kernels(precision)
    packed = pack_lens(lens, precision, device)
    src = stream_source(lens, 0.0, 0.7, device=device)
    rng = np.random.default_rng(0)
    b = src.box
    a = rng.uniform(b.a0, b.a1, rays)
    c = rng.uniform(b.b0, b.b1, rays)
    host = np.empty((rays, RAY_IN_COLS))
    host[:, 0:3] = b.points(a, c)
    host[:, 3:6] = src.field.direction
    host[:, 6] = rng.uniform(400.0, 700.0, rays)
    arr = wp.array(host, dtype=k.real, device=device)
    del host
    out = wp.empty((rays, RAY_IN_COLS + 1), dtype=k.real, device=device)
    st = wp.empty(rays, dtype=wp.int32, device=device)
    sf = wp.empty(rays, dtype=wp.int32, device=device)
    rec = wp.zeros((1, 1, N_RECORD), dtype=k.real, device=device)
    tab = wp.zeros((1, 1), dtype=k.real, device=device)
    shape, consts = shape_and_constants(packed)
    variant = choose_kernel(kernel, device, shape, rays)
    if variant == "specialised":
        sk = store_kernel(precision, shape, specialised.GPU_TUNING[precision] if device.startswith("cuda")
                          else specialised.DEFAULT_TUNING)
        kern, args, tail = sk.kernel, [params(sk, consts, device), arr, k.real(0.0), tab], [out, st, sf]
    else:
        kern, _, lens_arg = lens_variant(k, packed.general)
        args = [packed.surf, packed.media, packed.iris, lens.n_surfaces, arr, lens.n_surfaces, 1, k.real(0.0), 0, tab]
        tail = [out, st, sf, rec, lens_arg]
    wp.launch(kern, dim=min(rays, 1024), device=device, inputs=args + [0] + tail)
    wp.synchronize_device(device)
    # the CPU runs one slice per core, as lensrt.trace.trace does
    workers = 1 if device.startswith("cuda") else max(1, len(os.sched_getaffinity(0)))
    bounds = [rays * w // workers for w in range(workers + 1)]

    def run(w: int) -> None:
        wp.launch(kern, dim=bounds[w + 1] - bounds[w], device=device, inputs=args + [bounds[w]] + tail)

    t0 = time.perf_counter()
    with ThreadPoolExecutor(workers) as pool:
        list(pool.map(run, range(workers)))
    wp.synchronize_device(device)
    dt = time.perf_counter() - t0
    return dt, rays / dt, variant


def time_optiland(lens: Lens, rays: int, hy: float) -> tuple[float, float] | None:
    try:
        from optiland import optic
        from optiland.materials import IdealMaterial
    except Exception:  # noqa: BLE001 - optional peer
        return None
    from lensrt.paraxial import first_order
    wl = lens.wavelengths.primary_nm
    n = lens.indices(wl)
    op = optic.Optic()
    op.surfaces.add(index=0, radius=math.inf, thickness=math.inf)
    for i, s in enumerate(lens.surfaces):
        mat = "air" if n[i + 1] == 1.0 else IdealMaterial(float(n[i + 1]))
        op.surfaces.add(index=i + 1, radius=s.radius_mm, thickness=s.thickness_mm, material=mat,
                        is_stop=s.is_stop, conic=s.conic)
    op.surfaces.add(index=lens.n_surfaces + 1)
    op.set_aperture(aperture_type="EPD", value=first_order(lens).entrance_pupil_diameter_mm)
    op.fields.set_type(field_type="angle")
    op.fields.add(y=0.0)
    op.fields.add(y=math.degrees(lens.fields.max_radial))
    op.wavelengths.add(value=wl / 1000.0, is_primary=True)
    rng = np.random.default_rng(0)
    r = np.sqrt(rng.uniform(0, 1, rays))
    phi = rng.uniform(0, 2 * np.pi, rays)
    px, py = r * np.cos(phi), r * np.sin(phi)
    op.trace_generic(0.0, hy, px[:1000], py[:1000], wl / 1000.0)  # warm-up (numba, caches)
    t0 = time.perf_counter()
    try:
        op.ray_tracer.trace_generic(0.0, hy, px, py, wl / 1000.0, record=False)
    except TypeError:
        op.trace_generic(0.0, hy, px, py, wl / 1000.0)
    dt = time.perf_counter() - t0
    return dt, rays / dt


def aot_modules(lens: Lens, precisions: list[str], scaling: bool) -> list[str]:
    """Every Warp module a GPU run of this script loads (for --aot)."""
    names = module_names("float64")
    lenses = [lens] + ([stack_lens(ns) for ns in SURFACE_COUNTS] if scaling else [])
    for prec in precisions:
        get_kernels(prec)
        get_kernels("float64")
        names.extend(module_names(prec))
        for ln in lenses:
            shape, _ = shape_and_constants(pack_lens(ln, prec, "cpu"))
            tuning = specialised.GPU_TUNING[prec]
            for table in (False, True):
                names.append(stream_kernel(prec, shape, StreamOptions(SAMPLERS.index("sobol"), table, False, True),
                                           tuning).module)
            names.append(store_kernel(prec, shape, tuning).module)
    return names


SURFACE_COUNTS = (3, 6, 10, 15, 20, 30)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default=None, help="cpu, cuda, cuda:N (default: every device Warp sees)")
    ap.add_argument("--rays", type=float, default=None,
                    help="stream rays per run (default 1e9 on a GPU, 2e6 on the CPU)")
    ap.add_argument("--store-rays", type=float, default=None,
                    help="store-kernel rays (default 2^26 GPU, 1e6 CPU)")
    ap.add_argument("--optiland-rays", type=float, default=1e6, help="rays for optiland and the CPU comparison")
    ap.add_argument("--precision", choices=["float32", "float64", "both"], default="both")
    ap.add_argument("--kernel", choices=["auto", "generic", "specialised"], default="auto")
    ap.add_argument("--compare-generic", action="store_true", help="also time the generic kernel")
    ap.add_argument("--scaling", action="store_true", help="also scale rays (1e6..1e10 GPU) and surfaces (3..30)")
    ap.add_argument("--no-optiland", action="store_true")
    ap.add_argument("--aot", type=int, default=None, help="only compile the GPU modules for this CUDA arch")
    args = ap.parse_args(argv)

    wp = warp()
    precisions = ["float32", "float64"] if args.precision == "both" else [args.precision]
    lens = bench_lens()
    if args.aot is not None:
        names = list(dict.fromkeys(aot_modules(lens, precisions, args.scaling)))
        t0 = time.perf_counter()
        for name in names:
            wp.compile_aot_module(name, arch=args.aot, use_ptx=False)
        print(f"compiled {len(names)} modules for sm_{args.aot} in {time.perf_counter() - t0:.1f} s "
              f"into {wp.config.kernel_cache_dir}")
        return 0
    devices = [resolve_device(args.device)] if args.device else (
        ["cpu"] + (["cuda:0"] if wp.get_cuda_device_count() > 0 else []))
    print(f"lens: {lens.name} ({lens.n_surfaces} surfaces), 7-blade iris; host: {platform.processor() or platform.machine()}, "
          f"Python {platform.python_version()}, Warp {wp.config.version}", flush=True)
    rows = []
    cache: dict = {}
    kernels = [args.kernel] + (["generic"] if args.compare_generic and args.kernel != "generic" else [])
    for dev in devices:
        gpu = dev.startswith("cuda")
        n_stream = int(args.rays or (1e9 if gpu else 2e6))
        n_store = int(args.store_rays or ((1 << 26) if gpu else 1e6))
        name = describe_device(dev)
        if gpu:  # bring the clocks up: one untimed full-size run
            time_stream(lens, n_stream, precisions[0], dev, 1.0, True, cache, args.kernel)
        for kern in kernels:
            for prec in precisions:
                for hy, label in ((0.0, "on axis"), (1.0, "full field")):
                    for spectral in (True, False):
                        sec, rps, var = time_stream(lens, n_stream, prec, dev, hy, spectral, cache, kern)
                        rows.append([name, "stream", var, prec, label, "400-700 nm" if spectral else "3 lines",
                                     n_stream, sec, rps])
                        print(" | ".join(str(v) for v in rows[-1]), flush=True)
                sec, rps, var = time_store(lens, n_store, prec, dev, kern)
                rows.append([name, "store", var, prec, "0.7 field", "400-700 nm", n_store, sec, rps])
                print(" | ".join(str(v) for v in rows[-1]), flush=True)
    if not args.no_optiland:
        n_opt = int(args.optiland_rays)
        for hy, label in ((0.0, "on axis"), (1.0, "full field")):
            got = time_optiland(lens, n_opt, hy)
            if got is None:
                print("optiland is not installed: no peer timing")
                break
            rows.append(["cpu", "optiland (NumPy)", "-", "float64", label, "1 line", n_opt, got[0], got[1]])
            for prec in precisions:
                sec, rps, var = time_stream(lens, n_opt, prec, "cpu", hy, True, cache)
                rows.append(["cpu", "stream (same rays)", var, prec, label, "400-700 nm", n_opt, sec, rps])
    print(format_table([r[:7] + [f"{r[7]:.4f}", f"{r[8]:.3e}"] for r in rows],
                       ["device", "kernel", "variant", "precision", "field", "spectrum", "rays", "seconds",
                        "rays/s"]))
    if args.scaling:
        srows = []
        for dev in devices:
            gpu = dev.startswith("cuda")
            counts = [1e6, 1e7, 1e8, 1e9, 1e10] if gpu else [1e4, 1e5, 1e6, 4e6]
            for prec in precisions:
                for n in counts:
                    sec, rps, var = time_stream(lens, int(n), prec, dev, 1.0, True, cache, args.kernel)
                    srows.append([describe_device(dev), var, prec, f"{lens.n_surfaces} surfaces", int(n), sec, rps])
                    print(" | ".join(str(v) for v in srows[-1]), flush=True)
                n = int(1e9 if gpu else 1e6)
                for ns in SURFACE_COUNTS:
                    stack = stack_lens(ns)
                    sec, rps, var = time_stream(stack, n, prec, dev, 1.0, True, cache, args.kernel)
                    srows.append([describe_device(dev), var, prec, f"{ns} surfaces", n, sec, rps])
                    print(" | ".join(str(v) for v in srows[-1]), flush=True)
        print()
        print(format_table([r[:5] + [f"{r[5]:.4f}", f"{r[6]:.3e}"] for r in srows],
                           ["device", "variant", "precision", "lens", "rays", "seconds", "rays/s"],
                           title="scaling (stream, full field, 400-700 nm)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
