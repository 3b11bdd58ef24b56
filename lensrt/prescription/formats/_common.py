"""Helpers shared by the foreign-format readers: numbers, sniffing, unit names.

Every reader turns a problem into one :class:`~lensrt.errors.PrescriptionError`
naming the file and line; these helpers keep the messages uniform.
"""
from __future__ import annotations

import math
import re
import warnings
from typing import Sequence

from ...errors import PrescriptionError, UnknownGlassError
from ..materials import CatalogGlass, find_glass
from ..model import Lens, LoadWarning

__all__ = ["parse_number", "sniff_format", "reject_other_format", "fmt_list", "FORMAT_HINTS", "make_lens",
           "lookup_glass", "substitution_note", "LensFileWarning", "emit_load_warnings"]


class LensFileWarning(UserWarning):
    """An approximation a reader made (each is also in ``Lens.warnings``)."""


def emit_load_warnings(path: str | None, found: Sequence[LoadWarning],
                       model_category: type[LensFileWarning] = LensFileWarning) -> None:
    """One Python warning per :class:`LoadWarning` (``glass_model`` ones as ``model_category``)."""
    for w in found:
        where = f"{path}:{w.line}: " if path and w.line else (f"{path}: " if path else "")
        cat = model_category if w.code == "glass_model" else LensFileWarning
        warnings.warn(where + w.text, cat, stacklevel=4)

#: what to tell a user whose file holds another format than its extension says
FORMAT_HINTS = {
    "native": "a lensrt TOML lens (rename it to .toml or pass --format native)",
    "zemax": "a Zemax .zmx lens (rename it to .zmx or pass --format zemax)",
    "codev": "a CODE V sequence (rename it to .seq or pass --format codev)",
    "pbrt": "a pbrt lens table (rename it to .dat or pass --format pbrt)",
}

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eEdD][+-]?\d+)?$")


def parse_number(token: str, what: str, *, path: str | None = None, line: int | None = None,
                 allow_inf: bool = False) -> float:
    """``float(token)`` for a token of a lens file, or a :class:`PrescriptionError`.

    Fortran exponents (``1.5D-3``) are accepted; ``nan`` is always refused and
    ``inf`` unless ``allow_inf``.
    """
    tok = token.strip()
    low = tok.lower()
    if allow_inf and low in ("inf", "+inf", "infinity", "+infinity"):
        return math.inf
    if not _NUMBER.match(tok):
        if low.lstrip("+-") in ("nan", "inf", "infinity"):
            raise PrescriptionError(f"{what} is {tok!r}", path=path, line=line,
                                    hint="give a finite number")
        raise PrescriptionError(f"{what} {tok!r} is not a number", path=path, line=line)
    value = float(tok.replace("D", "E").replace("d", "e"))
    if not math.isfinite(value):
        raise PrescriptionError(f"{what} {tok!r} overflows", path=path, line=line,
                                hint="give a finite number")
    return value


def _is_number(tok: str) -> bool:
    return bool(_NUMBER.match(tok))


def sniff_format(text: str) -> str | None:
    """Best guess of a lens file's format from its content (``None`` when unsure)."""
    lines = [ln.strip() for ln in text.splitlines()[:400] if ln.strip()]
    if any(ln.startswith("[[surface]]") or ln.replace(" ", "") == 'format="lensrt-lens"' for ln in lines):
        return "native"
    zmx = {"VERS", "MODE", "SURF", "CURV", "DISZ", "GLAS", "UNIT", "ENPD", "WAVM", "GCAT", "TYPE"}
    firsts = [ln.split()[0].upper() for ln in lines]
    if len(zmx.intersection(f for f in firsts)) >= 3 and "SURF" in firsts:
        return "zemax"
    cmds = [re.split(r"[\s;]+", ln)[0].upper() for ln in lines if not ln.startswith("!")]
    if ("SO" in cmds or "SI" in cmds) and "S" in cmds:
        return "codev"
    rows = [ln for ln in lines if not ln.startswith("#")]
    if rows and sum(1 for ln in rows if len(ln.split()) == 4 and all(_is_number(t) for t in ln.split())) \
            >= max(2, int(0.8 * len(rows))):
        return "pbrt"
    return None


def reject_other_format(text: str, expected: str, path: str | None) -> None:
    """Raise if ``text`` clearly holds another lens format than ``expected``."""
    found = sniff_format(text)
    if found is not None and found != expected:
        raise PrescriptionError(f"this file holds {FORMAT_HINTS[found].split(' (')[0]}, not "
                                f"{FORMAT_HINTS[expected].split(' (')[0]}", path=path, line=None,
                                hint=FORMAT_HINTS[found].split("(")[1].rstrip(")"))


def fmt_list(values: Sequence[float]) -> str:
    """Numbers as a short space-separated string (12 significant digits, no float noise)."""
    return " ".join(f"{v:.12g}" for v in values)


def make_lens(path: str | None, **fields: object) -> Lens:
    """``Lens(**fields)``; an error about one surface gets that surface's file line."""
    try:
        return Lens(path=path, **fields)  # type: ignore[arg-type]
    except PrescriptionError as err:
        if err.path is None:
            err.path = path
        surfaces = fields.get("surfaces", ())
        if err.line is None and err.surface is not None and 0 <= err.surface < len(surfaces):  # type: ignore[arg-type]
            err.line = surfaces[err.surface].line  # type: ignore[index]
        raise


def _norm(name: str) -> str:
    return re.sub(r"[\s\-_.]", "", name).upper()


def lookup_glass(name: str, catalogs: Sequence[str]) -> CatalogGlass:
    """Look ``name`` up the way OpticStudio does: catalog by catalog, in the file's order.

    A catalog holding exactly that name (ignoring case, spaces, hyphens, dots)
    wins, the first such catalog in order. A name that no catalog holds
    exactly (OpticStudio's obsolete glasses, e.g. ``SK16``, which
    ``opticalglass``'s current catalogs no longer list) is then matched by
    :func:`~lensrt.prescription.materials.find_glass` over all the file's
    catalogs: a bare old Schott name goes to Schott's lead-free successor
    (``SK16`` -> ``N-SK16``) when SCHOTT is among them, else to the first
    catalog's equivalent (``J-SK16`` in Hikari). Raises
    :class:`UnknownGlassError` when none has it.
    """
    key = _norm(name)
    for cat in catalogs:
        try:
            glass = find_glass(name, [cat])
        except UnknownGlassError:
            continue
        if _norm(glass.name) == key:
            return glass
    return find_glass(name, list(catalogs))


def substitution_note(subs: dict[str, str]) -> tuple[str, str] | None:
    """A ``lens.notes`` entry listing glass names the file wrote that matched other catalog names."""
    if not subs:
        return None
    return ("glass_substitutions", "; ".join(f"{k} -> {v}" for k, v in sorted(subs.items())))
