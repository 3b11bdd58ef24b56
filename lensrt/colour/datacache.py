"""colour-science's tables kept on disk, so that a process reads them without importing colour-science.

``import colour`` executes the whole package (colour.plotting, pandas, ...): about 0.8 s on a 2-core
CPU and more on a machine whose site-packages hold no bytecode, for a few kilobytes of CIE tables.
Each module of :mod:`lensrt.colour` that reads a table from colour-science keeps doing so, in a
*build* function; :func:`cached_tables` runs that build once per colour-science version and keeps
its arrays in a NumPy ``.npz`` file:

``$LENSRT_CACHE/colour/<name>-colour-science-<version>-v<FORMAT>.npz`` (``LENSRT_CACHE`` unset:
``~/.cache/lensrt``).

The file is written on first use (atomically: a temporary file, then a rename, so concurrent
processes never see half a file), read back as the exact float64 arrays colour-science gave, and
rebuilt from colour-science when it is missing, unreadable, or holds another key. A folder that
cannot be written only costs the import (the tables are then built in memory). A new colour-science
version has a new file name, so an upgrade never reads the old tables.
"""
from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = ["FORMAT", "cache_dir", "cache_path", "cached_tables", "colour_science_version", "clear_memo"]

#: layout version of the files (part of the file name and of the key stored in each file)
FORMAT = 1
_KEY = "__lensrt_key__"

_MEMO: dict[str, dict[str, np.ndarray]] = {}
_LOCK = threading.Lock()
_VERSION: list[str | None] = []


def colour_science_version() -> str | None:
    """The installed colour-science version (package metadata; colour-science is not imported), or None."""
    if not _VERSION:
        from importlib import metadata
        try:
            _VERSION.append(metadata.version("colour-science"))
        except metadata.PackageNotFoundError:
            _VERSION.append(None)
    return _VERSION[0]


def cache_dir() -> Path:
    """The folder of the table files: ``$LENSRT_CACHE/colour``, else ``~/.cache/lensrt/colour``."""
    base = os.environ.get("LENSRT_CACHE")
    return (Path(base) if base else Path.home() / ".cache" / "lensrt") / "colour"


def cache_path(name: str) -> Path | None:
    """The file of table set ``name`` for the installed colour-science (None when its version is unknown)."""
    version = colour_science_version()
    if version is None:
        return None
    return cache_dir() / f"{name}-colour-science-{version}-v{FORMAT}.npz"


def _key(name: str) -> str:
    return f"{name}|colour-science {colour_science_version()}|format {FORMAT}"


def _read(path: Path, name: str) -> dict[str, np.ndarray] | None:
    """The arrays of ``path`` if it is a complete table file of ``name``, else None."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        return None
    except Exception:  # truncated or foreign file (BadZipFile, ValueError, OSError, EOFError, ...): rebuild
        return None
    key = arrays.pop(_KEY, None)
    if key is None or key.shape != () or str(key) != _key(name):
        return None
    return arrays


def _write(path: Path, name: str, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` to ``path`` atomically; an unwritable folder is skipped."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    except OSError:
        return
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays, **{_KEY: np.array(_key(name))})
        os.replace(tmp, path)
    except OSError:
        pass
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def cached_tables(name: str, build: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The arrays of table set ``name``: from memory, else its file, else ``build()`` (written to the file).

    ``build`` reads colour-science and returns plain arrays (numbers or strings, no objects). The
    arrays returned are read-only and shared: copy before changing them.
    """
    hit = _MEMO.get(name)
    if hit is not None:
        return hit
    with _LOCK:
        hit = _MEMO.get(name)
        if hit is not None:
            return hit
        path = cache_path(name)
        arrays = _read(path, name) if path is not None else None
        if arrays is None:
            arrays = {k: np.array(v) for k, v in build().items()}  # copies: colour-science keeps its own
            if path is not None:
                _write(path, name, arrays)
        for a in arrays.values():
            a.flags.writeable = False
        _MEMO[name] = arrays
        return arrays


def clear_memo() -> None:
    """Forget the tables held in memory (the next use reads the files again)."""
    with _LOCK:
        _MEMO.clear()
