"""Lazy package faces (PEP 562): a package lists its public names and the module defining each, and the
module is imported on first use, so that ``import lensrt.analysis.psf`` stays cheap.

Usage, in a package's ``__init__.py``::

    from ..core.lazy import lazy_face
    __getattr__, __all__ = lazy_face(__name__, {"PsfResult": "result", "psf_at": "map"})
"""
from __future__ import annotations

from importlib import import_module
from typing import Any, Callable

__all__ = ["lazy_face"]


def lazy_face(package: str, exports: dict[str, str]) -> tuple[Callable[[str], Any], list[str]]:
    """A module ``__getattr__`` that imports ``package.<module>`` for each public name, and ``__all__``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : dict
        Public name -> the name of the module (inside ``package``) that defines it.
    """
    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(import_module(f"{package}.{exports[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__, sorted(exports)
