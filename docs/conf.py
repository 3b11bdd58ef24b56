"""Sphinx configuration of the lensrt manual.

The API reference and the command-line reference are generated here, at build time, from the
package itself: :func:`write_api_pages` walks ``lensrt`` on disk (no hand-written list of module
paths, so it stays right when modules move) and writes one page per package into
``reference/api/``; :func:`write_cli_page` writes ``reference/cli-generated.md`` from lensrt's
argparse parser. Both folders are ignored by git.
"""
from __future__ import annotations

import os
import pkgutil
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))          # the lensrt of this tree, not an installed one

project = "lensrt"
author = "the lensrt developers"
copyright = "2026, the lensrt developers"  # noqa: A001 - Sphinx's name

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"              # the numpy docstrings give types (with units)

# napoleon turns every type in a docstring into a cross-reference; a bare class name that two
# modules define (``Spectrum``, ``Lens`` and its re-export) resolves to one of them with a warning
suppress_warnings = ["ref.python"]

html_theme = "alabaster"
html_title = "lensrt"
html_static_path: list[str] = []

#: modules the API reference leaves out: running them has side effects (``python -m lensrt``)
API_SKIP = {"lensrt.__main__"}
#: packages whose modules are internals of the command line: the CLI reference documents them
API_PACKAGE_DOCSTRING_ONLY = {"lensrt.commands"}


def _packages(root: Path, name: str) -> list[tuple[str, list[str]]]:
    """Every package under ``root`` (depth first) with its direct, public, non-package modules.

    Found on disk with :func:`pkgutil.iter_modules` (nothing is imported here), so the pages
    follow the package as it is: a moved or new module needs no edit of this file.
    """
    modules, found = [], []
    for info in sorted(pkgutil.iter_modules([str(root)]), key=lambda i: i.name):
        full = f"{name}.{info.name}"
        if full in API_SKIP or info.name.startswith("_"):   # private modules: internals
            continue
        if info.ispkg:
            found.extend(_packages(root / info.name, full))
        else:
            modules.append(full)
    return [(name, modules)] + found


def _page(package: str, modules: list[str]) -> str:
    title = f"``{package}``"
    lines = [title, "=" * len(title), "", f".. automodule:: {package}", "   :members:",
             "   :ignore-module-all:", ""]
    if package in API_PACKAGE_DOCSTRING_ONLY:
        return "\n".join(lines)
    for module in modules:
        head = f"``{module}``"
        lines += [head, "-" * len(head), "", f".. automodule:: {module}", "   :members:",
                  "   :ignore-module-all:", "   :show-inheritance:", ""]
    return "\n".join(lines)


def write_api_pages(out: Path = DOCS / "reference" / "api") -> list[str]:
    """Write ``index.rst`` and one page per lensrt package into ``out``; return the page names."""
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for package, modules in _packages(ROOT / "lensrt", "lensrt"):
        text = _page(package, modules)
        path = out / f"{package}.rst"
        if not path.exists() or path.read_text() != text:   # unchanged pages are not rebuilt
            path.write_text(text)
        names.append(package)
    for stale in out.glob("lensrt*.rst"):
        if stale.stem not in names:
            stale.unlink()
    index = ["Python API", "==========", "",
             "Generated from the numpy docstrings of every lensrt module, one page per package.", "",
             ".. toctree::", "   :maxdepth: 1", ""] + [f"   {n}" for n in names] + [""]
    text = "\n".join(index)
    if not (out / "index.rst").exists() or (out / "index.rst").read_text() != text:
        (out / "index.rst").write_text(text)
    return names


def _subcommands(parser, prefix: str):  # noqa: ANN001, ANN202
    """(command line, parser) for ``parser`` and every subcommand under it, depth first."""
    import argparse
    yield prefix, parser
    for action in parser._actions:  # argparse has no public walk over subparsers
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subcommands(sub, f"{prefix} {name}")


def write_cli_page(path: Path = DOCS / "reference" / "cli-generated.md") -> None:
    """Write every ``lensrt ... --help`` text into one MyST page."""
    os.environ["COLUMNS"] = "100"        # argparse wraps to the terminal: fix it
    from lensrt.cli import build_parser
    lines = ["# Every command's `--help`", "",
             "Generated at build time from `lensrt.cli.build_parser()`; the same text as "
             "`lensrt COMMAND --help`.", ""]
    for command, parser in _subcommands(build_parser(), "lensrt"):
        if command != "lensrt":
            lines += [f"## `{command}`", ""]
        lines += ["```text", parser.format_help().rstrip(), "```", ""]
    text = "\n".join(lines)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


_INLINE_MARKUP = re.compile(r"(``.*?``|:[a-z:]+:`[^`]*`|`[^`]*`)")


def escape_bars(app, what, name, obj, options, lines) -> None:  # noqa: ANN001, ARG001
    """Let docstrings write absolute values as plain text (``|m|``, ``|OTF|``).

    reStructuredText reads ``|name|`` as a substitution; outside literals and roles, a bar
    that does not start a line (a table or line block) is escaped before the docstring is parsed.
    """
    for i, line in enumerate(lines):
        stripped = line.strip()
        if "|" not in line or stripped == "|" or stripped.startswith(("| ", "+-", "+=")):
            continue
        parts = _INLINE_MARKUP.split(line)
        lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


#: napoleon's output for a numpy section entry whose "name" is a sentence
_PROSE_AS_FIELD = re.compile(r"^:(param|ivar|returns?|raises?) [^:]*\s[^:]*:")


def check_sections(app, what, name, obj, options, lines) -> None:  # noqa: ANN001, ARG001
    """Warn (an error under ``-W``) where napoleon read a paragraph as a parameter.

    A paragraph after a numpy ``Parameters`` or ``Attributes`` section still belongs to it;
    it belongs under a ``Notes`` heading. Runs after napoleon, on its reST output.
    """
    from sphinx.util import logging
    for line in lines:
        match = _PROSE_AS_FIELD.match(line)
        if match and not line.startswith(":param \\*"):
            logging.getLogger(__name__).warning(
                "docstring of %s: prose read as a field (%r): put it under a Notes heading",
                name, line[:60], type="lensrt", subtype="docstring")
            return


def setup(app) -> None:  # noqa: ANN001
    app.connect("autodoc-process-docstring", escape_bars)
    app.connect("autodoc-process-docstring", check_sections, priority=600)


write_api_pages()
write_cli_page()
