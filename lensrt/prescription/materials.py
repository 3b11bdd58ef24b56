"""Optical materials: vendor catalog glasses, nd/Vd model glasses, constant indices, air.

Every material evaluates its refractive index (relative to air, as Zemax and
CODE V list them) from one general dispersion formula whose coefficients pack
into a flat row of :data:`DISPERSION_WIDTH` floats, so a GPU kernel can compute
each ray's index from its own wavelength::

    n^2(w) = p0 + p1 w^2 + p2 w^4 + sum_{k=1..6} p_{k+2} w^(-2k)
             + sum_{j=0..2} p_{9+j} w^2 / (w^2 - p_{12+j}),      w in micrometres

The vendors' own formulas are special cases of it:

* Schott, Ohara: Sellmeier, n^2 = 1 + sum B_j w^2 / (w^2 - C_j);
* Hoya, CDGM, Sumita: the Schott power series, n^2 = A0 + A1 w^2 + A2 w^-2 + ... + A5 w^-8;
* Hikari: the extended series, n^2 = A0 + A1 w^2 + A2 w^4 + A3 w^-2 + ... + A8 w^-12.

Coefficients come from the vendor spreadsheets shipped by ``opticalglass``
(never typed in); tests check our evaluation against ``opticalglass``'s own.

The nd/Vd *model glass* is a two-term Cauchy law n = A + B / w^2 through n_d at
587.5618 nm with n_F - n_C = (n_d - 1) / V_d (F = 486.1327 nm, C = 656.2725 nm),
packed as n^2 = A^2 + 2AB w^-2 + B^2 w^-4. It reproduces n_d and V_d exactly; its
partial dispersions are those of a normal glass only approximately.
"""
from __future__ import annotations

import difflib
import math
import re
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterable, Sequence

import numpy as np

from ..errors import PrescriptionError, UnknownGlassError
from ..units import FRAUNHOFER_NM, NM_PER_UM
from .dispersion import DISPERSION_WIDTH

__all__ = [
    "DISPERSION_WIDTH", "Material", "Air", "ConstantIndex", "ModelGlass", "CatalogGlass",
    "AIR", "CATALOGS", "find_glass", "parse_material", "index_from_packed",
    "glass_names", "ExtrapolationWarning", "check_wavelength_range", "find_exact_vendor_glass",
    "vendor_nd_vd_table", "make_vendor_glass",
]

#: catalog names in the default search order
CATALOGS: tuple[str, ...] = ("Schott", "Ohara", "Hoya", "CDGM", "Hikari", "Sumita")


class ExtrapolationWarning(UserWarning):
    """A dispersion formula evaluated outside the wavelengths its catalog measured."""


def index_from_packed(packed: Sequence[float] | np.ndarray, wavelength_nm: float | np.ndarray) -> np.ndarray | float:
    """Evaluate the general dispersion formula (float64, vectorised over wavelength).

    Parameters
    ----------
    packed : sequence of float
        :data:`DISPERSION_WIDTH` coefficients (module docstring).
    wavelength_nm : float or array
        Wavelength in air, nm (the catalogs' convention).

    Returns
    -------
    float or ndarray
        Refractive index relative to air.
    """
    p = np.asarray(packed, dtype=np.float64)
    w = np.asarray(wavelength_nm, dtype=np.float64) / NM_PER_UM
    w2 = w * w
    n2 = p[0] + w2 * (p[1] + w2 * p[2])
    inv = 1.0 / w2
    acc = inv
    for k in range(3, 9):
        n2 = n2 + p[k] * acc
        acc = acc * inv
    for j in range(3):
        if p[9 + j] != 0.0:
            n2 = n2 + p[9 + j] * w2 / (w2 - p[12 + j])
    n = np.sqrt(n2)
    return float(n) if np.ndim(n) == 0 else n


class Material:
    """Base of all materials. Subclasses are frozen dataclasses (hashable, comparable)."""

    name: str

    def packed(self) -> tuple[float, ...]:
        """Coefficients of the general dispersion formula (module docstring)."""
        raise NotImplementedError  # pragma: no cover - abstract

    @property
    def valid_range_nm(self) -> tuple[float, float] | None:
        """Wavelength range (nm) over which the index is data, not extrapolation."""
        return None

    @property
    def is_air(self) -> bool:
        return False

    def index(self, wavelength_nm: float | np.ndarray) -> np.ndarray | float:
        """Refractive index at ``wavelength_nm`` (vectorised), relative to air."""
        return index_from_packed(self.packed(), wavelength_nm)

    def abbe_number(self) -> float:
        """V_d = (n_d - 1) / (n_F - n_C); ``inf`` for a non-dispersive material."""
        nd, nf, nc = (self.index(FRAUNHOFER_NM[k]) for k in ("d", "F", "C"))
        return math.inf if nf == nc else (nd - 1.0) / (nf - nc)

    def describe(self) -> str:
        """Short human-readable description for tables."""
        return self.name


@dataclass(frozen=True)
class Air(Material):
    """Air: index 1 at every wavelength (indices are relative to air)."""

    name: str = "air"

    def packed(self) -> tuple[float, ...]:
        return (1.0,) + (0.0,) * (DISPERSION_WIDTH - 1)

    @property
    def is_air(self) -> bool:
        return True


AIR = Air()


@dataclass(frozen=True)
class ConstantIndex(Material):
    """A non-dispersive medium of index ``n`` (pbrt tables, immersion media).

    ``n`` is 1..5; an index in 0.5..1 (an exotic medium, relative to air) needs ``exotic=True``
    (TOML ``material = { index = 0.7, exotic = true }``).
    """

    n: float
    name: str = ""
    exotic: bool = False

    def __post_init__(self) -> None:
        low = 0.5 if self.exotic else 1.0
        if not (math.isfinite(self.n) and low <= self.n <= 5.0):
            raise PrescriptionError(f"refractive index {self.n!r} is not physical",
                                    hint="give an index between 1 and 5" + (
                                        "; an index below 1 needs 'exotic = true' in a TOML material table"
                                        if math.isfinite(self.n) and 0.5 <= self.n < 1.0 else ""))
        if not self.name:
            object.__setattr__(self, "name", f"n={self.n:g}")

    def packed(self) -> tuple[float, ...]:
        return (self.n * self.n,) + (0.0,) * (DISPERSION_WIDTH - 1)

    @property
    def is_air(self) -> bool:
        return self.n == 1.0


@dataclass(frozen=True)
class ModelGlass(Material):
    """nd/Vd model glass: two-term Cauchy law through n_d and V_d (module docstring)."""

    nd: float
    vd: float
    name: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.nd) and 1.0 <= self.nd <= 5.0):
            raise PrescriptionError(f"model glass n_d = {self.nd!r} is not physical",
                                    hint="n_d must lie between 1 and 5")
        if not (math.isfinite(self.vd) and self.vd > 0.0):
            raise PrescriptionError(f"model glass V_d = {self.vd!r} is not physical",
                                    hint="the Abbe number must be positive")
        if not self.name:
            object.__setattr__(self, "name", f"model {self.nd:.5f}/{self.vd:.2f}")

    def packed(self) -> tuple[float, ...]:
        wf, wc, wd = (FRAUNHOFER_NM[k] / NM_PER_UM for k in ("F", "C", "d"))
        b = (self.nd - 1.0) / self.vd / (1.0 / wf**2 - 1.0 / wc**2)
        a = self.nd - b / wd**2
        p = [0.0] * DISPERSION_WIDTH
        p[0], p[3], p[4] = a * a, 2.0 * a * b, b * b
        return tuple(p)


@dataclass(frozen=True)
class CatalogGlass(Material):
    """A catalog material: its packed coefficients are copied from the catalog's own formula at load.

    ``source`` says where the data come from (``opticalglass``'s vendor
    spreadsheet, a refractiveindex.info page, a user ``.agf`` file, a CODE V
    private catalog), ``formula`` which formula it was. Outside ``range_nm``
    the formula is extrapolated: a warning for glasses, an error where
    ``range_is_limit`` (crystals and semiconductors whose formulas fail
    outside their data, e.g. germanium in the visible).
    """

    name: str
    catalog: str
    coefficients: tuple[float, ...] = field(repr=False, default=())
    range_nm: tuple[float, float] | None = field(repr=False, default=None)
    source: str = field(default="", compare=False)
    formula: str = field(default="", compare=False)
    range_is_limit: bool = field(default=False, compare=False)

    def packed(self) -> tuple[float, ...]:
        return self.coefficients

    @property
    def valid_range_nm(self) -> tuple[float, float] | None:
        return self.range_nm

    def describe(self) -> str:
        return f"{self.name} ({self.catalog})"

    @classmethod
    def lookup(cls, name: str, catalogs: Iterable[str] | None = None) -> "CatalogGlass":
        """Find a glass by the name users write; see :func:`find_glass`."""
        return find_glass(name, catalogs)


# ---------------------------------------------------------------------------
# catalog access (opticalglass is imported lazily: loading a lens with no
# catalog glass never touches the spreadsheets)


def _normalise(name: str) -> str:
    return re.sub(r"[\s\-_.]", "", name).upper()


_PREFIX = re.compile(r"^(N|S|J|H|K|E|P|L|M|Q|D|NA|LZ|ZK|Z)[-_ ]", re.IGNORECASE)


def _strip_vendor_prefix(name: str) -> str:
    return _normalise(_PREFIX.sub("", name))


def _canonical_catalog(name: str) -> str | None:
    key = name.strip().upper()
    for cat in CATALOGS:
        if cat.upper() == key:
            return cat
    return None


@lru_cache(maxsize=None)
def _catalog(cat: str):
    import logging
    logging.getLogger("opticalglass").setLevel(logging.ERROR)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import opticalglass.glassfactory as gf
        return gf.get_glass_catalog(cat)


@lru_cache(maxsize=None)
def glass_names(cat: str) -> tuple[str, ...]:
    """All glass names of catalog ``cat`` (one of :data:`CATALOGS`)."""
    return tuple(str(n) for n in _catalog(cat).get_glass_names())


def _pack_catalog(cat: str, coefs: np.ndarray) -> tuple[float, ...]:
    c = [float(x) for x in coefs]
    p = [0.0] * DISPERSION_WIDTH
    if cat in ("Schott", "Ohara"):
        p[0] = 1.0
        p[9:12] = c[0:3]
        p[12:15] = c[3:6]
    elif cat in ("Hoya", "CDGM", "Sumita"):
        p[0], p[1] = c[0], c[1]
        p[3:7] = c[2:6]
    elif cat == "Hikari":
        p[0], p[1], p[2] = c[0], c[1], c[2]
        p[3:9] = c[3:9]
    else:  # pragma: no cover - CATALOGS is closed
        raise PrescriptionError(f"no dispersion formula known for catalog {cat}")
    return tuple(p)


def _measured_range_nm(cat: str, name: str) -> tuple[float, float] | None:
    from opticalglass.spectral_lines import get_wavelength
    row = _catalog(cat).df.loc[name]["refractive indices"]
    waves = []
    for key, value in row.items():
        try:
            if value is None or not math.isfinite(float(value)):
                continue
            waves.append(float(get_wavelength(key)))
        except (TypeError, ValueError, KeyError):
            continue
    return (min(waves), max(waves)) if waves else None


@lru_cache(maxsize=None)
def _make_catalog_glass(cat: str, name: str) -> CatalogGlass:
    coefs = _catalog(cat).glass_coefs(name)
    if not np.all(np.isfinite(coefs)):
        raise PrescriptionError(f"catalog {cat} has no dispersion coefficients for {name}")
    formula = "Sellmeier (3 terms)" if cat in ("Schott", "Ohara") else \
        "extended power series" if cat == "Hikari" else "Schott power series"
    return CatalogGlass(name=name, catalog=cat, coefficients=_pack_catalog(cat, coefs),
                        range_nm=_measured_range_nm(cat, name), source=f"opticalglass ({cat} catalog)",
                        formula=formula)


@lru_cache(maxsize=1)
def vendor_nd_vd_table() -> tuple[tuple[str, str, float, float], ...]:
    """(catalog, glass, n_d, V_d) of every glass of :data:`CATALOGS`, as the vendors' sheets list them."""
    rows = []
    for cat in CATALOGS:
        df = _catalog(cat).df
        try:
            nd = df["refractive indices"]["d"]
            vd = df["abbe number"]["vd"]
        except KeyError:  # pragma: no cover - every opticalglass sheet has both columns
            continue
        for name, n, v in zip(df.index, nd, vd):
            try:
                n, v = float(n), float(v)
            except (TypeError, ValueError):
                continue
            if math.isfinite(n) and math.isfinite(v):
                rows.append((cat, str(name), n, v))
    return tuple(rows)


def find_exact_vendor_glass(name: str, catalog: str) -> CatalogGlass | None:
    """The glass of vendor ``catalog`` whose name equals ``name`` ignoring case, spaces, hyphens, dots
    and underscores (``NSK16`` = ``N-SK16``), else ``None``. No successor or prefix matching."""
    cat = _canonical_catalog(catalog)
    if cat is None:
        return None
    key = _normalise(name)
    for gname in glass_names(cat):
        if _normalise(gname) == key:
            return _make_catalog_glass(cat, gname)
    return None


def make_vendor_glass(catalog: str, name: str) -> CatalogGlass:
    """The glass ``name`` (exact catalog spelling) of vendor ``catalog``."""
    return _make_catalog_glass(catalog, name)


def find_glass(name: str, catalogs: Iterable[str] | None = None) -> CatalogGlass:
    """Find a vendor glass by the name users write.

    Matching, in order, within ``catalogs`` (default :data:`CATALOGS`): a catalog
    suffix (``N-BK7_SCHOTT``, ``NSK16_SCHOTT``) restricts the search to that
    catalog; then names are compared ignoring case, spaces, hyphens, dots and
    underscores (``NBK7`` = ``N-BK7``); then a bare old Schott name (``SK16``)
    finds Schott's lead-free successor ``N-SK16`` when Schott is searched; then
    ignoring a vendor prefix (``SK16`` finds Hikari's ``J-SK16`` when only Hikari is
    searched), taking the first catalog with exactly one such glass. Callers that
    care should record ``name -> glass.name`` substitutions (the file readers do).

    Raises
    ------
    UnknownGlassError
        If no catalog has the glass; the message suggests the closest names.
    """
    raw = name.strip()
    if not raw:
        raise UnknownGlassError("empty glass name", hint="name a catalog glass, e.g. N-BK7")
    search = [c for c in (_canonical_catalog(c) for c in (catalogs or CATALOGS)) if c]
    if not search:
        search = list(CATALOGS)
    base = raw
    m = re.match(r"^(.*?)[_:](" + "|".join(CATALOGS) + r")$", raw, re.IGNORECASE)
    if m:
        base = m.group(1)
        search = [_canonical_catalog(m.group(2))]  # type: ignore[list-item]
    key = _normalise(base)
    for cat in search:
        for gname in glass_names(cat):
            if _normalise(gname) == key:
                return _make_catalog_glass(cat, gname)
    # A bare name such as SK16 or BK7 is an old Schott name: if Schott is searched, its
    # lead-free successor (N-SK16, same nd/Vd) is the direct match; then other vendors'
    # equivalents (Hikari J-SK16, Sumita K-SK16) in the catalogs' order.
    stripped = _strip_vendor_prefix(base)
    if "Schott" in search and _PREFIX.match(base) is None:
        hits = [g for g in glass_names("Schott") if g.upper().startswith("N-") and _normalise(g[2:]) == key]
        if len(hits) == 1:
            return _make_catalog_glass("Schott", hits[0])
    for cat in search:
        hits = [g for g in glass_names(cat) if _strip_vendor_prefix(g) == stripped]
        if len(hits) == 1:
            return _make_catalog_glass(cat, hits[0])
    pool = {g: cat for cat in search for g in glass_names(cat)}
    close = difflib.get_close_matches(base.upper(), list(pool), n=4, cutoff=0.6)
    hint = ("closest: " + ", ".join(f"{g} ({pool[g]})" for g in close)) if close else \
        f"searched catalogs {', '.join(search)}"
    raise UnknownGlassError(f"glass {raw!r} is in no catalog ({', '.join(search)})", hint=hint)


def parse_material(spec: object, catalogs: Iterable[str] | None = None) -> Material:
    """Turn what a native file or a user gives into a :class:`Material`.

    Accepts ``"air"``/``""``; a glass name (``"N-BK7"``, ``"N-BK7_SCHOTT"``);
    a number (constant index); or a table with ``glass`` (+ ``catalog``),
    ``nd`` + ``vd`` (model glass) or ``index`` (constant).
    """
    if spec is None:
        return AIR
    if isinstance(spec, bool):
        raise PrescriptionError(f"material {spec!r} is not a glass, a number or a table")
    if isinstance(spec, (int, float)):
        return AIR if float(spec) == 1.0 else ConstantIndex(float(spec))
    if isinstance(spec, str):
        text = spec.strip()
        if text == "" or text.upper() == "AIR":
            return AIR
        return find_glass(text, catalogs)
    if isinstance(spec, dict):
        keys = set(spec)
        if {"glass", "coefficients"} <= keys:
            return _packed_glass(spec)
        if "glass" in keys:
            cats = [spec["catalog"]] if "catalog" in spec else catalogs
            if "catalog" in spec and _canonical_catalog(str(spec["catalog"])) is None:
                raise UnknownGlassError(f"unknown glass catalog {spec['catalog']!r}",
                                        hint=f"use one of {', '.join(CATALOGS)}")
            return find_glass(str(spec["glass"]), cats)
        if {"nd", "vd"} <= keys:
            return ModelGlass(float(spec["nd"]), float(spec["vd"]), name=str(spec.get("name", "")))
        if "index" in keys:
            n = float(spec["index"])
            exotic = spec.get("exotic", False)
            if not isinstance(exotic, bool):
                raise PrescriptionError(f"exotic must be true or false, not {exotic!r}")
            return AIR if n == 1.0 else ConstantIndex(n, name=str(spec.get("name", "")), exotic=exotic)
        raise PrescriptionError(f"material table {spec!r} needs 'glass', 'nd'+'vd' or 'index'")
    raise PrescriptionError(f"material {spec!r} is not a glass name, a number or a table")


def _packed_glass(spec: dict) -> CatalogGlass:
    """A glass given by its packed coefficients (how the native format stores non-vendor glasses)."""
    coefs = spec["coefficients"]
    if not isinstance(coefs, list) or len(coefs) != DISPERSION_WIDTH or \
            not all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in coefs):
        raise PrescriptionError(f"glass {spec['glass']!r}: coefficients must be {DISPERSION_WIDTH} finite numbers")
    rng = spec.get("range_nm")
    if rng is not None and (not isinstance(rng, list) or len(rng) != 2 or
                            not all(isinstance(v, (int, float)) and math.isfinite(v) for v in rng)):
        raise PrescriptionError(f"glass {spec['glass']!r}: range_nm must be two numbers (nm)")
    glass = CatalogGlass(name=str(spec["glass"]), catalog=str(spec.get("catalog", "")),
                         coefficients=tuple(float(c) for c in coefs),
                         range_nm=None if rng is None else (float(rng[0]), float(rng[1])),
                         source=str(spec.get("source", "native file")), formula=str(spec.get("formula", "")),
                         range_is_limit=bool(spec.get("range_is_limit", False)))
    n = glass.index(FRAUNHOFER_NM["d"]) if rng is None or rng[0] <= FRAUNHOFER_NM["d"] <= rng[1] else \
        glass.index(0.5 * (float(rng[0]) + float(rng[1])))
    if not (math.isfinite(n) and 1.0 <= n <= 5.0):
        raise PrescriptionError(f"glass {spec['glass']!r}: its coefficients give n = {n!r}, not a physical index")
    return glass


def check_wavelength_range(materials: Iterable[Material], wavelength_nm: Iterable[float]) -> list[str]:
    """Messages (and :class:`ExtrapolationWarning` s) for wavelengths outside a glass's data range.

    Raises
    ------
    PrescriptionError
        For a material whose range is a limit (``CatalogGlass.range_is_limit``:
        crystals and semiconductors, e.g. germanium at 550 nm).
    """
    msgs = []
    waves = [float(w) for w in wavelength_nm]
    for mat in sorted(set(materials), key=lambda m: m.describe()):
        rng = mat.valid_range_nm
        if rng is None:
            continue
        bad = [w for w in waves if w < rng[0] - 1e-9 or w > rng[1] + 1e-9]
        if bad and getattr(mat, "range_is_limit", False):
            raise PrescriptionError(
                f"{mat.describe()} has no index data at {', '.join(f'{w:g}' for w in bad)} nm "
                f"(its formula covers {rng[0]:g}-{rng[1]:g} nm)",
                hint="use wavelengths inside that range (see 'lensrt glass NAME') or another material")
        if bad:
            msg = (f"{mat.describe()}: dispersion formula extrapolated at {', '.join(f'{w:g}' for w in bad)} nm "
                   f"(catalog data cover {rng[0]:g}-{rng[1]:g} nm)")
            warnings.warn(msg, ExtrapolationWarning, stacklevel=2)
            msgs.append(msg)
    return msgs
