"""Find the glass a lens file names, the way a user expects, and say what was approximated.

Order (:func:`resolve_glass`):

1. the file's private glasses (CODE V ``PRV``) and the catalogs the file names
   (Zemax ``GCAT``): vendor catalogs through ``opticalglass``, the same vendor's
   pages of the refractiveindex.info database (obsolete and renamed glasses,
   e.g. Hikari ``SK16``), and user ``.agf`` catalogs of that name;
2. every other catalog lensrt has: the six vendors, the database's vendor
   shelves, user ``.agf`` catalogs, the crystals/semiconductors/silica by
   name or alias (``F_SILICA``, ``CAF2``, ``GERMANIUM`` ...) and the obsolete
   glasses of the 1980 catalogs (:mod:`~lensrt.prescription.robb1983`: Schott
   ``BK7``, ``SK19``, ``KZFSN5``) -- with a warning naming the catalog used;
   then another grade of a vendor's glass for a name that no catalog lists
   (Ohara ``S-LAL7Q`` -> ``S-LAL7``, Schott ``LF5HT`` -> ``LF5HTi``), only where
   the line's n_d/V_d confirm it; likewise a name its transcriber marked as
   uncertain with a trailing ``?`` (``SF12?`` -> Hikari ``SF12``: the file's
   catalogs first, then every catalog);
3. only with ``substitute``: a successor or another vendor's equivalent
   (``SK16`` -> ``N-SK16``), with a warning naming both glasses and the index
   difference at the primary wavelength;
4. only with ``model_fallback``: the line's n_d/V_d as a model glass;
5. else one :class:`~lensrt.errors.UnknownGlassError` naming the catalogs
   searched and the ways to supply the glass.

A catalog name always wins over n_d/V_d written on the line (as OpticStudio
does); where those differ from the catalog's by more than 1e-3 the warning says so.

User catalogs come from :func:`glass_policy` (``--glass-catalog PATH``, files
or folders of ``.agf``) and from the folder ``$LENSRT_GLASS_DIR`` (default
``~/.config/lensrt/glass``).
"""
from __future__ import annotations

import contextlib
import os
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Mapping, Sequence

from ..errors import UnknownGlassError
from ..units import FRAUNHOFER_NM
from .agf import AgfCatalog, read_agf
from .materials import (CATALOGS, CatalogGlass, Material, ModelGlass, find_exact_vendor_glass, find_glass,
                        make_vendor_glass, vendor_nd_vd_table)
from .model import LoadWarning
from .rii import find_rii_glass, find_rii_material
from .robb1983 import find_robb_glass

__all__ = ["GlassPolicy", "glass_policy", "current_policy", "user_catalogs", "resolve_glass", "GlassRequest",
           "LINE_TOLERANCE", "NEAREST_TOLERANCE", "VARIANT_SUFFIXES", "VARIANT_TOLERANCE", "CATALOG_PREFIXES",
           "split_catalog_suffix", "lookup_any", "vendor_of", "nearest_glass"]

#: largest |n_d(line) - n_d(catalog)| taken without a word
LINE_TOLERANCE = 1e-3
#: how close (n_d, V_d) a glass must be to the line's to substitute for a name without a successor
NEAREST_TOLERANCE = (5e-3, 1.5)


@dataclass(frozen=True)
class GlassPolicy:
    """What a reader may do when a glass is not found as named (CLI: ``--glass-*`` options)."""

    substitute: bool = False
    model_fallback: bool = False
    catalog_paths: tuple[str, ...] = ()


_POLICY: ContextVar[GlassPolicy] = ContextVar("lensrt_glass_policy", default=GlassPolicy())


@contextlib.contextmanager
def glass_policy(substitute: bool = False, model_fallback: bool = False,
                 catalog_paths: Sequence[str | Path] = ()) -> Iterator[GlassPolicy]:
    """Readers inside this block follow this policy (see the module docstring)."""
    pol = GlassPolicy(bool(substitute), bool(model_fallback), tuple(str(p) for p in catalog_paths))
    token = _POLICY.set(pol)
    try:
        yield pol
    finally:
        _POLICY.reset(token)


def current_policy() -> GlassPolicy:
    return _POLICY.get()


def _config_dir() -> Path:
    env = os.environ.get("LENSRT_GLASS_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "lensrt" / "glass"


def user_catalogs(policy: GlassPolicy | None = None) -> tuple[AgfCatalog, ...]:
    """The ``.agf`` catalogs of the policy's paths (files or folders) and of the config folder."""
    pol = policy or current_policy()
    files: list[Path] = []
    for raw in pol.catalog_paths:
        p = Path(raw)
        files += sorted(p.glob("*.agf")) + sorted(p.glob("*.AGF")) if p.is_dir() else [p]
    cfg = _config_dir()
    if cfg.is_dir():
        files += sorted(cfg.glob("*.agf")) + sorted(cfg.glob("*.AGF"))
    return tuple(read_agf(str(f)) for f in files)


def split_catalog_suffix(name: str) -> tuple[str, str | None]:
    """``NSK16_SCHOTT`` -> (``NSK16``, ``Schott``); a name without a vendor suffix is returned as is."""
    for cat in CATALOGS:
        for sep in ("_", ":"):
            if name.upper().endswith(sep + cat.upper()) and len(name) > len(cat) + 1:
                return name[: -len(cat) - 1], cat
    return name, None


@dataclass
class GlassRequest:
    """One glass a file names, with what the line says about it."""

    name: str
    file_catalogs: Sequence[str] | None = None    # GCAT names (upper case) or None when the file names none
    nd: float | None = None                         # the line's n_d/V_d, when real (not 0 or absent)
    vd: float | None = None
    surface: int | None = None
    line: int | None = None
    primary_nm: float = FRAUNHOFER_NM["d"]
    private: Mapping[str, Material] = field(default_factory=dict)


def _in_catalogs(name: str, cats: Sequence[str], agfs: Sequence[AgfCatalog]) -> CatalogGlass | None:
    """The glass ``name`` of the first of ``cats`` that holds it: user .agf and vendor catalogs
    (``opticalglass``) first, in ``cats`` order, then the database's shelves of those vendors."""
    for cat in cats:
        for a in agfs:
            if a.name == cat.upper():
                g = a.find(name)
                if g is not None:
                    return g
        g = find_exact_vendor_glass(name, cat)
        if g is not None:
            return g
    if not cats:
        return None
    g = find_rii_glass(name, tuple(cats)) or find_robb_glass(name, tuple(cats))
    for cat in cats if g is None else ():
        prefix = CATALOG_PREFIXES.get(cat.upper())
        if prefix and name.upper().startswith(prefix) and len(name) > len(prefix):
            g = find_rii_glass(name[len(prefix):], (cat,))
            if g is not None:
                break
    return g


def vendor_of(catalog: str, agfs: Sequence[AgfCatalog] = ()) -> str | None:
    """The vendor a renamed catalog belongs to (``OHARA-CALDWELL2`` -> ``Ohara``), else ``None``.

    A catalog lensrt has under that exact name (a vendor or a user .agf) is not renamed.
    """
    key = catalog.upper()
    if any(a.name == key for a in agfs) or any(c.upper() == key for c in CATALOGS):
        return None
    for cat in CATALOGS:
        if key.startswith(cat.upper()) and not key[len(cat):len(cat) + 1].isalpha():
            return cat
    return None


def lookup_any(name: str, agfs: Sequence[AgfCatalog] = ()) -> CatalogGlass | None:
    """The glass ``name`` in any catalog lensrt has (user .agf, vendors, database shelves, aliases)."""
    base, suffix = split_catalog_suffix(name)
    if suffix is not None:
        return _in_catalogs(base, [suffix], agfs)
    for a in agfs:
        g = a.find(name)
        if g is not None:
            return g
    g = find_rii_material(name)  # the aliases first: cheap, and no vendor sheet names a glass F_SILICA or CAF2
    if g is not None:
        return g
    for cat in CATALOGS:
        g = find_exact_vendor_glass(name, cat)
        if g is not None:
            return g
    for cat, prefix in CATALOG_PREFIXES.items():  # OpticStudio's LZ_K8 without its GCAT LZOS
        if name.upper().startswith(prefix) and len(name) > len(prefix):
            g = find_rii_glass(name[len(prefix):], (cat,))
            if g is not None:
                return g
    return find_rii_glass(name) or find_robb_glass(name)


def nearest_glass(nd: float, vd: float, prefer: Sequence[str] = ()) -> CatalogGlass | None:
    """The vendor glass nearest to (n_d, V_d) within :data:`NEAREST_TOLERANCE`, preferring ``prefer``'s catalogs."""
    dn_max, dv_max = NEAREST_TOLERANCE
    best = None
    pref = [p.upper() for p in prefer]
    for cat, name, n, v in vendor_nd_vd_table():
        if abs(n - nd) <= dn_max and abs(v - vd) <= dv_max:
            score = (0 if cat.upper() in pref else 1, abs(n - nd) / dn_max + abs(v - vd) / dv_max)
            if best is None or score < best[0]:
                best = (score, cat, name)
    return None if best is None else make_vendor_glass(best[1], best[2])


def _dn(glass: Material, req: GlassRequest) -> float | None:
    return None if req.nd is None else float(glass.index(FRAUNHOFER_NM["d"])) - req.nd


def _line_check(glass: Material, req: GlassRequest, out: list[LoadWarning]) -> None:
    dn = _dn(glass, req)
    if dn is not None and abs(dn) > LINE_TOLERANCE:
        out.append(LoadWarning("glass_line_disagrees",
                               f"glass {req.name}: the line's n_d = {req.nd:.6f} differs from {glass.describe()}'s "
                               f"{req.nd + dn:.6f} by {-dn:+.2e}; the catalog's data are used", req.surface, req.line))


def _provenance(glass: Material, req: GlassRequest, out: list[LoadWarning]) -> None:
    """Say so when the data are not a vendor's formula: an obsolete glass's 1980 model, a fitted table."""
    source = getattr(glass, "source", "")
    if source.startswith("Robb"):
        nd = float(glass.index(FRAUNHOFER_NM["d"]))
        diff = f"; the line's n_d = {req.nd:g} differs by {req.nd - nd:+.2e}" if req.nd is not None else ""
        out.append(LoadWarning("glass_obsolete", f"glass {req.name}: obsolete glass {glass.describe()}, in no current "
                               f"catalog; index from {source}: {getattr(glass, 'formula', '')}; n_d = {nd:.5f}"
                               f"{diff}", req.surface, req.line))
    elif "fitted to the page" in getattr(glass, "formula", ""):
        out.append(LoadWarning("glass_fitted", f"glass {req.name}: {glass.describe()} from {source}, a table of n "
                               f"only: {glass.formula}", req.surface, req.line))


#: suffixes a vendor adds to a glass without changing its n_d/V_d: Ohara's ``Q`` (its catalog's S-LAL54Q, S-LAH52Q
#: and S-LAH63Q list the same n_d and V_d as S-LAL54, S-LAH52 and S-LAH63) and Schott's transmission grades ``HT``,
#: ``HTi``, ``HTultra`` (N-BK7 = N-BK7HT = N-BK7HTi: 1.5168/64.17); the first entry is the plain name
VARIANT_SUFFIXES: dict[str, tuple[str, ...]] = {"Ohara": ("", "Q"), "Schott": ("", "HT", "HTi", "HTultra")}
#: how close the line's (n_d, V_d) must be to the other grade's for a variant name to be read as that glass
VARIANT_TOLERANCE = (1e-3, 0.5)
#: the prefix OpticStudio's catalog of a vendor puts before that vendor's glass names (``LZ_K8`` in LZOS.AGF)
CATALOG_PREFIXES: dict[str, str] = {"LZOS": "LZ_"}


def _variant(base: str, req: GlassRequest) -> CatalogGlass | None:
    """Another grade of a vendor's glass for a name that no catalog lists (``S-LAL7Q`` -> Ohara ``S-LAL7``,
    ``LF5HT`` -> Schott ``LF5HTi``).

    Taken only when the line's n_d and V_d confirm it within :data:`VARIANT_TOLERANCE` (the catalogs
    cannot: they do not list the name).
    """
    if req.nd is None or req.vd is None:
        return None
    for vendor, suffixes in VARIANT_SUFFIXES.items():
        own = max((s for s in suffixes if base.upper().endswith(s.upper())), key=len)
        root = base[: len(base) - len(own)]
        for other in suffixes:
            if other == own or not root:
                continue
            g = find_exact_vendor_glass(root + other, vendor) or find_rii_glass(root + other, (vendor,))
            if g is None:
                continue
            if _line_confirms(g, req):
                return g
    return None


def _line_confirms(g: CatalogGlass, req: GlassRequest) -> bool:
    """Whether the line's n_d and V_d agree with glass ``g`` within :data:`VARIANT_TOLERANCE`."""
    nd = float(g.index(FRAUNHOFER_NM["d"]))
    vd = (nd - 1.0) / float(g.index(FRAUNHOFER_NM["F"]) - g.index(FRAUNHOFER_NM["C"]))
    return abs(nd - req.nd) <= VARIANT_TOLERANCE[0] and abs(vd - req.vd) <= VARIANT_TOLERANCE[1]


def _uncertain(base: str, req: GlassRequest, own: Sequence[str], agfs: Sequence[AgfCatalog]
               ) -> CatalogGlass | None:
    """The glass a name marked uncertain (``SF12?``) names, taken only when the line's n_d and V_d confirm it within
    :data:`VARIANT_TOLERANCE` (the file's catalogs first, then every catalog lensrt has)."""
    name = base.rstrip("?").strip()
    if name == base or not name or req.nd is None or req.vd is None:
        return None
    for g in (_in_catalogs(name, own, agfs), lookup_any(name, agfs)):
        if g is None:
            continue
        if _line_confirms(g, req):
            return g
    return None


def _searched(req: GlassRequest, agfs: Sequence[AgfCatalog]) -> str:
    named = ", ".join(req.file_catalogs) if req.file_catalogs else "none"
    users = ", ".join(f"{a.name} ({a.path})" for a in agfs) or "none"
    return (f"the file's catalogs ({named}), then {', '.join(CATALOGS)} (opticalglass), the refractiveindex.info "
            f"database's vendor shelves and materials, user catalogs: {users}")


def resolve_glass(req: GlassRequest, policy: GlassPolicy | None = None) -> tuple[Material, list[LoadWarning]]:
    """The material for ``req`` and the warnings that describe any approximation (module docstring)."""
    pol = policy or current_policy()
    agfs = user_catalogs(pol)
    out: list[LoadWarning] = []
    name = req.name
    base, suffix = split_catalog_suffix(name)
    # 1. private glasses, then the file's own catalogs
    for key, mat in req.private.items():
        if key.upper() == name.upper():
            out.append(LoadWarning("glass_private", f"glass {name}: the file's private catalog ({mat.describe()}; "
                                   f"{getattr(mat, 'formula', '')})",
                                   req.surface, req.line))
            return mat, out
    own = [suffix] if suffix else list(req.file_catalogs or ())
    g = _in_catalogs(base, own, agfs)
    if g is None:  # a renamed vendor catalog (OHARA-CALDWELL2, SCHOTT_2000): that vendor's current catalog
        renamed = {c: vendor_of(c, agfs) for c in own}
        g = _in_catalogs(base, [v for v in renamed.values() if v], agfs)
        if g is not None:
            orig = next(c for c, v in renamed.items() if v and v.upper() == g.catalog.upper())
            out.append(LoadWarning("glass_other_catalog", f"glass {name}: the file's catalog {orig} read as "
                                   f"lensrt's {g.catalog} catalog ({g.describe()}, {g.source})", req.surface,
                                   req.line))
    if g is not None:
        _provenance(g, req, out)
        _line_check(g, req, out)
        return g, out
    # 2. every catalog lensrt has
    g = lookup_any(base, agfs)
    if g is not None:
        alias = g.catalog == "refractiveindex.info"
        from_db = g.source.startswith("refractiveindex.info")
        _provenance(g, req, out)
        if own or alias or from_db:
            code = "glass_alias" if alias else "glass_other_catalog"
            dn = _dn(g, req)
            diff = f"; its n_d differs from the line's by {dn:+.2e}" if dn is not None else ""
            where = f"not in the file's catalogs ({', '.join(own)}); " if own else ""
            out.append(LoadWarning(code, f"glass {name}: {where}using {g.describe()} from {g.source}{diff}",
                                   req.surface, req.line))
        else:
            _line_check(g, req, out)
        return g, out
    g = _variant(base, req)
    if g is not None:
        out.append(LoadWarning("glass_variant", f"glass {name}: in no catalog lensrt has; read as {g.describe()} "
                               f"from {g.source}, another grade of the same glass, as the line's n_d = "
                               f"{req.nd:g}, V_d = {req.vd:g} confirm (n_d differs by "
                               f"{float(g.index(FRAUNHOFER_NM['d'])) - req.nd:+.2e})",
                               req.surface, req.line))
        return g, out
    g = _uncertain(base, req, own, agfs)
    if g is not None:
        out.append(LoadWarning("glass_uncertain_name", f"glass {name}: a name marked uncertain; read as "
                               f"{g.describe()} from {g.source}, as the line's n_d = {req.nd:g}, V_d = {req.vd:g} "
                               f"confirm (n_d differs by {float(g.index(FRAUNHOFER_NM['d'])) - req.nd:+.2e})",
                               req.surface, req.line))
        return g, out
    # 3. a successor or another vendor's equivalent, on request
    how = "its successor or another vendor's equivalent"
    try:
        succ = find_glass(base, list(CATALOGS))
    except UnknownGlassError:
        succ = None
        if req.nd is not None and req.vd is not None:
            succ = nearest_glass(req.nd, req.vd, own)
            how = f"the vendor glass nearest the line's n_d = {req.nd:g}, V_d = {req.vd:g} (if those are " \
                  "placeholders, so is this choice)"
    if succ is not None and pol.substitute:
        n_line = f"{req.nd:.6f} (the line)" if req.nd is not None else "unknown (no catalog data)"
        out.append(LoadWarning("glass_substituted",
                               f"glass {name} substituted by {succ.describe()}, {how} (--glass-substitute): n = "
                               f"{float(succ.index(req.primary_nm)):.6f} at {req.primary_nm:g} nm; {name}'s n_d "
                               f"{n_line}" + (f", difference {float(succ.index(FRAUNHOFER_NM['d'])) - req.nd:+.2e}"
                                              if req.nd is not None else ""), req.surface, req.line))
        return succ, out
    # 4. the line's model values, on request
    if pol.model_fallback and req.nd is not None and req.vd is not None:
        out.append(LoadWarning("glass_model", f"glass {name} is in no catalog lensrt has: the line's n_d = "
                               f"{req.nd:g}, V_d = {req.vd:g} are used as a model glass (--glass-model-fallback)",
                               req.surface, req.line))
        return ModelGlass(req.nd, req.vd, name=name), out
    hints = [f"add its catalog with --glass-catalog PATH.agf (or put the .agf in {_config_dir()})"]
    if succ is not None:
        hints.append(f"--glass-substitute takes {succ.describe()}")
    if req.nd is not None and req.vd is not None:
        hints.append(f"--glass-model-fallback takes the line's n_d = {req.nd:g}, V_d = {req.vd:g}")
    raise UnknownGlassError(f"glass {name!r} is in no catalog lensrt reads (searched {_searched(req, agfs)})",
                            line=req.line, hint="; ".join(hints))
