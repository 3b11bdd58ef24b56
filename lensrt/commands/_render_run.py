"""``lensrt render SCENE``: options -> :func:`lensrt.render.integrator.render` -> files and a summary.

Called by :mod:`lensrt.commands.render` (which parses the arguments and loads the scene and lens);
the command layer's half of the render, so that :mod:`lensrt.render` never imports the CLI.
"""
from __future__ import annotations

import sys
import time
from typing import Any

from ..errors import LensrtError
from ._common import emit, print_json

__all__ = ["run", "options_from_args", "progress_bar"]


def options_from_args(args) -> Any:
    from ..render.setup import RenderOptions
    window = None
    if getattr(args, "window", None):
        try:
            window = tuple(int(v) for v in args.window.split(","))
        except ValueError:
            window = ()
        if len(window) != 4:
            raise LensrtError(f"--window {args.window!r} must be row0,row1,col0,col1 (pixels)")
    for name in ("spp", "spp_per_pass"):
        v = getattr(args, name, None)
        if v is not None and v < 1:
            raise LensrtError(f"--{name.replace('_', '-')} must be at least 1")
    if args.time_budget is not None and not args.time_budget > 0:
        raise LensrtError("--time-budget must be positive (seconds)")
    if args.target_error is not None and not args.target_error > 0:
        raise LensrtError("--target-error must be positive (relative standard error, e.g. 0.02)")
    return RenderOptions(samples_per_pixel=args.spp, spp_per_pass=args.spp_per_pass, seed=args.seed,
                         time_budget_s=args.time_budget, target_rel_error=args.target_error,
                         band_width_nm=args.band_nm, focus=args.focus, device=args.device, width=args.width,
                         window=window)


def progress_bar(stream=None):
    """A progress callback drawing ``[####....] passes, seconds, estimated seconds left`` on ``stream``
    (stderr); redrawn in place on a terminal, one line per pass otherwise."""
    stream = sys.stderr if stream is None else stream
    tty = hasattr(stream, "isatty") and stream.isatty()

    def show(done: int, planned: int, elapsed: float, left: float | None) -> None:
        frac = min(done / max(planned, 1), 1.0)
        n = int(round(30 * frac))
        eta = "" if left is None else (" done" if left == 0 else f", ~{left:.1f} s left")
        line = f"render [{'#' * n}{'.' * (30 - n)}] pass {done}/{planned}, {elapsed:.1f} s{eta}"
        if tty:
            stream.write("\r" + line + "   ")
            if left == 0 or done >= planned:
                stream.write("\n")
        else:
            stream.write(line + "\n")
        stream.flush()
    return show


def run(args, scene, lens) -> int:
    from ..render.integrator import render
    from ..pipeline import write_outputs
    from contextlib import nullcontext
    options = options_from_args(args)
    context: Any = nullcontext(None)
    if getattr(args, "devices", None) or getattr(args, "workers", 0) or getattr(args, "scheduler", None) \
            or getattr(args, "executor", "thread") == "process":
        if args.device is not None:
            raise LensrtError("give --device (one device, this process) or --devices/--executor/--workers/--scheduler, "
                              "not both")
        from ._parallel import executor_from_args
        context = executor_from_args(args, uses_device=True)
    quiet = bool(args.json)
    if not quiet:
        sys.stderr.write(f"lensrt render: {scene.name}: planning, focusing, exit-pupil table "
                         "(a first run also compiles the render kernels)\n")
    t0 = time.perf_counter()
    with context as executor:
        result = render(scene, lens, options, executor=executor, progress=None if quiet else progress_bar())
    prefix = args.output if args.output else scene.name
    seed = options.seed if options.seed is not None else scene.render.seed
    files = write_outputs(result, scene, prefix, seed=seed)
    total = time.perf_counter() - t0
    if args.json:
        s = result.summary()
        s["files"] = files
        s["wall_seconds"] = total
        print_json(s)
        return 0
    rows, cols = result.shape
    items = {"tiles": f", {result.executor_item_count} row tiles with all passes each",
             "passes": f", {result.executor_item_count} one-pass items in rounds"}.get(result.executor_items, "")
    emit(f"{scene.name}: {cols} x {rows} px, {result.samples_per_pixel} samples/pixel ({result.passes} passes, "
         f"stopped by {result.stop_reason}), {result.mode} on {result.device}{items}")
    emit(f"  {result.samples:.4g} paths in {result.seconds:.3g} s = {result.samples_per_second:.3g} paths/s; "
         f"set-up {result.setup_seconds.get('total_before_passes', 0.0):.3g} s; wall {total:.3g} s")
    if result.through is not None:
        emit(f"  {100.0 * result.through.value:.2f} +- {100.0 * result.through.stderr:.2g} % of the paths got "
             "through the lens")
    elif result.through_fraction == result.through_fraction:
        emit(f"  {100.0 * result.through_fraction:.1f} % of the paths got through the lens")
    c = result.camera
    emit(f"  lens {c.lens.name}: f/{c.f_number:.3g} (working f/{c.working_f_number:.3g}), focus "
         + ("infinity" if c.focus_distance_mm == float("inf") else f"{c.focus_distance_mm / 1000.0:.4g} m")
         + f" ({c.focus_method}), sensor at z = {c.sensor_z_mm:.4f} mm")
    if result.regions:
        emit("  illuminance Y on the sensor (lux, mean +- standard error, batch means over passes):")
        for name, est in result.regions.items():
            rel = f"({100 * est.stderr / est.value:.2g} %)" if est.value else "(no light reached it)"
            emit(f"    {name:<12} {est.value:.5g} +- {est.stderr:.2g}  {rel}")
    for n in result.notes:
        emit(f"  note: {n}")
    for kind, path in files.items():
        emit(f"  wrote {path}")
    return 0
