"""`lensrt render` in one process against `--devices`: same EXR bits, render seconds and wall seconds.

Runs the CLI three times on a scene at a fixed sample count (after one warm-up run that compiles
the kernels): in-process on one device (`--device D0`), as a tiled Job on that one device
(`--devices D0`), and as a tiled Job on every device (`--devices ALL`); then checks that the three
EXRs hold the same bits and prints the render seconds (the passes; the Job paths include each
device's scene packing) and the wall seconds of the whole command (import, focus, exit-pupil
table, EXR writing).

    python benchmarks/render_devices_check.py                              # 2+ GPUs: cuda:0 / all
    python benchmarks/render_devices_check.py --one cpu --all cpu,cpu --width 96 --spp 8
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _render(scene: str, width: int, spp: int, extra: list[str], out: Path) -> tuple[dict, float]:
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "lensrt", "render", scene, "--width", str(width), "--spp", str(spp),
                        "-o", str(out), "--json"] + extra, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode:
        sys.exit(f"lensrt render {' '.join(extra)} failed:\n{r.stdout[-2000:]}{r.stderr[-3000:]}")
    return json.loads(r.stdout), wall


def _exr(path: Path) -> dict:
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        return {k: np.asarray(v.pixels) for k, v in f.channels().items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="still_life_mesh")
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--spp", type=int, default=512)
    ap.add_argument("--one", default="cuda:0", help="the single device (default cuda:0)")
    ap.add_argument("--all", default="all", help="the device list of the parallel run (default all)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        _render(a.scene, a.width, a.spp, ["--device", a.one], d / "warm")
        runs = [(f"in process (--device {a.one})", ["--device", a.one]),
                (f"tiled Job (--devices {a.one})", ["--devices", a.one]),
                (f"tiled Job (--devices {a.all})", ["--devices", a.all])]
        rows = []
        for k, (label, extra) in enumerate(runs):
            res, wall = _render(a.scene, a.width, a.spp, extra, d / f"r{k}")
            rows.append((label, res, wall, _exr(d / f"r{k}.exr")))
    ref = rows[0][3]
    print(f"{a.scene}, {a.width} px wide, {a.spp} samples/pixel")
    print(f"{'run':<34} {'items':<7} {'render s':>9} {'wall s':>7}  same EXR bits")
    for label, res, wall, img in rows:
        same = ref.keys() == img.keys() and all(np.array_equal(ref[k], img[k]) for k in ref)
        print(f"{label:<34} {str(res.get('executor_items')):<7} {res['seconds']:9.3f} {wall:7.2f}  {same}")


if __name__ == "__main__":
    main()
