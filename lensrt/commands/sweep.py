"""``lensrt sweep``: first-order and photographic quantities over lens variants (focus distance x f-number),
run as a parallel job, written as one table (terminal, CSV or JSON)."""
from __future__ import annotations

import argparse
import csv
import io
import math
from typing import Any

from ..core.budget import MAX_SWEEP_ROWS
from ._limits import parse_seed, positive_int
from ._common import add_lens_argument, emit, lens_config
from ._parallel import add_parallel_arguments, executor_from_args, progress_printer, run_summary_line

__all__ = ["register", "parse_values", "FULL_STOPS"]

#: full f-stops, sqrt(2) apart (p. 30)
FULL_STOPS = (1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 11.0, 16.0, 22.0)
DEFAULT_FOCUS_MM = (500.0, 1000.0, 2000.0, 5000.0, math.inf)


def _default_focus_mm(lens: Any) -> list[float]:
    """:data:`DEFAULT_FOCUS_MM` less the distances at or inside the lens's front focal point (no real image
    there: a 500 mm lens does not focus at 500 mm)."""
    from ..paraxial import first_order
    near = -first_order(lens).front_focal_z_mm
    return [d for d in DEFAULT_FOCUS_MM if d > near]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sweep", help="a quantity over lens variants (focus distance x f-number), one table",
                       description="Runs each lens variant -- the lens focused at a distance, stopped to an "
                                   "f-number -- as a work item (in this process, on local worker processes, "
                                   "or on a Dask cluster) and writes one table with a row per variant. "
                                   "Quantities are first-order (paraxial) ones and the Field Guide's "
                                   "photographic formulas.")
    add_lens_argument(p)
    p.add_argument("--focus-distance-mm", metavar="LIST",
                   help="focus distances, object plane to first vertex in mm: a comma list ('inf' allowed) or "
                        "A:B:N for N values from A to B in equal ratios (default 500,1000,2000,5000,inf)")
    p.add_argument("--f-number", metavar="LIST",
                   help="f-numbers N = f/D: a comma list or A:B:N in equal ratios (default: the full stops "
                        "from the lens's own f-number to 16)")
    p.add_argument("--quantity", metavar="LIST",
                   help="columns: a comma list of quantity names, or 'all' (see --list-quantities)")
    p.add_argument("--list-quantities", action="store_true", help="print the quantity names and units, and exit")
    p.add_argument("--wavelength-nm", type=float, metavar="W", help="wavelength in nm (default: the lens's primary)")
    p.add_argument("--sensor", default="full-frame", metavar="FORMAT",
                   help="sensor format for depth of field and angle of view (default full-frame)")
    p.add_argument("--coc-mm", type=float, metavar="C", help="circle of confusion in mm (default: the format's)")
    p.add_argument("--format", choices=("table", "csv", "json"), default="table",
                   help="what to print (default table)")
    p.add_argument("-o", "--output", metavar="FILE", help="write the table to FILE (.csv, .json or .txt)")
    p.add_argument("--seed", type=parse_seed, default=0, help="job seed (the paraxial sweep draws no random numbers)")
    p.add_argument("--max-rows", type=positive_int, default=None, metavar="N",
                   help=f"allow more than {MAX_SWEEP_ROWS} variants (focus distances x f-numbers)")
    add_parallel_arguments(p)
    p.set_defaults(func=cmd_sweep)


def parse_values(text: str, what: str, max_count: int | None = None) -> list[float]:
    """A comma list of numbers ('inf' allowed) or ``A:B:N`` (N values from A to B in equal ratios);
    N at most ``max_count`` (default :data:`lensrt.core.budget.MAX_SWEEP_ROWS`, ``--max-rows``)."""
    import numpy as np

    from ..errors import LensrtError
    text = text.strip()
    try:
        if ":" in text:
            a, b, n = text.split(":")
            lo, hi, count = float(a), float(b), int(float(n)) if math.isfinite(float(n)) else -1
            if not (0 < lo and 0 < hi and math.isfinite(lo) and math.isfinite(hi) and count >= 1):
                raise ValueError
            _check_rows(count, f"{what} {text}", max_count)
            return [float(v) for v in np.geomspace(lo, hi, count)] if count > 1 else [lo]
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise LensrtError(f"{what} {text!r} is not a comma list of numbers or A:B:N",
                          hint="e.g. 1000,2000,inf or 500:20000:8") from None
    if not values:
        raise LensrtError(f"{what} is empty")
    if not all(v > 0 for v in values):  # nan, 0 and negative distances or f-numbers
        raise LensrtError(f"{what} {text!r}: every value must be positive", hint="e.g. 1000,2000,inf or 500:20000:8")
    return values


def _check_rows(count: int, what: str, max_count: int | None) -> None:
    from ..core.budget import check_count
    check_count(count, max_count or MAX_SWEEP_ROWS, f"{what}: {count} variants", "--max-rows")


def _default_f_numbers(lens: Any, wavelength_nm: float | None) -> list[float]:
    from ..paraxial import first_order
    n0 = first_order(lens, wavelength_nm).f_number
    stops = [s for s in FULL_STOPS if s >= 0.95 * n0 and s <= 16.0]
    return [n0] + [s for s in stops if abs(s - n0) > 0.05 * n0] if stops else [n0]


def _columns(spec: str | None) -> list[str]:
    from ..errors import LensrtError
    from ..studies.sweep import DEFAULT_QUANTITIES, QUANTITIES
    if spec is None:
        names = list(DEFAULT_QUANTITIES)
    elif spec.strip() == "all":
        names = list(QUANTITIES)
    else:
        names = [s.strip() for s in spec.split(",") if s.strip()]
    bad = [n for n in names if n not in QUANTITIES]
    if bad or not names:
        raise LensrtError(f"unknown quantity {', '.join(bad) or '(none)'}",
                          hint=f"known: {', '.join(QUANTITIES)}")
    return names


def _csv_cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v) if isinstance(v, float) else v


def _as_csv(rows: list[dict], keys: list[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(keys)
    for r in rows:
        w.writerow([_csv_cell(r[k]) for k in keys])
    return buf.getvalue()


def cmd_sweep(args: argparse.Namespace) -> int:
    from ..errors import LensrtError
    from ..io.table import dumps_json, format_table
    from ..paraxial import photographic as ph
    from ..studies.sweep import QUANTITIES, SweepSetup, sweep_job

    if args.list_quantities:
        emit(format_table([(k, u or "-", d) for k, (u, d) in QUANTITIES.items()], ["quantity", "unit", "meaning"]))
        return 0
    if args.wavelength_nm is not None and not (math.isfinite(args.wavelength_nm)
                                               and 200.0 <= args.wavelength_nm <= 20000.0):
        raise LensrtError(f"--wavelength-nm {args.wavelength_nm:g} is outside 200..20000 nm")
    if args.coc_mm is not None and not (math.isfinite(args.coc_mm) and args.coc_mm > 0):
        raise LensrtError(f"--coc-mm {args.coc_mm:g} must be a positive diameter in mm")
    fmt = ph.sensor_format(args.sensor)
    columns = _columns(args.quantity)
    variants = _lenses(args)
    lens = variants[0][1]
    if args.wavelength_nm is not None:
        lens.check_wavelengths(args.wavelength_nm)  # an ExtrapolationWarning where a glass is extrapolated
    given = parse_values(args.focus_distance_mm, "--focus-distance-mm", args.max_rows) if args.focus_distance_mm \
        else None
    rows = []
    for name, one in variants:
        focus = given if given is not None else _default_focus_mm(one)
        fnums = parse_values(args.f_number, "--f-number", args.max_rows) if args.f_number \
            else _default_f_numbers(one, args.wavelength_nm)
        _check_rows(len(variants) * len(focus) * len(fnums),
                    f"{len(variants)} configurations x {len(focus)} focus distances x {len(fnums)} f-numbers",
                    args.max_rows)
        if args.f_number:
            from ..paraxial.fnumber import check_f_number
            for n in fnums:  # as render and bokeh: never wider than the lens opens
                check_f_number(one, n)
        job = sweep_job(SweepSetup(one, args.wavelength_nm, args.sensor, args.coc_mm), focus, fnums, args.seed)
        with executor_from_args(args, uses_device=job.uses_device) as ex:
            result = ex.run(job, progress=progress_printer(args, "variants"))
        rows += [({"configuration": name} if name is not None else {}) | r for r in result.value]
    keys = (["configuration"] if variants[0][0] is not None else []) + ["focus_distance_mm", "f_number"] + \
        [c for c in columns if c != "f_number"]
    coc = fmt.coc_mm if args.coc_mm is None else args.coc_mm
    meta = {"lens": lens.name, "configurations": [n for n, _ in variants if n is not None], "path": lens.path, "wavelength_nm": args.wavelength_nm, "sensor": fmt.name,
            "coc_mm": coc, "columns": {k: QUANTITIES.get(k, ("mm" if k.endswith("_mm") else "", ""))[0]
                                       for k in keys}}
    doc = {**meta, "rows": [{k: r[k] for k in keys} for r in rows], "run": result.summary()}
    table = format_table([[r[k] for k in keys] for r in rows], keys,
                         title=f"{lens.name or lens.path}: {len(rows)} variants, sensor {fmt.name}, CoC {coc:g} mm; "
                               "distances in mm in front of the first vertex")
    texts = {"table": table + "\n" + run_summary_line(result) + "\n", "csv": _as_csv(rows, keys),
             "json": dumps_json(doc) + "\n"}
    if args.output:
        from ..io.paths import output_file
        path = output_file(args.output)
        kind = {".csv": "csv", ".json": "json", ".txt": "table"}.get(path.suffix.lower())
        if kind is None:
            raise LensrtError(f"cannot tell the table format of {path} from its extension",
                              hint="name it .csv, .json or .txt")
        try:
            path.write_text(texts[kind])
        except OSError as err:
            raise LensrtError(f"cannot write {path}: {err.strerror}") from None
        emit(f"wrote {path} ({len(rows)} rows, {kind}); {run_summary_line(result)}")
        return 0
    emit(texts[args.format])
    return 0


def _lenses(args: argparse.Namespace) -> list[tuple[str | None, Any]]:
    """(configuration name, lens) pairs to sweep: every configuration with ``--config all``, else one lens."""
    from ..loading import load_configurations, load_lens
    config = lens_config(args, allow_all=True)
    if config is not None and config.lower() == "all":
        family = load_configurations(args.file)
        return list(zip(family.names, family.configurations()))
    return [(None, load_lens(args.file, config=config))]
