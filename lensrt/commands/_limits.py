"""Argument ranges checked where they are parsed, and the budget options (``--max-memory``, ``--max-rays``).

Shared by the subcommands: seeds, counts, file stems and the flags that raise the limits of
:mod:`lensrt.core.budget`. Each check ends in one :class:`~lensrt.errors.LensrtError` line (or argparse's
own one-line error for ``type=`` converters) naming the argument.
"""
from __future__ import annotations

import argparse
import math
import re

from ..core.budget import MAX_RAYS_PER_POINT, check_count, parse_memory
from ..errors import LensrtError

__all__ = ["MAX_COUNT", "parse_count", "MAX_SEED", "parse_seed", "add_max_memory_argument", "memory_limit",
           "add_max_rays_argument", "check_rays", "safe_stem", "positive_int", "check_psf_budget"]

#: seeds are unsigned 63-bit integers (Warp's rand_init and numpy's SeedSequence both take them)
MAX_SEED = (1 << 63) - 1


#: the largest ray count :func:`parse_count` takes (2^62: the stream kernels' 2^32 epochs of 2^30 rays)
MAX_COUNT = 1 << 62


def parse_count(text: str) -> int:
    """``"1e6"`` or ``"1000000"`` -> 1000000."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v >= 1):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive count")
    if v > MAX_COUNT:  # ray indices and seeds are 64-bit: beyond this the randomisation would repeat
        raise argparse.ArgumentTypeError(f"{text!r} is more than 2^62 ({MAX_COUNT:.3g})")
    return int(round(v))


def parse_seed(text: str) -> int:
    """argparse ``type=``: a seed in 0 .. 2^63 - 1."""
    try:
        v = int(str(text).strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"seed {text!r} is not an integer") from None
    if not 0 <= v <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"seed {text} must be in 0 .. 2^63-1")
    return v


def positive_int(text: str) -> int:
    """argparse ``type=``: an integer >= 1."""
    try:
        v = int(str(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text} must be at least 1")
    return v


def add_max_memory_argument(p: argparse.ArgumentParser) -> None:
    """``--max-memory SIZE``: the memory limit of :func:`lensrt.core.budget.check_memory`."""
    p.add_argument("--max-memory", metavar="SIZE", default=None,
                   help="refuse jobs estimated to need more memory than this (e.g. 16G; default: 80%% of the "
                        "memory available)")


def memory_limit(args: argparse.Namespace) -> int | None:
    """The ``--max-memory`` limit in bytes, or None for the default."""
    text = getattr(args, "max_memory", None)
    return None if text is None else parse_memory(text)


def add_max_rays_argument(p: argparse.ArgumentParser) -> None:
    """``--max-rays N``: the cap of :func:`check_rays`."""
    p.add_argument("--max-rays", type=parse_count, default=None, metavar="N",
                   help=f"allow more than {MAX_RAYS_PER_POINT:.0e} rays per field point or source")


def check_rays(args: argparse.Namespace, rays: float, what: str = "--rays") -> None:
    """Refuse a ray count above ``--max-rays`` (default :data:`lensrt.core.budget.MAX_RAYS_PER_POINT`)."""
    cap = getattr(args, "max_rays", None) or MAX_RAYS_PER_POINT
    check_count(float(rays), float(cap), f"{what} {rays:.3g} per point", "--max-rays")


def safe_stem(name: str, what: str = "--name") -> str:
    """A file-name stem that stays inside its output folder: no path separators, no '..', printable."""
    text = str(name)
    if (not text or text in (".", "..") or "/" in text or "\\" in text or "\0" in text
            or not re.fullmatch(r"[\w.+\-=@,]+", text)):
        raise LensrtError(f"{what} {name!r} is not a plain file name",
                          hint="use letters, digits and . _ - + without folders (the folder is --out)")
    return text


def check_psf_budget(args: argparse.Namespace, n_fields: int = 1) -> None:
    """``psf``/``mtf``: the ray cap per field point and the memory of ``n_fields`` PSF grids (and pupils)."""
    from ..core.budget import check_memory, estimate_psf_bytes
    check_rays(args, float(args.rays))
    diffraction = getattr(args, "method", "geometric") != "geometric"
    lines = getattr(args, "lines", 1) if getattr(args, "spectrum", None) else 7
    if getattr(args, "lines", 1) < 1:
        raise LensrtError(f"--lines {args.lines} must be at least 1")
    check_memory(estimate_psf_bytes(n_fields, int(args.pixels), int(args.batches), int(args.pupil_samples),
                                    diffraction, lines), memory_limit(args))
