"""The surface types of a Zemax ``.zmx`` file beyond STANDARD and EVENASPH (:mod:`lensrt.prescription.shapes`).

Used by :mod:`.zemax`. Lengths are in lens units in the file (``f`` = mm per lens unit);
``PARM n`` and ``XDAT n`` are the surface's parameters and extra data:

* ``ODDASPHE`` (odd asphere): ``PARM 1..8`` = beta_1..beta_8 on r^1 .. r^8 -> ``odd`` with R_n = 1 mm
  (beta_i in lens units^(1 - i) -> mm^(1 - i)).
* ``XOSPHERE`` (extended odd asphere): ``XDAT 1`` = number of terms N, ``XDAT 2`` = normalisation
  radius, ``XDAT 3..`` = coefficients on rho^1 .. rho^N (lens units) -> ``odd``.
* ``XASPHERE`` (extended asphere): the same extra data with coefficients on rho^2, rho^4, ... ->
  ``odd`` with the odd powers zero.
* ``QED_TYPE`` (Q-type asphere): ``XDAT 1`` = 0 (Q^bfs) or 1 (Q^con), ``XDAT 2`` = number of terms,
  ``XDAT 3`` = normalisation radius, ``XDAT 4..`` = a_0, a_1, ... (lens units) -> ``qbfs`` / ``qcon``.
* ``BICONICX`` / ``BICONIC`` (biconic): ``PARM 1`` = x radius (0: flat in x), ``PARM 2`` = x conic.
* ``TOROIDAL``: ``PARM 1`` = radius of rotation (0: infinite, a cylinder), ``PARM 2..9`` =
  alpha_1..alpha_8 on y^2, y^4, ... (the y-profile's even terms); its Zernike extra data must be zero.
* ``XPOLYNOM`` (extended polynomial): ``XDAT 1`` = number of terms, ``XDAT 2`` = normalisation radius,
  ``XDAT 3..`` = coefficients on x, y, x^2, x y, y^2, ... of (x, y) / R_n (lens units) -> ``xy``.
* ``SZERNSAG`` (Zernike standard sag): ``PARM 1..8`` = alpha_1..alpha_8 on r^2 .. r^16 (as EVENASPH),
  ``XDAT 1`` = number of terms, ``XDAT 2`` = normalisation radius, ``XDAT 3..`` = Z_1, Z_2, ... (Noll's
  order and normalisation, OpticStudio's "Zernike Standard"; lens units) -> ``zernike``. A Zernike
  decenter (``PARM 9``, ``PARM 10``) is refused.
* ``FZERNSAG`` (Zernike fringe sag): the same parameters and extra data, the coefficients on the fringe
  Zernike terms F_1 .. F_37 (OpticStudio's "Zernike Fringe" order, not normalised) -> ``zernike_fringe``.
  The layout is OpticStudio's for both Zernike sag surfaces (its manual, "Zernike Fringe Sag": extra data
  1 = number of terms, 2 = normalisation radius, 3.. = coefficients); it is checked on the three
  FZERNSAG files of YuryStrelkov/ZemaxUtils (a 2 m telescope whose Zernike terms are small figure errors:
  8 terms over the mirrors' and lenses' semi-diameters).

Any other non-zero parameter or extra data on these surfaces is refused by name, never dropped.
"""
from __future__ import annotations

from ...errors import PrescriptionError
from ..shapes import MAX_FRINGE_TERMS, MAX_SHAPE_TERMS, SurfaceShape

__all__ = ["SHAPE_TYPES", "zemax_shape"]

#: the surface types read here
SHAPE_TYPES = ("ODDASPHE", "XOSPHERE", "XASPHERE", "QED_TYPE", "BICONICX", "BICONIC", "TOROIDAL", "XPOLYNOM",
               "SZERNSAG", "FZERNSAG")

Params = dict[int, tuple[float, int]]


def _refuse_extra(kind: str, data: Params, allowed: range, what: str, path: str | None, line: int) -> None:
    bad = [i for i in data if i not in allowed and data[i][0] != 0.0]
    if bad:
        i = bad[0]
        raise PrescriptionError(f"{what} {i} = {data[i][0]:g} on a {kind} surface: lensrt does not model it",
                                path=path, line=data[i][1],
                                hint=f"{kind} uses {what} {allowed.start}..{allowed.stop - 1} only")


def _extended(kind: str, xdat: Params, first: int, f: float, path: str | None, line: int
              ) -> tuple[list[float], float]:
    """(coefficients in mm, normalisation radius in mm) of the extra data ``N, [type,] R_n, c_1 .. c_N``."""
    get = lambda i: xdat.get(i, (0.0, line))[0]  # noqa: E731
    n_at, rn_at = first, first + 1
    n = int(get(n_at))
    if n < 0 or n > MAX_SHAPE_TERMS or n != get(n_at):
        raise PrescriptionError(f"XDAT {n_at} = {get(n_at):g}: the number of terms of a {kind} surface must be a "
                                f"whole number 0..{MAX_SHAPE_TERMS}", path=path, line=xdat.get(n_at, (0, line))[1])
    rn = get(rn_at)
    if n and rn <= 0.0:
        raise PrescriptionError(f"XDAT {rn_at} = {rn:g}: the normalisation radius of a {kind} surface must be "
                                "positive", path=path, line=xdat.get(rn_at, (0, line))[1])
    _refuse_extra(kind, xdat, range(1, rn_at + 1 + n), "XDAT", path, line)
    return [get(rn_at + 1 + j) * f for j in range(n)], (rn if n else 1.0) * f


def zemax_shape(kind: str, parm: Params, xdat: Params, f: float, path: str | None, line: int
                ) -> tuple[SurfaceShape, tuple[float, ...]]:
    """The :class:`SurfaceShape` and even asphere terms (mm) of a surface of type ``kind`` (module docstring)."""
    p = lambda i: parm.get(i, (0.0, line))[0]  # noqa: E731
    if kind == "ODDASPHE":
        _refuse_extra(kind, parm, range(1, 9), "PARM", path, line)
        _refuse_extra(kind, xdat, range(1, 1), "XDAT", path, line)
        return SurfaceShape("odd", tuple(p(i) * f ** (1 - i) for i in range(1, 9)), 1.0), ()
    if kind in ("XOSPHERE", "XASPHERE"):
        _refuse_extra(kind, parm, range(1, 1), "PARM", path, line)
        coef, rn = _extended(kind, xdat, 1, f, path, line)
        if kind == "XASPHERE":  # rho^2, rho^4, ...: the even places of the odd series
            coef = [v for a in coef for v in (0.0, a)]
        return SurfaceShape("odd", tuple(coef), rn), ()
    if kind == "QED_TYPE":
        _refuse_extra(kind, parm, range(1, 1), "PARM", path, line)
        q = xdat.get(1, (0.0, line))
        if q[0] not in (0.0, 1.0):
            raise PrescriptionError(f"XDAT 1 = {q[0]:g}: a Q-type surface is type 0 (Qbfs) or 1 (Qcon)", path=path,
                                    line=q[1])
        coef, rn = _extended(kind, xdat, 2, f, path, line)
        return SurfaceShape("qcon" if q[0] == 1.0 else "qbfs", tuple(coef), rn), ()
    if kind in ("BICONICX", "BICONIC"):
        _refuse_extra(kind, parm, range(1, 3), "PARM", path, line)
        _refuse_extra(kind, xdat, range(1, 1), "XDAT", path, line)
        rx = p(1) * f
        return SurfaceShape("biconic", curvature_x_per_mm=0.0 if rx == 0.0 else 1.0 / rx, conic_x=p(2)), ()
    if kind in ("XPOLYNOM", "SZERNSAG", "FZERNSAG"):
        even = kind != "XPOLYNOM"
        _refuse_extra(kind, parm, range(1, 9 if even else 1), "PARM", path, line)
        coef, rn = _extended(kind, xdat, 1, f, path, line)
        asph = tuple(p(i) * f ** (1 - 2 * i) for i in range(1, 9)) if even else ()
        if kind == "FZERNSAG" and len(coef) > MAX_FRINGE_TERMS:
            raise PrescriptionError(f"XDAT 1 = {len(coef)}: a FZERNSAG surface has at most {MAX_FRINGE_TERMS} "
                                    "fringe Zernike terms", path=path, line=xdat.get(1, (0, line))[1])
        kinds = {"XPOLYNOM": "xy", "SZERNSAG": "zernike", "FZERNSAG": "zernike_fringe"}
        return SurfaceShape(kinds[kind], tuple(coef), rn), asph
    if kind == "TOROIDAL":
        _refuse_extra(kind, parm, range(0, 10), "PARM", path, line)  # PARM 0 (unused) is written as 0
        if parm.get(0, (0.0, line))[0] != 0.0:
            _refuse_extra(kind, parm, range(1, 10), "PARM", path, line)
        _refuse_extra(kind, xdat, range(1, 3), "XDAT", path, line)  # XDAT 1 = 0 Zernike terms, XDAT 2 its radius
        rr = p(1) * f
        asph = tuple(p(i) * f ** (1 - 2 * (i - 1)) for i in range(2, 10))
        return SurfaceShape("toroidal", curvature_x_per_mm=0.0 if rr == 0.0 else 1.0 / rr), asph
    raise PrescriptionError(f"TYPE {kind} is not a shape type", path=path, line=line)
