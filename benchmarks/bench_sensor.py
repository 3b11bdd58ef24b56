"""Benchmark: a full-size frame from sensor-plane spectral irradiance to 16-bit sRGB on the CPU.

    python benchmarks/bench_sensor.py                       # 24 MP (4000 x 6000), 16 wavelengths
    python benchmarks/bench_sensor.py --rows 1000 --cols 1500 --wavelengths 31 --demosaic malvar2004

Prints one table of seconds per stage (wall clock, time.perf_counter). The irradiance cube is
random smooth spectra (float32); the sensor is the ``fullframe_24mp`` preset at ISO 400 with
every noise source on. The first exposure also builds the sensor's fixed-pattern maps (cached
afterwards); both the first and a repeated exposure are timed.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from lensrt.io.png import write_png, write_tiff  # noqa: E402
from lensrt.io.table import format_table  # noqa: E402
from lensrt.isp import Isp, IspSettings, quantize  # noqa: E402
from lensrt.sensor import electrons_to_raw, get_preset, mean_photoelectrons  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=4000)
    ap.add_argument("--cols", type=int, default=6000)
    ap.add_argument("--wavelengths", type=int, default=16)
    ap.add_argument("--demosaic", default="bilinear")
    ap.add_argument("--preset", default="fullframe_24mp")
    ap.add_argument("--iso", type=float, default=400)
    ap.add_argument("--write", action="store_true", help="also time writing 16-bit TIFF and PNG")
    args = ap.parse_args()
    rows, cols, n = args.rows, args.cols, args.wavelengths
    sensor = get_preset(args.preset)
    rng = np.random.default_rng(0)
    wl = np.linspace(400, 700, n)
    timings: list[list] = []

    def timed(label, fn):
        t0 = time.perf_counter()
        out = fn()
        timings.append([label, time.perf_counter() - t0])
        return out

    # a smooth random spectral image: a few broad spectral shapes mixed per pixel (not timed)
    basis = np.stack([np.exp(-0.5 * ((wl - c) / 60) ** 2) for c in (450, 550, 650)], -1).astype(np.float32)
    weights = rng.uniform(0, 1, (rows, cols, 3)).astype(np.float32)
    E = (weights.reshape(-1, 3) @ basis.T).reshape(rows, cols, n) * np.float32(2e-3)
    del weights
    isp = Isp(sensor, IspSettings(demosaic=args.demosaic))
    timed("colour calibration (once per sensor)", lambda: isp.calibration)
    mean_e = timed("irradiance -> mean photoelectrons", lambda: mean_photoelectrons(sensor, E, wl, 0.01))
    raw = timed("noise, full well, gain, ADC (first: + FPN maps)",
                lambda: electrons_to_raw(sensor, mean_e, 0.01, rng=rng, iso=args.iso))
    raw = timed("noise, full well, gain, ADC (repeat)", lambda: electrons_to_raw(sensor, mean_e, 0.01, rng=rng, iso=args.iso))
    res = timed(f"ISP develop ({args.demosaic})", lambda: isp.develop(raw))
    for k, v in res.seconds.items():
        timings.append([f"  isp: {k}", v])
    img16 = timed("quantise to 16-bit sRGB", lambda: quantize(res.encoded, 16))
    end_to_end = sum(t for label, t in timings if label.startswith(("irradiance", "noise, full well, gain, ADC (repeat)",
                                                                     "ISP develop", "quantise")))
    timings.append(["irradiance -> 16-bit sRGB (sum of the above, FPN cached)", end_to_end])
    if args.write:
        with tempfile.TemporaryDirectory() as d:
            timed("write 16-bit TIFF (uncompressed)", lambda: write_tiff(Path(d) / "a.tif", img16))
            timed("write 16-bit PNG (zlib level 6)", lambda: write_png(Path(d) / "a.png", img16, 16))
    print(f"lensrt sensor benchmark: {rows} x {cols} ({rows * cols / 1e6:.1f} MP), {n} wavelengths float32, "
          f"preset {sensor.name}, ISO {args.iso:g}")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPU cores visible, "
          f"numpy {np.__version__}, python {platform.python_version()}")
    print(format_table(timings, ["stage", "seconds"], digits=3))
    return 0


if __name__ == "__main__":
    sys.exit(main())
