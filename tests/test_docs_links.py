"""The README and the manual's markdown pages link only to files that exist.

Fast (no Sphinx run): every relative link and image target in README.md, CHANGELOG.md and
docs/**/*.md, outside code blocks and inline code, must name an existing file or folder. The
Sphinx build in CI (``-W``) checks the rest of the manual; this keeps the README, which GitHub
and PyPI show without Sphinx, from rotting. Every module, file and test the pages name
(``lensrt.analysis.psf.map``, ``trace/api.py``, ``tests/trace/test_trace_kernels.py``) must exist,
and every ``from lensrt... import ...`` line of its examples must import, so a move that
forgets the manual fails here. It also holds the README to its two promises:
the test command CI runs is the README's, verbatim, and the README stays a README (<= 250 lines).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: pages written by docs/conf.py at build time (not in a fresh clone)
GENERATED = ("docs/reference/api/", "docs/reference/cli-generated.md", "docs/_build/")

LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
INLINE_CODE = re.compile(r"(`+).*?\1")


def markdown_pages() -> list[Path]:
    pages = [README, ROOT / "CHANGELOG.md"]
    pages += sorted(p for p in (ROOT / "docs").rglob("*.md")
                    if not str(p.relative_to(ROOT)).startswith(GENERATED))
    return [p for p in pages if p.exists()]


def relative_targets(text: str) -> list[tuple[int, str]]:
    """(line number, target) of every relative link or image outside code."""
    found, fence = [], None
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.lstrip()
        if stripped.startswith(("```", "~~~")):
            mark = stripped[:3]
            fence = None if fence == mark else (fence or mark)
            continue
        if fence:
            continue
        for target in LINK.findall(INLINE_CODE.sub("", line)):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # http:, mailto:, in-page anchors
            found.append((number, target.split("#", 1)[0]))
    return found


#: a dotted lensrt name, a path under lensrt/, tests/ or benchmarks/, or a path inside lensrt
#: that starts at a stage folder (``trace/api.py``)
CODE_NAME = re.compile(r"(?<![\w/.-])(lensrt(?:\.\w+)+|(?:lensrt|tests|benchmarks)/[\w/*]+\.py|"
                       r"[a-z_]+/[\w/*]*\w\.py)")


def missing_code_names(text: str) -> list[str]:
    """Names of lensrt modules (and their attributes) and files in ``text`` that do not exist."""
    missing = []
    for name in dict.fromkeys(CODE_NAME.findall(text)):
        if "/" in name:
            path = name if name.startswith(("lensrt/", "tests/", "benchmarks/")) else f"lensrt/{name}"
            if not (name.split("/")[0] in {"lensrt", "tests", "benchmarks"} or (ROOT / "lensrt" / name.split("/")[0]).is_dir()):
                continue  # a path outside the package (docs/conf.py, out/psf.py)
            if not list(ROOT.glob(path)):
                missing.append(name)
            continue
        parts = name.rstrip(".").split(".")
        for k in range(len(parts), 0, -1):  # the longest prefix that is a module or package
            base = ROOT.joinpath(*parts[:k])
            source = base.with_suffix(".py") if base.with_suffix(".py").exists() else base / "__init__.py"
            if source.exists():
                break
        else:
            missing.append(name)
            continue
        if k < len(parts) and not re.search(rf"\b{re.escape(parts[k])}\b", source.read_text()):
            missing.append(name)  # an attribute its module does not define or re-export
    return missing


def test_link_pattern_finds_links_and_images_but_not_code() -> None:
    text = ("see [a](docs/a.md#x) and ![b](img/b.png), [web](https://x.org), [here](#top)\n"
            "`[not](code.md)`\n```\n[not](fenced.md)\n```\n")
    assert relative_targets(text) == [(1, "docs/a.md"), (1, "img/b.png")]


@pytest.mark.parametrize("page", markdown_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_and_images_exist(page: Path) -> None:
    missing = [f"{page.relative_to(ROOT)}:{n}: {t}" for n, t in relative_targets(page.read_text())
               if not (page.parent / t).exists()]
    assert not missing, "links to files that do not exist:\n" + "\n".join(missing)


def test_code_name_check_finds_moved_modules() -> None:
    text = ("`lensrt.trace.stream` `lensrt.trace.no_such_module` `lensrt.paraxial.first_order.no_such_name` "
            "`trace/api.py` `trace/gone.py` `tests/test_docs_links.py` `docs/conf.py`")
    assert missing_code_names(text) == ["lensrt.trace.no_such_module", "lensrt.paraxial.first_order.no_such_name",
                                        "trace/gone.py"]


@pytest.mark.parametrize("page", markdown_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_modules_and_files_named_exist(page: Path) -> None:
    missing = missing_code_names(page.read_text())
    assert not missing, f"{page.relative_to(ROOT)} names modules or files that do not exist: {missing}"


IMPORT_LINE = re.compile(r"^\s*(from lensrt[\w.]* import [\w, ]+\w|import lensrt[\w.]*)\s*(?:#.*)?$", re.M)


@pytest.mark.parametrize("page", markdown_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_python_imports_in_examples_work(page: Path) -> None:
    """Every ``from lensrt... import ...`` line of the page's examples imports."""
    failed = []
    for line in dict.fromkeys(IMPORT_LINE.findall(page.read_text())):
        try:
            exec(line, {})  # noqa: S102 - the page's own import line
        except ImportError as err:
            failed.append(f"{line}: {err}")
    assert not failed, f"{page.relative_to(ROOT)}:\n" + "\n".join(failed)


def test_readme_has_images_and_links() -> None:
    targets = [t for _, t in relative_targets(README.read_text())]
    assert any(t.endswith(".png") for t in targets) and any(t.endswith(".md") for t in targets)


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    command = next(line for line in ci if "pytest" in line and not line.startswith("#"))
    assert command in README.read_text().splitlines()


def test_readme_stays_short() -> None:
    assert len(README.read_text().splitlines()) <= 250
