"""One error type for bad input, carrying where it happened and what to do.

Every problem with a user's input (a lens file, a scene, an option) ends as a
:class:`LensrtError`: the CLI prints its one-line message and exits non-zero,
never a traceback.
"""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["LensrtError", "PrescriptionError", "UnknownGlassError", "LensrtDeprecationWarning", "located"]


class LensrtError(Exception):
    """A problem with the user's input.

    Parameters
    ----------
    message : str
        What is wrong, in one sentence.
    path : str or Path, optional
        The file the problem is in.
    line : int, optional
        1-based line number in ``path``.
    hint : str, optional
        What to do about it.
    surface : int, optional
        Index of the lens surface concerned (0 = first surface after the
        object); readers turn it into a line number.
    """

    def __init__(self, message: str, *, path: str | Path | None = None, line: int | None = None,
                 hint: str | None = None, surface: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.path = str(path) if path is not None else None
        self.line = line
        self.hint = hint
        self.surface = surface

    def __str__(self) -> str:
        where = ""
        if self.path:
            where = self.path + (f":{self.line}" if self.line else "") + ": "
        elif self.line:
            where = f"line {self.line}: "
        text = where + self.message
        if self.surface is not None and self.line is None:
            text += f" (surface {self.surface + 1})"
        if self.hint:
            text += f" -- {self.hint}"
        return text


class PrescriptionError(LensrtError):
    """A lens prescription that cannot be loaded or is physically impossible."""


class UnknownGlassError(PrescriptionError):
    """A glass name found in no catalog."""


@contextmanager
def located(path: str | Path | None = None, line: int | None = None) -> Iterator[None]:
    """Fill in ``path``/``line`` of any :class:`LensrtError` raised inside, if missing.

    Non-lensrt exceptions raised by parsing helpers (``ValueError`` from
    ``float()``, ``IndexError`` from a short line) become a
    :class:`PrescriptionError` at that location.
    """
    try:
        yield
    except LensrtError as err:
        if err.path is None:
            err.path = str(path) if path is not None else None
        if err.line is None:
            err.line = line
        raise
    except (ValueError, IndexError, KeyError, TypeError, OverflowError, ZeroDivisionError) as err:
        raise PrescriptionError(f"cannot read this line: {err}", path=path, line=line) from err


class LensrtDeprecationWarning(FutureWarning):
    """An input spelling that still works but goes away in the next release; the message names the new one.

    A ``FutureWarning`` (shown to users by default, unlike ``DeprecationWarning``): the CLI prints it as
    one ``lensrt: warning:`` line.
    """
