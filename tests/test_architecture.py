"""The package's floor plan, checked: imports point down the floors, no import cycles, no private names
borrowed across modules, no overlong functions.

Every ``import``/``from ... import`` in ``lensrt/`` is read with :mod:`ast` (function-local ones too), so the
graph checked here is the real one. The floors are the pipeline's order (see docs/architecture.md):
a module may import its own package (top-level stage folder) and any package on a LOWER floor, never one on
its own floor or above.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "lensrt"

#: floors, bottom first; names are the first component under ``lensrt`` (a folder or a top-level module)
FLOORS: list[set[str]] = [
    {"core", "units", "errors", "stats", "device"},
    {"colour", "prescription", "parallel", "library"},
    {"paraxial", "sensor"},
    {"trace", "io", "isp"},
    {"loading"},
    {"analysis", "render"},
    {"pipeline", "views", "studies", "simulate"},
    {"report"},
    {"cli", "commands", "__main__", "__init__"},
]

#: (importing stage, imported stage) -> the one-line reason it is allowed; keep this empty
ALLOWED_UP: dict[tuple[str, str], str] = {}

#: known violations being removed, each with its reason; keep this empty
PENDING: dict[str, str] = {}

#: the longest a function may be (lines, decorators excluded)
MAX_FUNCTION_LINES = 120


def _modules() -> dict[str, Path]:
    mods = {}
    for p in sorted(ROOT.rglob("*.py")):
        rel = p.relative_to(ROOT.parent).with_suffix("")
        name = ".".join(rel.parts)
        mods[name.removesuffix(".__init__")] = p
    return mods


MODULES = _modules()


def _stage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _floor(stage: str) -> int:
    for i, names in enumerate(FLOORS):
        if stage in names:
            return i
    raise AssertionError(f"lensrt.{stage} is on no floor: add it to FLOORS in tests/test_architecture.py")


def _imports(module: str, path: Path) -> list[tuple[str, str, int]]:
    """(imported module, imported name or '', line) for every lensrt import in ``module``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    package = module if is_pkg else module.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            if not base.startswith("lensrt"):
                continue
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in MODULES:
                    out.append((full, "", node.lineno))
                else:
                    out.append((base, alias.name, node.lineno))
        elif isinstance(node, ast.Import):
            out += [(a.name, "", node.lineno) for a in node.names if a.name.startswith("lensrt")]
    return out


def _graph() -> dict[str, set[str]]:
    graph = {m: set() for m in MODULES}
    for m, p in MODULES.items():
        for target, _, _ in _imports(m, p):
            if target in MODULES and target != m:
                graph[m].add(target)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), package faces left out."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def _faceless(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph without package faces (``__init__`` re-exports are not dependencies of the code)."""
    faces = {m for m, p in MODULES.items() if p.name == "__init__.py"}
    return {m: {t for t in ts if t not in faces} for m, ts in graph.items() if m not in faces}


def test_every_stage_is_on_a_floor():
    for m in MODULES:
        _floor(_stage(m))


def test_no_import_cycles():
    cycles = [c for c in _cycles(_faceless(_graph())) if "cycle " + " <-> ".join(c) not in PENDING]
    assert not cycles, "import cycles among lensrt modules:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_imports_point_down_the_floors():
    bad = []
    for m, p in MODULES.items():
        if p.name == "__init__.py" and m == "lensrt":
            continue  # the package face re-exports from every floor, lazily
        src = _stage(m)
        for target, _, line in _imports(m, p):
            dst = _stage(target)
            if dst == src or (src, dst) in ALLOWED_UP:
                continue
            if _floor(dst) == _floor(src) in (0, len(FLOORS) - 1):
                continue  # the leaf modules of the bottom floor, and the command line, may use each other
            if _floor(dst) >= _floor(src):
                bad.append(f"{p.relative_to(ROOT.parent)}:{line}: {m} -> {target} "
                           f"(floor {_floor(src)} imports floor {_floor(dst)})")
    assert not bad, "imports that do not point down the floors:\n" + "\n".join(bad)


def test_no_private_name_crosses_a_module():
    bad = []
    for m, p in MODULES.items():
        for target, name, line in _imports(m, p):
            if target != m and name.startswith("_") and not name.startswith("__") \
                    and f"private {p.relative_to(ROOT.parent)}: {name}" not in PENDING:
                bad.append(f"{p.relative_to(ROOT.parent)}:{line}: from {target} import {name}")
    assert not bad, "private names imported from another module:\n" + "\n".join(bad)


def test_no_function_is_too_long():
    bad = []
    for m, p in MODULES.items():
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES and f"long {p.relative_to(ROOT.parent)}: {node.name}" not in PENDING:
                    bad.append(f"{p.relative_to(ROOT.parent)}:{node.lineno}: {node.name} is {n} lines")
    assert not bad, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(bad)


@pytest.mark.parametrize("package", sorted(m for m, p in MODULES.items()
                                           if p.name == "__init__.py" and m.count(".") >= 1))
def test_every_package_face_says_what_it_offers(package):
    doc = ast.get_docstring(ast.parse(MODULES[package].read_text(encoding="utf-8")))
    assert doc and len(doc.split()) >= 5, f"{package}/__init__.py needs a docstring saying what it offers"
