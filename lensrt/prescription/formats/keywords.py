"""What the lens-file readers do with keywords they do not read: ignore on purpose, or warn.

OpticStudio adds ``.zmx`` keywords with every release and CODE V has hundreds
of commands; a reader that refused every keyword it does not know would break on
every new version. The policy:

* a keyword that changes the optics is either read or refused by name (the
  readers' own ``UNSUPPORTED`` tables: mirrors, tilts, apertures ...);
* a keyword known to hold display, file, optimisation or tolerancing settings
  is ignored on purpose (the readers' ``IGNORED`` tables and the lists here),
  recorded once as a ``keyword_ignored`` warning only where it might matter;
* any other keyword is ignored with a ``keyword_unknown`` warning naming it and
  its line, so a program can refuse such a lens (``lensrt info --json``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..model import LoadWarning

__all__ = ["ZEMAX_SETTINGS", "CODEV_NON_OPTICAL", "KeywordPolicy", "ZemaxKeywordPolicy"]

#: .zmx keywords of newer OpticStudio versions confirmed to hold display, file or optimisation settings only
#: (the reader's own ``IGNORED`` table holds the long-known ones). None of the newer keywords seen in public
#: files (``IWDP``, ``ZVCY``, ...) could be confirmed from a public description, so they are warned about.
ZEMAX_SETTINGS: dict[str, str] = {
    "TOLE": "tolerance data", "MNCA": "merit operand", "BLNK": "merit function comment",
}

#: CODE V commands that do not change the optics, ignored on purpose (``DOR`` and ``UID`` as issue 25 lists;
#: ``VIE``/``PLO`` draw the lens, ``OUT`` sets output)
CODEV_NON_OPTICAL: dict[str, str] = {
    "DOR": "non-optical setting", "UID": "user identification", "VIE": "lens drawing", "PLO": "plot command",
    "OUT": "output control",
}


@dataclass
class KeywordPolicy:
    """Collects the warnings for keywords a reader did not read (one per keyword, first line named)."""

    fmt: str
    settings: dict[str, str]
    warnings: list[LoadWarning] = field(default_factory=list)
    seen: set[str] = field(default_factory=set)

    def unread(self, keyword: str, line: int, surface: int | None = None) -> None:
        """Record ``keyword`` on ``line``: ignored on purpose if a known setting, else an unknown-keyword warning."""
        kw = keyword.upper()
        if kw in self.seen:
            return
        self.seen.add(kw)
        if kw in self.settings:
            return
        self.warnings.append(LoadWarning(
            "keyword_unknown", f"{self.fmt} keyword {keyword!r} on line {line} is unknown to lensrt and was "
            "ignored; if it changes the optics the result is wrong", surface, line))


def ZemaxKeywordPolicy() -> KeywordPolicy:  # noqa: N802 - a factory named like the class it makes
    """The policy for ``.zmx`` files (:data:`ZEMAX_SETTINGS`)."""
    return KeywordPolicy("Zemax", dict(ZEMAX_SETTINGS))
