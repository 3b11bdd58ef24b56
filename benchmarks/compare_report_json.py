"""Compare the numbers of two ``report.json`` files (e.g. before and after a speed change).

Usage (from the repository root)::

    python benchmarks/compare_report_json.py BEFORE/report.json AFTER/report.json

Walks both files in step and compares every number, except timings and what describes the run
(keys with seconds, wall/kernel time, rates, dates, paths, versions, command lines). Prints the
number of values compared, how many differ, the largest absolute and relative differences and
where they are (the first 20 differing paths). Exit status 0 when the structure matches (the
numbers may differ), 1 when a value exists in one file only or the kinds differ.
"""
from __future__ import annotations

import json
import math
import re
import sys

#: keys whose values are timings or describe the run, not results
SKIP = re.compile(r"(seconds|_s$|^seconds$|wall|kernel_s|rays_per_second|rays_per_s|date|time|path|"
                  r"command_line|environment|version|lensrt$|platform|device|telemetry|launches|copies|"
                  r"^out_dir$|files|progress|group_id|traceback)", re.IGNORECASE)


def walk(a, b, where: str, out: dict) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if SKIP.search(str(k)):
                continue
            if k not in a or k not in b:
                out["structure"].append(f"{where}/{k}: only in {'after' if k not in a else 'before'}")
                continue
            walk(a[k], b[k], f"{where}/{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out["structure"].append(f"{where}: {len(a)} vs {len(b)} entries")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{where}[{i}]", out)
    elif isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        out["n"] += 1
        if a != b:
            out["other"].append(f"{where}: {a!r} -> {b!r}"[:200])
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        out["n"] += 1
        if a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)):
            return
        d = abs(a - b)
        rel = d / max(abs(a), abs(b))
        out["diff"].append((rel, d, where, a, b))
    else:
        out["structure"].append(f"{where}: {type(a).__name__} vs {type(b).__name__}")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[2].strip())
        return 2
    a, b = (json.load(open(p)) for p in argv)
    out = {"n": 0, "diff": [], "other": [], "structure": []}
    walk(a, b, "", out)
    diffs = sorted(out["diff"], reverse=True)
    print(f"{out['n']} values compared; {len(diffs)} numbers differ; {len(out['other'])} other values differ; "
          f"{len(out['structure'])} structural differences")
    if diffs:
        print(f"largest relative difference {diffs[0][0]:.3g}; largest absolute "
              f"{max(d[1] for d in diffs):.3g}")
        for rel, d, where, x, y in diffs[:20]:
            print(f"  {where}: {x!r} -> {y!r} (rel {rel:.2g})")
    for s in (out["other"] + out["structure"])[:20]:
        print("  " + s)
    return 1 if out["structure"] else 0


if __name__ == "__main__":
    sys.exit(main())
