"""The README and the manual's markdown pages link only to files that exist.

Fast (no Sphinx run): every relative link and image target in README.md, CHANGELOG.md and
docs/**/*.md, outside code blocks and inline code, must name an existing file or folder. The
Sphinx build in CI (``-W``) checks the rest of the manual; this keeps the README, which GitHub
and PyPI show without Sphinx, from rotting. It also holds the README to its two promises:
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


def test_link_pattern_finds_links_and_images_but_not_code() -> None:
    text = ("see [a](docs/a.md#x) and ![b](img/b.png), [web](https://x.org), [here](#top)\n"
            "`[not](code.md)`\n```\n[not](fenced.md)\n```\n")
    assert relative_targets(text) == [(1, "docs/a.md"), (1, "img/b.png")]


@pytest.mark.parametrize("page", markdown_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_and_images_exist(page: Path) -> None:
    missing = [f"{page.relative_to(ROOT)}:{n}: {t}" for n, t in relative_targets(page.read_text())
               if not (page.parent / t).exists()]
    assert not missing, "links to files that do not exist:\n" + "\n".join(missing)


def test_readme_has_images_and_links() -> None:
    targets = [t for _, t in relative_targets(README.read_text())]
    assert any(t.endswith(".png") for t in targets) and any(t.endswith(".md") for t in targets)


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    command = next(line for line in ci if "pytest" in line and not line.startswith("#"))
    assert command in README.read_text().splitlines()


def test_readme_stays_short() -> None:
    assert len(README.read_text().splitlines()) <= 250
