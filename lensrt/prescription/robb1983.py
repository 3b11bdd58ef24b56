"""Obsolete glasses of the 1980 catalogs (Schott, Ohara, Hoya, Corning-France, Chance), from Robb & Mercado 1983.

Old lens files name glasses that no current catalog lists (Schott ``BK7``,
``SK19``, ``KZFSN5``, ...). ``opticalglass`` ships Table V of P. N. Robb and
R. I. Mercado, "Calculation of refractive indices using Buchdahl's chromatic
coordinate", Appl. Opt. 22, 1198 (1983), doi:10.1364/AO.22.001198: for each
glass of five 1980 catalogs a quadratic Buchdahl model fitted to the catalog's
indices in the visible (standard deviation ~1e-5)::

    n(w) = N0 + nu1 omega + nu2 omega^2,   omega = dw / (1 + 2.5 dw),   dw = w - w0,   w in micrometres

with the base wavelength w0 = 0.574 um of the paper. (``opticalglass``'s own
:class:`Buchdahl` object takes w0 = 587.6 nm; with that base, its n_d of BK7 is
1.51692 against Schott's 1.51680, while w0 = 0.574 um reproduces the current
catalogs' n_d of the unchanged glasses F2, SF5, SF11 within 1e-5.)

lensrt's kernels evaluate one packed formula for every material, so the model
is sampled over its fitted band (:data:`BAND_NM`) and packed as a Schott power
series by least squares (:func:`~lensrt.prescription.dispersion.fit_power_series`);
the largest difference from the model over the band is kept in ``formula``.
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np

from .dispersion import fit_power_series
from .materials import CatalogGlass

__all__ = ["BASE_WAVELENGTH_UM", "BAND_NM", "ROBB_CATALOGS", "robb_table", "robb_index", "find_robb_glass"]

#: Robb & Mercado's base wavelength (um)
BASE_WAVELENGTH_UM = 0.574
#: the visible band of the paper's quadratic model (nm): lensrt's data range for these glasses
BAND_NM = (400.0, 700.0)
#: the paper's catalogs as lensrt names them (the data file's headings in upper case)
ROBB_CATALOGS: tuple[str, ...] = ("Schott", "Ohara", "Hoya", "Corning-France", "Chance")


def _data_file() -> Path:
    import opticalglass
    return Path(opticalglass.__file__).parent / "data" / "robb1983_data_final.txt"


def _key(name: str) -> str:
    """Case and punctuation ignored; a letter O after a digit read as zero (the data file prints ``NBFD1O``)."""
    return re.sub(r"(?<=\d)O", "0", re.sub(r"[\s\-_.]", "", name).upper())


@lru_cache(maxsize=1)
def robb_table() -> dict[str, dict[str, tuple[str, float, float, float]]]:
    """Catalog -> normalised glass name -> (name as printed, N0, nu1, nu2), read from opticalglass's data file."""
    out: dict[str, dict[str, tuple[str, float, float, float]]] = {}
    catalog = None
    path = _data_file()
    if not path.is_file():  # an opticalglass without the table: no 1980 glasses, never a traceback
        return out
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        if line.startswith("#"):
            if "GLASS CATALOGUE" in line:
                head = line[1:].split()[0].upper()
                catalog = next((c for c in ROBB_CATALOGS if c.upper() == head), None)
                if catalog is not None:
                    out.setdefault(catalog, {})
            continue
        tok = line.split()
        if catalog is None or len(tok) < 4:
            continue
        try:
            n0, nu1, nu2 = float(tok[1]), float(tok[2]), float(tok[3])
        except ValueError:
            continue
        out[catalog].setdefault(_key(tok[0]), (re.sub(r"(?<=\d)O", "0", tok[0]), n0, nu1, nu2))
    return out


def robb_index(n0: float, nu1: float, nu2: float, wavelength_nm: np.ndarray | float) -> np.ndarray | float:
    """The quadratic Buchdahl model of the paper at ``wavelength_nm`` (nm, in air)."""
    dw = np.asarray(wavelength_nm, dtype=np.float64) / 1000.0 - BASE_WAVELENGTH_UM
    om = dw / (1.0 + 2.5 * dw)
    return n0 + nu1 * om + nu2 * om * om


@lru_cache(maxsize=None)
def _glass(catalog: str, key: str) -> CatalogGlass:
    name, n0, nu1, nu2 = robb_table()[catalog][key]
    waves = np.linspace(BAND_NM[0], BAND_NM[1], 31)
    packed, resid = fit_power_series(list(waves), list(robb_index(n0, nu1, nu2, waves)))
    return CatalogGlass(name=name, catalog=f"{catalog} 1980", coefficients=packed, range_nm=BAND_NM,
                        source="Robb & Mercado 1983 (Appl. Opt. 22, 1198), Table V, as shipped by opticalglass",
                        formula=f"Buchdahl quadratic model packed as a Schott power series (max |dn| {resid:.1e} "
                                f"over {BAND_NM[0]:g}-{BAND_NM[1]:g} nm)")


def find_robb_glass(name: str, catalogs: tuple[str, ...] | None = None) -> CatalogGlass | None:
    """The obsolete glass ``name`` (case and punctuation ignored) of the first of ``catalogs`` that lists it.

    ``catalogs`` are vendor names (``"SCHOTT"``, ``"Hoya"``; case ignored); ``None`` searches all five
    in :data:`ROBB_CATALOGS` order.
    """
    table = robb_table()
    key = _key(name)
    wanted = [c.upper() for c in catalogs] if catalogs is not None else [c.upper() for c in ROBB_CATALOGS]
    for want in wanted:
        for cat in ROBB_CATALOGS:
            if cat.upper() == want and key in table.get(cat, {}):
                return _glass(cat, key)
    return None
