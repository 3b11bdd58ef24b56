"""``lensrt`` command line: subcommands are thin wrappers over the pipeline stages.

Each module in :mod:`lensrt.commands` registers its subcommands; heavy imports
happen inside the command functions, so ``lensrt --help`` stays fast. Bad
input ends in one ``lensrt: error: ...`` line and exit status 2, never a
traceback (set ``LENSRT_DEBUG=1`` to see one for unexpected errors).
"""
from __future__ import annotations

import argparse
import os
import sys
from importlib import import_module
from typing import Sequence

from . import __version__
from .errors import LensrtError

__all__ = ["main", "build_parser", "COMMAND_MODULES"]

#: modules of lensrt.commands, in the order their subcommands appear in --help
COMMAND_MODULES = ("lens", "info", "glass", "ray", "compare", "psf", "mtf", "wavefront", "bokeh", "render",
                   "sensor", "converge", "report", "sweep", "simulate")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lensrt", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"lensrt {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        try:
            module = import_module(f"lensrt.commands.{name}")
        except ModuleNotFoundError as err:
            if err.name == f"lensrt.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    """Warnings (a glass taken from a file's n_d/V_d, an extrapolated index) as one stderr line."""
    print(f"lensrt: warning: {message}", file=sys.stderr if file is None else file)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status."""
    import warnings
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command line, for reports that record it
    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        return int(args.func(args) or 0)
    except LensrtError as err:
        print(f"lensrt: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("lensrt: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as err:  # noqa: BLE001 - the last line of defence against tracebacks
        if os.environ.get("LENSRT_DEBUG"):
            raise
        print(f"lensrt: internal error: {type(err).__name__}: {err} "
              "(this is a bug in lensrt; rerun with LENSRT_DEBUG=1 for the traceback)", file=sys.stderr)
        return 3
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
