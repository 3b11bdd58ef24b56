"""Load counts of the two peer corpora: rayoptics' 41 lens files and optiland's sample lenses.

optiland's samples are exported to ``.zmx`` with ``optiland.fileio.save_zemax_file`` (optiland is a
test-only oracle; this script is run by hand). Prints one line per file (``ok`` or the error's first
line) and the totals; ``--json`` writes the per-file results.

    PYTHONPATH=. python benchmarks/corpus_load.py [--glass-substitute] [--glass-model-fallback]
"""
from __future__ import annotations

import argparse
import inspect
import json
import tempfile
import warnings
from pathlib import Path


def rayoptics_files() -> list[Path]:
    import rayoptics
    root = Path(rayoptics.__file__).parent
    return sorted(p for sub in ("zemax/tests", "codev/tests") for p in (root / sub).iterdir()
                  if p.suffix.lower() in (".zmx", ".seq"))


def optiland_samples() -> list[tuple[str, type]]:
    """Every Optic subclass defined in optiland.samples' modules (29 in optiland 0.5.x)."""
    import importlib
    import pkgutil

    import optiland.samples as samples
    from optiland.optic import Optic
    found = {}
    for info in pkgutil.iter_modules(samples.__path__):
        mod = importlib.import_module(f"optiland.samples.{info.name}")
        for name, cls in inspect.getmembers(mod, inspect.isclass):
            if issubclass(cls, Optic) and cls is not Optic and cls.__module__ == mod.__name__:
                found[name] = cls
    return sorted(found.items())


def optiland_files(out: Path) -> list[Path]:
    from optiland.fileio import save_zemax_file
    files = []
    for name, cls in optiland_samples():
        path = out / f"{name}.zmx"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                save_zemax_file(cls(), str(path))
        except Exception as err:  # noqa: BLE001 - report what optiland cannot export
            print(f"export-failed {name}: {type(err).__name__}: {str(err)[:100]}")
            continue
        files.append(path)
    return files


def try_load(path: Path, **options) -> str:
    from lensrt.errors import LensrtError
    from lensrt.loading import load_lens
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            load_lens(path, **options)
        return "ok"
    except LensrtError as err:
        return str(err).splitlines()[0][:160]
    except Exception as err:  # noqa: BLE001 - a traceback is a bug: count it
        return f"TRACEBACK {type(err).__name__}: {err}"[:160]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--glass-substitute", action="store_true")
    ap.add_argument("--glass-model-fallback", action="store_true")
    ap.add_argument("--json", metavar="PATH")
    args = ap.parse_args()
    opts = {}
    if args.glass_substitute:
        opts["glass_substitute"] = True
    if args.glass_model_fallback:
        opts["glass_model_fallback"] = True
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for corpus, files in (("rayoptics", rayoptics_files()), ("optiland", optiland_files(Path(tmp)))):
            res = {p.name: try_load(p, **opts) for p in files}
            results[corpus] = res
            for name, r in res.items():
                print(f"{corpus:9s} {name:40s} {r}")
            ok = sum(r == "ok" for r in res.values())
            tb = sum(r.startswith("TRACEBACK") for r in res.values())
            print(f"== {corpus}: {ok}/{len(res)} load, {tb} tracebacks")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()


def first_order_vs_optiland() -> list[dict]:
    """EFL of each optiland sample that lensrt loads, lensrt vs optiland, with the largest index difference
    between the two tools' glass data at the primary wavelength (so disagreements can be told apart)."""
    import numpy as np
    import optiland.backend as be
    from optiland.fileio import save_zemax_file
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, cls in optiland_samples():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                op = cls()
                path = Path(tmp) / f"{name}.zmx"
                try:
                    save_zemax_file(op, str(path))
                    lens = load_lens(path)
                except Exception:  # noqa: BLE001 - the load counts report these
                    continue
                wl_um = float(op.primary_wavelength)
                theirs = float(be.to_numpy(op.paraxial.f2()))
                mine = first_order(lens, wl_um * 1000.0).efl_mm
                n_op = [float(np.ravel(be.to_numpy(s.material_post.n(wl_um)))[0])
                        for s in op.surface_group.surfaces[1:-1]]
                n_me = list(lens.indices(wl_um * 1000.0))[1:]
                dn = max(abs(a - b) for a, b in zip(n_op, n_me)) if len(n_op) == len(n_me) else float("nan")
            rows.append(dict(name=name, efl_lensrt=mine, efl_optiland=theirs, rel=(mine - theirs) / theirs,
                             max_dn=dn, glasses=sorted({s.material.describe() for s in lens.surfaces
                                                        if not s.material.is_air})))
    return rows
