"""Compare every output file of two report folders (e.g. before and after a change to how they are written).

Usage (from the repository root)::

    python benchmarks/compare_report_files.py BEFORE_DIR AFTER_DIR

For each file the two folders share: PNG -- the decoded pixels must be equal and the text chunks
equal except run timings (``lensrt:seconds``); EXR -- every channel bit for bit and every attribute
(JSON attributes walked number by number as :mod:`compare_report_json` does, skipping timings); JSON
-- as :mod:`compare_report_json`; ``index.html`` is skipped (it prints timings). Files in one folder
only are listed. Exit status 0 when every shared file is equal in that sense, 1 otherwise.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compare_report_json import SKIP, walk  # noqa: E402 - the sibling script

#: PNG text keys that hold timings
PNG_TIMING_KEYS = {"lensrt:seconds"}


def _walk_result(a, b) -> dict:
    out = {"n": 0, "diff": [], "other": [], "structure": []}
    walk(a, b, "", out)
    return out


def _problems(out: dict) -> list[str]:
    return [f"{w}: {x!r} -> {y!r}" for _, _, w, x, y in out["diff"]] + out["other"] + out["structure"]


def compare_png(a: Path, b: Path) -> list[str]:
    from PIL import Image
    ia, ib = Image.open(a), Image.open(b)
    problems = []
    pa, pb = np.asarray(ia), np.asarray(ib)
    if pa.shape != pb.shape:
        return [f"size {pa.shape} vs {pb.shape}"]
    if not np.array_equal(pa, pb):
        problems.append(f"{int(np.count_nonzero(np.any(pa != pb, axis=-1) if pa.ndim == 3 else pa != pb))} "
                        "pixels differ")
    ta = {k: v for k, v in ia.text.items() if k not in PNG_TIMING_KEYS}
    tb = {k: v for k, v in ib.text.items() if k not in PNG_TIMING_KEYS}
    if ta != tb:
        problems.append(f"text chunks differ: {sorted(set(ta.items()) ^ set(tb.items()))[:4]}")
    return problems


def _attribute(v):
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    if isinstance(v, str) and v[:1] in "[{":
        try:
            return json.loads(v)
        except ValueError:
            return v
    return v


def compare_exr(a: Path, b: Path) -> list[str]:
    from lensrt.io.exr import read_exr
    ca, ma = read_exr(a)
    cb, mb = read_exr(b)
    problems = []
    if sorted(ca) != sorted(cb):
        return [f"channels {sorted(ca)} vs {sorted(cb)}"]
    for k in ca:
        if ca[k].dtype != cb[k].dtype or not np.array_equal(ca[k].view(np.uint8), cb[k].view(np.uint8)):
            problems.append(f"channel {k} differs")
    ma = {k: _attribute(v) for k, v in ma.items() if not SKIP.search(k)}
    mb = {k: _attribute(v) for k, v in mb.items() if not SKIP.search(k)}
    return problems + _problems(_walk_result(ma, mb))


def compare_json(a: Path, b: Path) -> list[str]:
    return _problems(_walk_result(json.loads(a.read_text()), json.loads(b.read_text())))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[2].strip())
        return 2
    da, db = Path(argv[0]), Path(argv[1])
    names_a = {p.name for p in da.iterdir() if p.is_file()}
    names_b = {p.name for p in db.iterdir() if p.is_file()}
    bad = 0
    for name in sorted(names_a ^ names_b):
        print(f"{name}: only in {'before' if name in names_a else 'after'}")
        bad += 1
    kinds = {".png": compare_png, ".exr": compare_exr, ".json": compare_json}
    for name in sorted(names_a & names_b):
        compare = kinds.get(Path(name).suffix.lower())
        if compare is None:
            continue
        problems = compare(da / name, db / name)
        print(f"{name}: {'equal' if not problems else 'DIFFERENT'}")
        for p in problems[:10]:
            print(f"  {p}"[:240])
        bad += bool(problems)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
