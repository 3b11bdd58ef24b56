"""CODE V glass syntax: fictitious glasses (``1.55:55.8``, ``517.642``, ``517642``) and private catalogs (``PRV``).

Fictitious glasses name n_d and V_d directly: ``n:v`` (``1.55:55.8``), or the
six-digit glass code ``nnnvvv`` (``517642`` is n_d = 1.517, V_d = 64.2) with or
without its dot (``517.642``), or the longer code CODE V writes for more
precision (``517000.520000`` is n_d = 1.517000, V_d = 52.0000: the digits before
the dot are n_d's decimals, those after it V_d / 100). They become n_d/V_d model glasses.

A private catalog lists indices at wavelengths::

    PRV
      PWL 656.3 587.6 486.1
      'E48' 1.5184 1.5201 1.5231
    END

lensrt fits the Schott power series (as many terms as points, at most six) to
each glass's indices; the fit's largest residual is part of the material's
``formula`` text and of the ``glass_private`` warning, and the PWL span is the
data range (outside it the fit is extrapolated, with a warning).
"""
from __future__ import annotations

import re

from ...errors import PrescriptionError
from ..dispersion import fit_power_series
from ..materials import CatalogGlass, ModelGlass

__all__ = ["fictitious_glass", "PrivateCatalog"]

_CODE = re.compile(r"^(\d{3})\.?(\d{3})$")
_LONG_CODE = re.compile(r"^(\d{3,})\.(\d{3,})$")  # 517000.520000: n_d - 1 and V_d / 100, more digits
_COLON = re.compile(r"^(\d+(?:\.\d*)?):(\d+(?:\.\d*)?)$")


def fictitious_glass(text: str) -> ModelGlass | None:
    """The model glass a fictitious-glass token names, or ``None`` if it is not one."""
    tok = text.strip("'\"")
    m = _COLON.match(tok)
    if m:
        return ModelGlass(float(m.group(1)), float(m.group(2)), name=tok)
    m = _CODE.match(tok)
    if m:
        return ModelGlass(1.0 + int(m.group(1)) / 1000.0, int(m.group(2)) / 10.0, name=tok)
    m = _LONG_CODE.match(tok)
    if m:  # the digits before the dot are the decimals of n_d, those after it V_d / 100
        return ModelGlass(float("1." + m.group(1)), 100.0 * float("0." + m.group(2)), name=tok)
    return None


class PrivateCatalog:
    """Collects one ``PRV`` ... ``END`` block of a sequence file."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        self.wavelengths_nm: list[float] = []
        self.rows: dict[str, tuple[list[float], int]] = {}

    def command(self, toks: list[str], line: int) -> bool:
        """Take one command inside the block; ``False`` at ``END``."""
        head = toks[0].upper()
        if head == "END":
            return False
        if head == "PWL":
            try:
                self.wavelengths_nm = [float(t) for t in toks[1:]]
            except ValueError:
                raise PrescriptionError(f"cannot read PWL {' '.join(toks[1:])!r}", path=self.path,
                                        line=line) from None
            return True
        if toks[0][:1] not in "'\"":
            raise PrescriptionError(f"inside PRV: expected PWL, a quoted glass name or END, found {toks[0]!r}",
                                    path=self.path, line=line, hint="close the private catalog with END")
        name = toks[0].strip("'\"")
        try:
            values = [float(t) for t in toks[1:]]
        except ValueError:
            raise PrescriptionError(f"private glass {name}: cannot read its indices", path=self.path,
                                    line=line) from None
        self.rows[name.upper()] = (values, line)
        return True

    def glasses(self) -> dict[str, CatalogGlass]:
        """The block's glasses, fitted (see the module docstring)."""
        out = {}
        w = self.wavelengths_nm
        for key, (n, line) in self.rows.items():
            if not w or len(n) != len(w):
                raise PrescriptionError(f"private glass {key} gives {len(n)} indices for {len(w)} PWL wavelengths",
                                        path=self.path, line=line, hint="give one index per PWL wavelength")
            if any(not (1.0 <= v <= 5.0) for v in n):
                raise PrescriptionError(f"private glass {key}: an index outside 1..5", path=self.path, line=line)
            packed, resid = fit_power_series(w, n)
            out[key] = CatalogGlass(name=key, catalog="PRV", coefficients=packed, range_nm=(min(w), max(w)),
                                    source=f"CODE V private catalog (line {line})",
                                    formula=f"Schott power series fitted to {len(w)} indices "
                                            f"(largest residual {resid:.1e})")
        return out
