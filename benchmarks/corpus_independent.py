"""Load rate and focal-length sanity on public lens files that lensrt does NOT ship (issue 25's "independent set").

Files come from the repository snapshots that the session's ``fetch`` tool mirrors (``--mirror-root``, default
``/work/.mirror``: one bare git directory per repository, ``owner+name/repo``), read straight from git, or from
paths given on the command line. Excluded: every file whose text equals one the project ships
(``tests/data/**``) or one of the peer corpora (rayoptics' and optiland's test folders), and any path inside a
``tests`` folder of rayoptics or optiland (:data:`PEER_REPOS`). At most ``--max-per-repo`` files per repository, drawn with ``--seed``.

For each file: loads, or the refusal's first line (grouped by the rules of ``tests/prescription/test_corpus.py``),
or a traceback (a bug). For each Zemax file whose GLAS lines carry n_d (and no mirror or coordinate break),
lensrt's paraxial EFL is compared with an independent y-nu trace through those n_d
(``corpus_load.line_nd_efl_mm``, no lensrt code): a difference over 1 % with no approximation warning from
lensrt would be a *silently* wrong focal length, the failure the issue names; over 1 % with a warning is visible.

    PYTHONPATH=. python benchmarks/corpus_independent.py [--mirror-root DIR] [--max-per-repo N] [--seed S]
        [--json PATH] [FILE ...]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import random
import subprocess
import sys
import tempfile
import warnings
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import corpus_load  # noqa: E402 - the sibling benchmark: try_load, line_nd_efl_mm, the corpus rules

EXTENSIONS = (".zmx", ".seq")
#: repositories whose test folders the peer corpora are (issue 22/24 use them): no file under a ``tests`` folder
PEER_REPOS = ("mjhoptics/ray-optics", "HarrisonKramer/optiland")


def _digest(data: bytes) -> str:
    """Hash of a lens file's text, blind to encoding (OpticStudio's UTF-16 or UTF-8) and to whitespace."""
    text = data.decode("utf-16", errors="replace") if data[:2] in (b"\xff\xfe", b"\xfe\xff") else \
        data.decode("utf-8", errors="replace")
    return hashlib.sha1(" ".join(text.split()).encode()).hexdigest()


def shipped_digests() -> set[str]:
    """Digests of every lens file the project ships and of the peer corpora."""
    files = [p for p in (ROOT / "tests" / "data").rglob("*") if p.suffix.lower() in EXTENSIONS + (".dat",)]
    try:
        files += corpus_load.rayoptics_files()
    except ImportError:  # pragma: no cover - rayoptics is a test-only oracle
        pass
    return {_digest(p.read_bytes()) for p in files}


def mirror_files(root: Path, max_per_repo: int, seed: int, out: Path, skip: set[str]) -> list[tuple[str, Path]]:
    """Lens files of every mirrored repository, written to ``out``: [(repo/path@commit, local path)]."""
    chosen = []
    for git_dir in sorted(root.glob("*/repo")):
        repo = git_dir.parent.name.replace("+", "/", 1)
        rng = random.Random(f"{seed}:{repo}")  # per repository: adding a mirror leaves the others' draws alone
        run = lambda *a: subprocess.run(["git", "-C", str(git_dir), *a], capture_output=True, check=True).stdout
        try:
            commit = run("rev-parse", "HEAD").decode().strip()
            names = run("ls-tree", "-r", "--name-only", "-z", "HEAD").decode().split("\0")
        except subprocess.CalledProcessError:
            continue
        names = [n for n in names if n.lower().endswith(EXTENSIONS)
                 and not (repo in PEER_REPOS and "tests/" in n)]
        rng.shuffle(names)
        taken, seen = 0, set()
        for name in names:
            if taken >= max_per_repo:
                break
            try:
                data = run("show", f"HEAD:{name}")
            except subprocess.CalledProcessError:
                continue  # a file the snapshot lists but does not hold
            key = _digest(data)
            if key in skip or key in seen:
                continue
            seen.add(key)
            local = out / f"{len(chosen):03d}_{Path(name).name}"
            local.write_bytes(data)
            chosen.append((f"{repo}/{name}@{commit[:12]}", local))
            taken += 1
    return chosen


def check_file(path: Path, rules) -> dict:
    """Load one file; its EFL against the GLAS lines' n_d where the file allows the independent trace."""
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    from lensrt.prescription.formats import read_text
    status = corpus_load.try_load(path)
    row = {"status": "ok" if status == "ok" else "traceback" if status.startswith("TRACEBACK") else "refused"}
    if row["status"] != "ok":
        row["reason"] = rules.refusal_rule(status) or f"other: {status.split(': ', 1)[-1][:70]}"
        return row
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lens = load_lens(path)
        row["efl_mm"] = float(first_order(lens).efl_mm)
    row["warnings"] = sorted({w.code for w in lens.warnings})
    text = read_text(path)
    if path.suffix.lower() == ".zmx" and "MIRROR" not in text and "COORDBRK" not in text:
        try:
            row["line_nd_efl_mm"] = corpus_load.line_nd_efl_mm(path, text)
        except (ValueError, IndexError, ZeroDivisionError):
            pass  # GLAS lines without n_d: no independent value
    return row


def report(rows: dict[str, dict]) -> None:
    """Markdown: load rate, refusal reasons, EFL sanity."""
    n = len(rows)
    ok = sum(r["status"] == "ok" for r in rows.values())
    tb = sum(r["status"] == "traceback" for r in rows.values())
    repos = {k.split("/")[0] + "/" + k.split("/")[1] for k in rows}
    print(f"\n**{ok}/{n} load ({ok / max(n, 1):.0%}) from {len(repos)} repositories, {tb} tracebacks.**\n")
    print("| refusal reason | files |\n| --- | --- |")
    for reason, count in Counter(r["reason"] for r in rows.values() if r["status"] != "ok").most_common():
        print(f"| {reason} | {count} |")
    checked = {k: r for k, r in rows.items() if "line_nd_efl_mm" in r}
    off = {k: r for k, r in checked.items() if abs(r["efl_mm"] / r["line_nd_efl_mm"] - 1.0) > 0.01}
    silent = {k: r for k, r in off.items() if not r["warnings"]}
    print(f"\nEFL against a y-nu trace with the GLAS lines' n_d: {len(checked)} files checked, "
          f"{len(checked) - len(off)} within 1 %, {len(off) - len(silent)} off by more with a warning, "
          f"**{len(silent)} silently off**.\n")
    if off:
        print("| file | lensrt EFL (mm) | line-n_d EFL (mm) | difference | lensrt's warnings |")
        print("| --- | --- | --- | --- | --- |")
        for k, r in sorted(off.items()):
            print(f"| `{k}` | {r['efl_mm']:.4f} | {r['line_nd_efl_mm']:.4f} | "
                  f"{r['efl_mm'] / r['line_nd_efl_mm'] - 1:+.2%} | {', '.join(r['warnings']) or 'none'} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path, help="lens files to measure instead of the mirrors")
    ap.add_argument("--mirror-root", type=Path, default=Path("/work/.mirror"))
    ap.add_argument("--max-per-repo", type=int, default=25)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", metavar="PATH")
    args = ap.parse_args()
    rules = corpus_load._corpus_test_module()
    with tempfile.TemporaryDirectory() as tmp:
        if args.files:
            chosen = [(str(p), p) for p in args.files]
        else:
            chosen = mirror_files(args.mirror_root, args.max_per_repo, args.seed, Path(tmp), shipped_digests())
        rows = {}
        for key, path in chosen:
            rows[key] = check_file(path, rules)
            r = rows[key]
            detail = r.get("reason") or "EFL {:.4f} mm".format(r["efl_mm"])
            print(f"{r['status']:9s} {key}  {detail}")
    report(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
