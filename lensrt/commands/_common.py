"""Helpers shared by the subcommands: common options and output."""
from __future__ import annotations

import argparse
import sys
from typing import Any

__all__ = ["add_lens_argument", "add_reader_options", "add_glass_options", "reader_options", "lens_config",
           "print_json", "emit"]


def add_lens_argument(parser: argparse.ArgumentParser, optional: bool = True) -> None:
    """Positional ``FILE``: a lens file or a library lens name (default: the built-in lens)."""
    parser.add_argument("file", nargs="?" if optional else None, default=None, metavar="FILE",
                        help="lens file (.toml, .zmx, .seq, .dat) or library lens name; "
                             "default: the built-in 50 mm f/2 double Gauss")
    parser.add_argument("--config", metavar="N|NAME", default=None,
                        help="configuration of a multi-configuration lens (zoom/focus position): a 1-based "
                             "number or a name (default: the file's current one)")


def lens_config(args: argparse.Namespace, allow_all: bool = False) -> str | None:
    """The ``--config`` value of :func:`add_lens_argument` (``"all"`` only where ``allow_all``)."""
    from ..errors import LensrtError
    value = getattr(args, "config", None)
    if value is not None and value.lower() == "all" and not allow_all:
        raise LensrtError("--config all is not available for this command",
                          hint="give one configuration (a number or a name); lensrt info and report take all")
    return value


def add_reader_options(parser: argparse.ArgumentParser) -> None:
    """``--format`` and the format-specific reader options (``--pbrt-thickness``, ``--pbrt-field-deg``)."""
    parser.add_argument("--format", choices=["native", "zemax", "codev", "pbrt"],
                        help="file format (default: from the extension)")
    parser.add_argument("--pbrt-thickness", choices=["auto", "next", "previous"], default=None,
                        help="pbrt tables: column 2 is the distance to the next surface (scaled *.NNmm.dat) or "
                             "from the previous one (unscaled 'axpos' tables); default: detected")
    parser.add_argument("--pbrt-field-deg", type=float, default=None, metavar="DEG",
                        help="pbrt tables: largest field half-angle (default: the paraxial chief-ray limit)")
    parser.add_argument("--aperture-rule", choices=["every_surface", "opticstudio"], default=None,
                        help="which semi-diameters vignette: every_surface (every element's clear aperture, the "
                             "photographic reading of pbrt's tables; the default) or opticstudio (only "
                             "user-defined semi-diameters and surface apertures)")
    add_glass_options(parser)


def add_glass_options(parser: argparse.ArgumentParser) -> None:
    """``--glass-catalog``, ``--glass-substitute``, ``--glass-model-fallback`` (docs/guide/glass.md)."""
    parser.add_argument("--glass-catalog", action="append", default=None, metavar="PATH",
                        help="a Zemax .agf glass catalog (or a folder of them) to search; repeatable")
    parser.add_argument("--glass-substitute", action="store_true", default=None,
                        help="accept a successor or equivalent glass (SK16 -> N-SK16) for a name no catalog holds, "
                             "with a warning")
    parser.add_argument("--glass-model-fallback", action="store_true", default=None,
                        help="use a file's n_d/V_d for a glass no catalog holds, with a warning")


def reader_options(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments for :func:`lensrt.loading.load_lens` from :func:`add_reader_options`' options."""
    opts: dict[str, Any] = {"format": getattr(args, "format", None)}
    for key in ("pbrt_thickness", "pbrt_field_deg", "aperture_rule", "glass_catalog", "glass_substitute",
                "glass_model_fallback"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    return opts


def print_json(value: Any) -> None:
    """Write ``value`` as JSON; a dict gets the command's ``telemetry`` so far (:mod:`lensrt.core.telemetry`)."""
    from ..core.telemetry import snapshot
    from ..io.table import dumps_json
    rec = snapshot()
    if isinstance(value, dict) and rec is not None and "telemetry" not in value:
        value = {**value, "telemetry": rec}
    sys.stdout.write(dumps_json(value) + "\n")


def emit(text: str) -> None:
    sys.stdout.write(text.rstrip("\n") + "\n")
