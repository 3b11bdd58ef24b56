"""The lens library (``lens_prescriptions/``) and the built-in scenes (``scenes/``)."""
from __future__ import annotations

from pathlib import Path

from .errors import LensrtError

__all__ = ["DEFAULT_LENS", "library_dir", "library_lenses", "resolve_lens_path", "scenes_dir"]

#: the built-in default lens: a 50 mm f/2 double Gauss
DEFAULT_LENS = "dgauss_50mm_f2"


def _data_dir(name: str) -> Path:
    here = Path(__file__).resolve().parent
    for cand in (here.parent / name, here / name):
        if cand.is_dir():
            return cand
    raise LensrtError(f"lensrt's {name}/ folder is missing from this installation",
                      hint="reinstall lensrt (pip install -e .)")


def library_dir() -> Path:
    """Folder of the native lens library."""
    return _data_dir("lens_prescriptions")


def scenes_dir() -> Path:
    """Folder of the built-in scenes."""
    return _data_dir("scenes")


def library_lenses() -> list[Path]:
    """All library lens files, sorted by name."""
    return sorted(library_dir().glob("*.toml"))


def resolve_lens_path(name: str | Path | None) -> Path:
    """A path for ``name``: an existing file, or a library lens by stem (``None`` = default)."""
    if name is None:
        name = DEFAULT_LENS
    p = Path(name)
    if p.exists():
        return p
    if p.parent == Path("."):
        # a library name may contain dots (nikkor_50mm_f1.4): try NAME.toml, then NAME as NAME.toml
        for cand in (library_dir() / (p.name + ".toml"), library_dir() / p.name):
            if cand.suffix == ".toml" and cand.exists():
                return cand
    if p.parent == Path(".") and p.suffix.lower() not in (".toml", ".zmx", ".seq", ".dat"):
        names = ", ".join(q.stem for q in library_lenses())
        raise LensrtError(f"no lens file or library lens named {str(name)!r}",
                          hint=f"library lenses: {names}")
    return p  # the reader reports "file not found" with the path
