"""Output paths: folders made on demand, and a :class:`LensrtError` (not an ``OSError``) when a
path given for output cannot be used (a parent that is a file, no permission, a folder where a
file should go)."""
from __future__ import annotations

from pathlib import Path

from ..errors import LensrtError

__all__ = ["output_dir", "output_file"]


def output_dir(path: str | Path) -> Path:
    """Create the output folder ``path`` (and its parents) if needed; returns it as a Path."""
    p = Path(path)
    existing = next((q for q in (p, *p.parents) if q.exists()), None)
    if existing is not None and not existing.is_dir():
        raise LensrtError(f"{existing} is a file, not a folder for the output", hint="choose another output path")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise LensrtError(f"cannot create the output folder {p}: {err.strerror or err}",
                          hint="choose another output path") from None
    return p


def output_file(path: str | Path, suffix: str | None = None) -> Path:
    """Create the folder of the output file ``path`` if needed; returns ``path`` as a Path.

    ``suffix`` (e.g. ``".exr"``): the file format being written, which the name must say.
    """
    p = Path(path)
    if suffix is not None and p.suffix.lower() != suffix:
        raise LensrtError(f"{p}: this output is written as {suffix[1:].upper()}, so its name must end in {suffix}",
                          hint=f"rename it (e.g. {p.with_suffix(suffix).name})")
    if p.is_dir():
        raise LensrtError(f"{p} is a folder, not a file name for the output", hint="add a file name")
    output_dir(p.parent)
    return p
