"""Zemax ``.agf`` glass catalogs (a user's own or a vendor's), read into :class:`CatalogGlass` es.

An ``.agf`` file lists glasses as ``NM name formula MIL nd vd exclude status``
lines, each followed by ``CD`` (dispersion coefficients, micrometres) and
``LD`` (the wavelength range of the data, micrometres) lines; ``CC``, ``GC``,
``ED``, ``TD``, ``OD``, ``IT`` lines are comments, thermal, other and
transmission data that lensrt does not need. The catalog's name is the file's
stem (``MYGLASS.agf`` answers ``GCAT MYGLASS``), as in OpticStudio.

Formulas (numbers as OpticStudio's manual gives them) that lensrt packs exactly
(:mod:`lensrt.prescription.dispersion`): 1 Schott, 2 Sellmeier 1, 4 Sellmeier 2,
6 Sellmeier 3 and 11 Sellmeier 5 (with at most three non-zero terms),
7 Handbook 1, 8 Handbook 2, 9 Sellmeier 4, 10 Extended, 12 Extended 2 (without
its w^6 term), 13 Extended 3. Herzberger (3) and Conrady (5) are refused by
name when such a glass is used.
"""
from __future__ import annotations

import codecs
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..errors import PrescriptionError
from .dispersion import NotRepresentable, PackBuilder
from .materials import CatalogGlass

__all__ = ["AgfCatalog", "read_agf", "pack_agf_formula", "AGF_FORMULAS"]

#: OpticStudio's formula numbers and names
AGF_FORMULAS = {1: "Schott", 2: "Sellmeier 1", 3: "Herzberger", 4: "Sellmeier 2", 5: "Conrady", 6: "Sellmeier 3",
                7: "Handbook of Optics 1", 8: "Handbook of Optics 2", 9: "Sellmeier 4", 10: "Extended",
                11: "Sellmeier 5", 12: "Extended 2", 13: "Extended 3"}


def pack_agf_formula(formula: int, c: list[float]) -> tuple[float, ...]:
    """Pack the ``CD`` coefficients of an ``.agf`` formula; :class:`NotRepresentable` if lensrt cannot."""
    c = list(c) + [0.0] * 12
    b = PackBuilder()
    if formula == 1:  # n^2 = a0 + a1 w^2 + a2 w^-2 + a3 w^-4 + a4 w^-6 + a5 w^-8
        for coef, e in zip(c[:6], (0, 2, -2, -4, -6, -8)):
            b.power(coef, e)
    elif formula in (2, 6, 11):  # n^2 - 1 = sum K_i w^2 / (w^2 - L_i)
        b.power(1.0, 0)
        for i in range({2: 3, 6: 4, 11: 5}[formula]):
            b.sellmeier(c[2 * i], c[2 * i + 1])
    elif formula == 4:  # n^2 = 1 + A + B w^2 / (w^2 - C) + D / (w^2 - E)  (A B C D E)
        b.power(1.0 + c[0], 0).sellmeier(c[1], c[2]).handbook(c[3], c[4])
    elif formula == 7:  # n^2 = A + B / (w^2 - C) - D w^2
        b.power(c[0], 0).handbook(c[1], c[2]).power(-c[3], 2)
    elif formula == 8:  # n^2 = A + B w^2 / (w^2 - C) - D w^2
        b.power(c[0], 0).sellmeier(c[1], c[2]).power(-c[3], 2)
    elif formula == 9:  # n^2 = A + B w^2 / (w^2 - C) + D w^2 / (w^2 - E)
        b.power(c[0], 0).sellmeier(c[1], c[2]).sellmeier(c[3], c[4])
    elif formula == 10:  # n^2 = a0 + a1 w^2 + a2 w^-2 + ... + a7 w^-12
        for coef, e in zip(c[:8], (0, 2, -2, -4, -6, -8, -10, -12)):
            b.power(coef, e)
    elif formula == 12:  # n^2 = a0 + a1 w^2 + a2 w^-2 + a3 w^-4 + a4 w^-6 + a5 w^-8 + a6 w^4 + a7 w^6
        for coef, e in zip(c[:8], (0, 2, -2, -4, -6, -8, 4, 6)):
            b.power(coef, e)
    elif formula == 13:  # n^2 = a0 + a1 w^2 + a2 w^4 + a3 w^-2 + ... + a8 w^-12
        for coef, e in zip(c[:9], (0, 2, 4, -2, -4, -6, -8, -10, -12)):
            b.power(coef, e)
    else:
        raise NotRepresentable(f"formula {formula} ({AGF_FORMULAS.get(formula, 'unknown')})")
    return b.packed()


@dataclass(frozen=True)
class _Entry:
    name: str
    formula: int
    nd: float
    vd: float
    coefficients: tuple[float, ...]
    range_nm: tuple[float, float] | None
    line: int


@dataclass(frozen=True)
class AgfCatalog:
    """One ``.agf`` catalog: its name (the file stem, upper case), path and glasses by normalised name."""

    name: str
    path: str
    entries: tuple[_Entry, ...]

    def names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.entries)

    def find(self, name: str) -> CatalogGlass | None:
        """The glass called ``name`` (ignoring case, spaces, hyphens, dots, underscores), else ``None``."""
        key = _key(name)
        for e in self.entries:
            if _key(e.name) == key:
                return self.glass(e)
        return None

    def glass(self, e: _Entry) -> CatalogGlass:
        try:
            packed = pack_agf_formula(e.formula, list(e.coefficients))
        except NotRepresentable as err:
            raise PrescriptionError(f"glass {e.name} of catalog {self.name}: {err} cannot be represented by "
                                    "lensrt's dispersion formula", path=self.path, line=e.line,
                                    hint="refit the glass to a Sellmeier or Schott formula") from None
        return CatalogGlass(name=e.name, catalog=self.name, coefficients=packed, range_nm=e.range_nm,
                            source=f"user catalog {self.path}",
                            formula=f"AGF formula {e.formula} ({AGF_FORMULAS.get(e.formula, '?')})")


def _key(name: str) -> str:
    return "".join(ch for ch in name.upper() if ch not in " -_.")


def _decode(data: bytes) -> str:
    for bom, enc in ((codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
                     (codecs.BOM_UTF16_BE, "utf-16")):
        if data.startswith(bom):
            return data.decode(enc, errors="replace")
    if data[1:2] == b"\x00":
        return data.decode("utf-16-le", errors="replace")
    return data.decode("latin-1")


def _floats(toks: list[str], path: str, no: int, what: str) -> list[float]:
    try:
        return [float(t) for t in toks]
    except ValueError:
        raise PrescriptionError(f"cannot read the {what} {' '.join(toks)!r}", path=path, line=no) from None


@lru_cache(maxsize=64)
def read_agf(path: str) -> AgfCatalog:
    """Read a Zemax ``.agf`` file (UTF-16 or 8-bit text).

    Raises :class:`PrescriptionError` for a missing file or a malformed ``NM``/``CD``/``LD`` line.
    """
    p = Path(path)
    if not p.is_file():
        raise PrescriptionError("glass catalog not found", path=path, hint="give the path of a Zemax .agf file")
    text = _decode(p.read_bytes())
    entries: list[_Entry] = []
    cur: dict | None = None

    def close() -> None:
        if cur is not None:
            entries.append(_Entry(cur["name"], cur["formula"], cur["nd"], cur["vd"], tuple(cur["cd"]),
                                  cur["ld"], cur["line"]))

    for no, raw in enumerate(text.splitlines(), start=1):
        toks = raw.split()
        if not toks:
            continue
        tag = toks[0].upper()
        if tag == "NM":
            close()
            if len(toks) < 6:
                raise PrescriptionError("NM line needs a name, formula, MIL code, n_d and V_d", path=path, line=no)
            nums = _floats(toks[2:6], path, no, "NM values")
            cur = dict(name=toks[1], formula=int(nums[0]), nd=nums[2], vd=nums[3], cd=[], ld=None, line=no)
        elif tag == "CD" and cur is not None:
            cur["cd"] = _floats(toks[1:], path, no, "dispersion coefficients")
        elif tag == "LD" and cur is not None and len(toks) >= 3:
            lo, hi = _floats(toks[1:3], path, no, "wavelength range")
            cur["ld"] = (lo * 1000.0, hi * 1000.0)
    close()
    if not entries:
        raise PrescriptionError("no glasses (NM lines) in this catalog", path=path,
                                hint="a Zemax .agf file lists each glass on an 'NM name formula ...' line")
    return AgfCatalog(name=p.stem.upper(), path=str(p), entries=tuple(entries))
