"""CODE V special surfaces (``SPS type`` + ``SCO``/``SCC`` coefficient commands) as :mod:`lensrt.prescription.shapes`.

Used by :mod:`.codev`. A special surface is declared on the current surface by ``SPS <type> [n]`` and its
coefficients are set by ``SCO <name> <value>`` (several pairs may follow one ``SCO``); ``SCC`` (their
variable codes) changes nothing optical and is read and ignored. A coefficient is named either by its
number ``C<j>`` or by its name. Lengths are in the file's lens units (``f`` = mm per unit).

Read here -- each numbering from a source independent of lensrt, named beside it:

* ``SPS ODD`` (odd polynomial asphere): ``C1`` = ``K`` (conic), ``C<i+1>`` = ``AR<i>`` on r^i (i = 1 .. 30),
  ``C33`` = ``NRADIUS``; the number after ``SPS ODD`` is NRADIUS (0: not normalised, as 1). Source: the
  table of CODE V's *Lens System Setup Reference Manual* (2026) p. 353 as quoted in the ``.seq`` writer
  ``make_seq.py`` (a patent-to-CODE V converter validated by its author against CODE V 2026's own export),
  which writes ``SPS ODD 0.0`` + ``SCO K`` + ``SCO AR<n>``. Only NRADIUS = 0 or 1 is read: the
  normalised form (r / NRADIUS)^i against AR_i r^i is not confirmed by that source -> ``odd``.
* ``SPS XYP`` (XY polynomial): ``C1`` = ``K``, ``C<j>`` on x^m y^n with j = ((m + n)^2 + m + 3 n) / 2 + 1
  (C2 = x, C3 = y, C4 = x^2, C5 = x y, C6 = y^2, C7 = x^3 ...), x and y divided by ``NRADIUS`` -- as
  written by a freeform-fitting script that emits CODE V commands (``SPS XYP 450.0``, ``SCO NRADIUS
  450.0``, ``SCO C3`` .. ``C45`` labelled Y, X2, Y2, X2Y, Y3, X4, ... Y8 and evaluated on (x, y) / R);
  the same order as Zemax's extended polynomial -> ``xy``.
* ``SPS QBF`` (Forbes Q^bfs): ``NRADIUS`` = ``C1``, ``QB4`` = ``C3`` = a_0, ``QB6`` = ``C4`` = a_1, ...
  ``QB<2m+4>`` = ``C<m+3>`` = a_m on the surface's sphere -- from CODE V 10.8's own listing of a QBF
  mirror (``threemrc_qbfs.lis`` in the rayoptics wheel, BSD-3), which lists the same mirror as a conic +
  ASP surface (``threemrc.lis``): read this way the two sags agree to 2e-5 mm over r <= 185 mm (the
  listing's 5 significant figures), and the sign or order read any other way misses by 0.2 mm -> ``qbfs``.

Refused by name, one clear error each: ``SPS QCN`` and ``ZRN``/``ZFR`` and every other special type (no
numbering found that could be checked), ``C2`` and ``K`` of a QBF surface (not in the listing), ODD
NRADIUS other than 0 or 1, any coefficient number or name a type does not define, a special surface that
also carries ``ASP`` coefficients or a conic from ``K``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ...errors import PrescriptionError
from ..shapes import MAX_SHAPE_TERMS, SurfaceShape

__all__ = ["SPS_TYPES", "SpecialSurface", "special_surface", "special_coefficients", "special_shape"]

#: the special surface types read here
SPS_TYPES = ("ODD", "XYP", "QBF")
_REFUSED = {"QCN": "a Forbes Q^con asphere", "ZRN": "a Zernike polynomial surface",
            "ZFR": "a Fringe Zernike surface", "AAS": "an anamorphic asphere", "UDS": "a user-defined surface"}
_HINT = ("give the surface in a Zemax file (Q-type: TYPE QED_TYPE, Zernike: TYPE SZERNSAG) or as a lensrt "
         "TOML shape; lensrt reads SPS ODD, XYP and QBF")


@dataclass
class SpecialSurface:
    """One ``SPS`` declaration and the ``SCO`` coefficients set on it: {number j: (value, line)}."""

    kind: str
    line: int
    coefficients: dict[int, tuple[float, int]] = field(default_factory=dict)


def _err(msg: str, path: str | None, line: int | None, hint: str | None = None) -> PrescriptionError:
    return PrescriptionError(msg, path=path, line=line, hint=hint)


def special_surface(args: list[str], line: int, path: str | None) -> SpecialSurface:
    """The :class:`SpecialSurface` of ``SPS <type> [n]`` (n: the NRADIUS, module docstring)."""
    if not args:
        raise _err("SPS without a surface type", path, line, "write e.g. 'SPS ODD 0'")
    kind = args[0].upper().strip("'\"")
    if kind not in SPS_TYPES:
        what = _REFUSED.get(kind, f"special surface type {kind!r}")
        raise _err(f"SPS {args[0]}: {what} is not supported", path, line, _HINT)
    sps = SpecialSurface(kind, line)
    if len(args) > 2:
        raise _err(f"unexpected {' '.join(args[2:])!r} after SPS {kind} {args[1]}", path, line)
    if len(args) == 2:
        try:
            sps.coefficients[_nradius_number(kind)] = (float(args[1]), line)
        except ValueError:
            raise _err(f"SPS {kind} {args[1]!r}: the number after the type (NRADIUS) is not a number", path,
                       line) from None
    return sps


def _nradius_number(kind: str) -> int:
    return {"ODD": 33, "XYP": 0, "QBF": 1}[kind]  # XYP: kept apart (0), its C numbers are all polynomial terms


def _number(kind: str, name: str) -> int | None:
    """The coefficient number j of ``name`` (``C<j>`` or a documented name) on a ``kind`` surface; None if unknown."""
    n = name.upper()
    m = re.fullmatch(r"C(\d+)", n)
    if m:
        j = int(m.group(1))
        top = {"ODD": 33, "XYP": MAX_SHAPE_TERMS, "QBF": MAX_SHAPE_TERMS + 2}[kind]  # xy: 65 terms after C1
        return j if 1 <= j <= top else None
    if n == "NRADIUS":
        return _nradius_number(kind)
    if n == "K" and kind in ("ODD", "XYP"):
        return 1
    m = re.fullmatch(r"AR(\d+)", n)
    if m and kind == "ODD" and 1 <= int(m.group(1)) <= 30:
        return int(m.group(1)) + 1
    m = re.fullmatch(r"QB(\d+)", n)
    if m and kind == "QBF" and int(m.group(1)) >= 4 and int(m.group(1)) % 2 == 0:
        return int(m.group(1)) // 2 + 1
    return None


def special_coefficients(sps: SpecialSurface | None, args: list[str], line: int, path: str | None) -> None:
    """Record ``SCO name value [name value ...]`` on the current special surface."""
    if sps is None:
        raise _err("SCO before SPS on this surface", path, line,
                   "declare the special surface first: 'SPS <type>' on the surface, then its SCO lines")
    if not args or len(args) % 2:
        raise _err(f"cannot read SCO {' '.join(args)}", path, line, "write 'SCO <coefficient> <value>', e.g. 'SCO C3 0.1'")
    for name, value in zip(args[0::2], args[1::2]):
        if re.fullmatch(r"S(\d+|O|I)", name, re.IGNORECASE):
            raise _err(f"SCO {name}: commands that change another surface are not supported", path, line,
                       "write the SCO lines after that surface's S line")
        j = _number(sps.kind, name)
        if j is None or (sps.kind == "ODD" and j == 32):
            raise _err(f"SCO {name}: not a coefficient lensrt knows on an SPS {sps.kind} surface", path, line,
                       _known(sps.kind))
        try:
            v = float(value)
        except ValueError:
            raise _err(f"SCO {name} {value!r}: not a number", path, line) from None
        old = sps.coefficients.get(j)
        if old is not None and old[1] == sps.line and old[0] != v:
            raise _err(f"SCO {name} {value}: SPS {sps.kind} gave NRADIUS {old[0]:g} on line {sps.line}", path, line,
                       "give the normalisation radius once, or the same value twice")
        sps.coefficients[j] = (v, line)


def _known(kind: str) -> str:
    return {"ODD": "SPS ODD takes K (C1), AR1 .. AR30 (C2 .. C31) and NRADIUS (C33)",
            "XYP": f"SPS XYP takes K (C1), C2 .. C{MAX_SHAPE_TERMS} (x, y, x^2, x y, y^2, ...) and NRADIUS",
            "QBF": "SPS QBF takes NRADIUS (C1) and QB4, QB6, ... (C3, C4, ...); C2 and K are not read"}[kind]


def special_shape(sps: SpecialSurface | None, conic: float, asphere: tuple[float, ...], f: float,
                  path: str | None) -> tuple[SurfaceShape | None, float, tuple[float, ...]]:
    """(shape, conic, even asphere terms in mm) of a surface with its special surface ``sps`` (None: unchanged)."""
    if sps is None:
        return None, conic, asphere
    if asphere or conic != 0.0:
        raise _err(f"SPS {sps.kind} on a surface that also has ASP/CON coefficients", path, sps.line,
                   "give the conic and every term with SCO on the special surface")
    co = {j: v for j, (v, _) in sps.coefficients.items()}
    at = lambda j: sps.coefficients.get(j, (0.0, sps.line))[1]  # noqa: E731
    if sps.kind == "QBF":
        if co.get(2, 0.0) != 0.0:
            raise _err(f"SCO C2 = {co[2]:g} on an SPS QBF surface: its meaning is not known to lensrt", path, at(2),
                       _known("QBF"))
        rn = co.get(1, 0.0)
        if rn <= 0.0:
            raise _err(f"SPS QBF with NRADIUS {rn:g}: a Q^bfs surface needs a positive normalisation radius", path,
                       at(1), "give it with 'SCO NRADIUS <radius>'")
        terms = [co.get(j, 0.0) * f for j in range(3, max([j for j in co] + [2]) + 1)]
        return SurfaceShape("qbfs", tuple(terms), rn * f), 0.0, ()
    k = co.pop(1, 0.0)
    if sps.kind == "ODD":
        rn = co.pop(33, 0.0)
        if rn not in (0.0, 1.0):
            raise _err(f"SPS ODD with NRADIUS {rn:g}: only 0 or 1 (no normalisation) is read", path, at(33),
                       "write the AR coefficients on plain powers of r with NRADIUS 0")
        terms = [co.get(i + 1, 0.0) * f ** (1 - i) for i in range(1, 31)]
        return SurfaceShape("odd", tuple(terms), 1.0), k, ()
    rn = co.pop(0, 0.0)  # XYP
    if rn < 0.0:
        raise _err(f"SPS XYP with NRADIUS {rn:g}: the normalisation radius must be positive", path, at(0))
    rn = rn if rn > 0.0 else 1.0
    last = max(list(co) + [1])
    terms = [co.get(j, 0.0) * f for j in range(2, last + 1)]
    return SurfaceShape("xy", tuple(terms), rn * f), k, ()
