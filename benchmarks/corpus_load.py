"""Load counts of the peer corpora (rayoptics' 41 lens files, optiland's sample lenses) and of lensrt's own corpus.

optiland's samples are exported to ``.zmx`` with ``optiland.fileio.save_zemax_file`` (optiland is a
test-only oracle; this script is run by hand). Prints one line per file (``ok`` or the error's first
line) and the totals; ``--json`` writes the per-file results. ``--corpus own`` loads ``tests/data/corpus``
(sources in its SOURCES.md) and prints, as markdown, the refusal reasons (the rules of
``tests/prescription/test_corpus.py``) and the focal lengths against ``expected.toml``.

    PYTHONPATH=. python benchmarks/corpus_load.py [--corpus peers|own|all] [--glass-substitute] [--glass-model-fallback]
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


OWN = Path(__file__).resolve().parent.parent / "tests" / "data" / "corpus"


def _corpus_test_module():
    """tests/prescription/test_corpus.py, for its refusal rules (one list, kept with the test)."""
    import importlib.util
    path = OWN.parent.parent / "prescription" / "test_corpus.py"
    spec = importlib.util.spec_from_file_location("corpus_rules", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def own_corpus_report(opts: dict) -> dict:
    """Load every file of tests/data/corpus; print the markdown tables docs/guide/corpus.md quotes."""
    import tomllib
    from collections import Counter
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    rules = _corpus_test_module()
    expected = tomllib.loads((OWN / "expected.toml").read_text())
    files = sorted(p for p in OWN.iterdir() if p.suffix.lower() in (".zmx", ".seq", ".dat"))
    res, efl = {}, {}
    for path in files:
        res[path.name] = try_load(path, **opts)
        if res[path.name] == "ok":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                efl[path.name] = first_order(load_lens(path, **opts)).efl_mm
    ok = sum(r == "ok" for r in res.values())
    tb = sum(r.startswith("TRACEBACK") for r in res.values())
    print(f"\n**{ok}/{len(res)} load ({ok / len(res):.0%}), {tb} tracebacks.**\n")
    reasons = Counter(rules.refusal_rule(r) or f"no named rule: {r.split(': ', 1)[-1][:60]}"
                      for r in res.values() if r != "ok")
    print("| refusal reason | files |\n| --- | --- |")
    for reason, count in reasons.most_common():
        names = ", ".join(f"`{n}`" for n, r in res.items()
                          if r != "ok" and (rules.refusal_rule(r) or f"no named rule: {r.split(': ', 1)[-1][:60]}") == reason)
        print(f"| {reason} | {count}: {names} |")
    print("\n| file | stated EFL (mm) | held to | lensrt EFL (mm) | difference |\n| --- | --- | --- | --- | --- |")
    for name, entry in sorted(expected.items()):
        got = efl.get(name)
        diff = f"{(got - entry['efl_mm']) / entry['efl_mm']:+.2%}" if got is not None else "not loaded"
        held = f"{rules.NOMINAL_TOLERANCE:.0%} (nominal)" if entry.get("nominal") else "1%"
        print(f"| `{name}` | {entry['efl_mm']:g} | {held} | {'' if got is None else f'{got:.4f}'} | {diff} |")
    return res


def line_nd_efl_mm(path: Path, text: str | None = None) -> float:
    """Independent paraxial EFL of a Zemax file from its CURV/DISZ and the n_d written on each GLAS line
    (y-nu trace, object at infinity; no lensrt code). For files whose GLAS lines carry real n_d values.
    ``text``: the decoded file, when it is not plain UTF-8 (OpticStudio's UTF-16)."""
    surfaces, current = [], None
    for line in (text if text is not None else path.read_text(errors="replace")).splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == "SURF":
            current = {"c": 0.0, "t": 0.0, "n": 1.0}
            surfaces.append(current)
        elif words[0] == "CURV":
            current["c"] = float(words[1])
        elif words[0] == "DISZ" and words[1] != "INFINITY":
            current["t"] = float(words[1])
        elif words[0] == "GLAS":
            current["n"] = float(words[4])
            if current["n"] < 1.0:
                raise ValueError(f"{path.name}: a GLAS line without n_d")
    y, nu, n_before = 1.0, 0.0, 1.0
    inner = surfaces[1:-1]
    for i, s in enumerate(inner):
        nu = nu - y * s["c"] * (s["n"] - n_before)
        if i < len(inner) - 1:
            y += s["t"] * nu / s["n"]
        n_before = s["n"]
    return -1.0 / nu


def own_corpus_oracles() -> None:
    """lensrt's EFL of each loaded .zmx of the own corpus against optiland's paraxial trace, or where optiland
    cannot read the file, against ``line_nd_efl_mm``."""
    import optiland.backend as be
    from optiland.fileio import load_zemax_file
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    print("\n| file | lensrt EFL (mm) | oracle | oracle EFL (mm) | relative difference |\n| --- | --- | --- | --- | --- |")
    # against optiland, "EFL" is the rear focal length n'/Phi on both sides (= 1/Phi in air)
    for path in sorted(OWN.glob("*.zmx")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if try_load(path) != "ok":
                continue
            fo = first_order(load_lens(path))
            mine = fo.efl_mm
            try:  # optiland's f2 is the rear focal length n'/Phi (an immersion objective's image space is water)
                ref, how = float(be.to_numpy(load_zemax_file(str(path)).paraxial.f2())), "optiland"
                mine = fo.rear_focal_length_mm
            except Exception:  # noqa: BLE001 - optiland cannot read every file; fall back to the line's n_d
                ref, how = line_nd_efl_mm(path), "y-nu, line n_d"
        print(f"| `{path.name}` | {mine:.5f} | {how} | {ref:.5f} | {(mine - ref) / ref:+.1e} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--corpus", choices=("peers", "own", "all"), default="peers")
    ap.add_argument("--oracles", action="store_true", help="own corpus: compare EFLs with optiland / a y-nu trace")
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
    if args.corpus in ("own", "all"):
        results["own"] = own_corpus_report(opts)
        for name, r in results["own"].items():
            print(f"own       {name:40s} {r}")
    if args.oracles:
        own_corpus_oracles()
    if args.corpus == "own":
        if args.json:
            Path(args.json).write_text(json.dumps(results, indent=1))
        return
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
