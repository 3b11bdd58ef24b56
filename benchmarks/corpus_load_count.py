"""Load every lens file of the rayoptics test corpus with lensrt and count outcomes.

Usage (from the repository root)::

    PYTHONPATH=. python benchmarks/corpus_load_count.py [--efl]

Prints one line per file (OK with the EFL, or the one-line error) and the
totals. The corpus is the 41 lens files the ``rayoptics`` wheel ships under
``rayoptics/zemax/tests`` and ``rayoptics/codev/tests`` (.zmx/.seq; the
.smx duplicates are not lens files lensrt reads). With ``--efl`` each loaded
file's focal length is compared with rayoptics' ``efl`` (where rayoptics loads the
file). rayoptics' efl is n'/Phi with the image-space index signed by the
direction of travel, i.e. lensrt's ``rear_focal_length_mm`` (lensrt's
``efl_mm`` is 1/Phi: they differ in sign after an odd number of mirrors), converted
from the file's lens units to mm (rayoptics reports lens units).
"""
from __future__ import annotations

import sys
import traceback
import warnings
from pathlib import Path

__all__ = ["corpus_files", "main"]


def corpus_files() -> list[Path]:
    """The 41 .zmx/.seq files of the rayoptics wheel's test folders (sorted)."""
    import rayoptics
    root = Path(rayoptics.__file__).parent
    out = []
    for sub in ("zemax/tests", "codev/tests"):
        out += [p for p in (root / sub).iterdir() if p.suffix.lower() in (".zmx", ".seq")]
    return sorted(out)


def _rayoptics_efl(path: Path) -> float | None:
    import contextlib
    import os
    import tempfile
    try:
        from rayoptics.environment import open_model
        with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            here = os.getcwd()
            os.chdir(tmp)  # rayoptics writes a reader log into the working directory
            with contextlib.ExitStack() as stack:
                stack.callback(os.chdir, here)
                opm = open_model(str(path), info=False)
        # rayoptics reports lens units (questar35.seq: DIM I, 50.5 in = 1282.7 mm)
        to_mm = {"mm": 1.0, "cm": 10.0, "meters": 1000.0, "inches": 25.4, "feet": 304.8}[opm["system_spec"].dimensions]
        return float(opm["analysis_results"]["parax_data"].fod.efl) * to_mm
    except Exception:  # noqa: BLE001 -- the oracle's own failures are reported as "n/a"
        return None


def main(argv: list[str]) -> int:
    from lensrt.errors import LensrtError
    from lensrt.loading import load_lens
    from lensrt.paraxial.first_order import first_order
    want_efl = "--efl" in argv
    ok = clean = crash = 0
    for p in corpus_files():
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                lens = load_lens(p)
                fo = first_order(lens)
                efl, rear = fo.efl_mm, fo.rear_focal_length_mm
        except LensrtError as e:
            clean += 1
            print(f"ERROR {p.name}: {str(e).splitlines()[0][:160]}")
            continue
        except Exception:  # noqa: BLE001 -- a traceback is a bug, counted and shown
            crash += 1
            print(f"CRASH {p.name}:\n{traceback.format_exc()}")
            continue
        ok += 1
        line = f"OK    {p.name}: EFL {efl:.9g} mm"
        if want_efl:
            ref = _rayoptics_efl(p)
            if ref is not None:
                rel = abs(rear - ref) / abs(ref) if ref else float("nan")
                line += f"   f' {rear:.9g}  rayoptics efl {ref:.9g} mm  rel {rel:.2e}"
        print(line)
    print(f"loaded {ok}, clean errors {clean}, tracebacks {crash}, of {ok + clean + crash}")
    return 0 if crash == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
