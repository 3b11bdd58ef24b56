"""Helpers shared by the subcommands: common options and output."""
from __future__ import annotations

import argparse
import sys
from typing import Any

__all__ = ["add_lens_argument", "print_json", "emit"]


def add_lens_argument(parser: argparse.ArgumentParser, optional: bool = True) -> None:
    """Positional ``FILE``: a lens file or a library lens name (default: the built-in lens)."""
    parser.add_argument("file", nargs="?" if optional else None, default=None, metavar="FILE",
                        help="lens file (.toml, .zmx, .seq, .dat) or library lens name; "
                             "default: the built-in 50 mm f/2 double Gauss")


def print_json(value: Any) -> None:
    from ..io.table import dumps_json
    sys.stdout.write(dumps_json(value) + "\n")


def emit(text: str) -> None:
    sys.stdout.write(text.rstrip("\n") + "\n")
