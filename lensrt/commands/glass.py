"""``lensrt glass NAME``: where a material's data come from, its formula, range and indices."""
from __future__ import annotations

import argparse
from typing import Any

from ._common import emit, print_json

__all__ = ["register", "glass_data"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("glass", help="a glass's source, dispersion formula, valid range and indices",
                       description="Look a glass or material up the way the lens readers do and print where its "
                                   "data come from, its formula, the wavelength range of the data and its "
                                   "indices (docs/guide/glass.md).")
    p.add_argument("name", metavar="NAME", help="glass name (N-BK7, SK16, F_SILICA, GERMANIUM, N-BK7_SCHOTT ...)")
    p.add_argument("--catalog", action="append", default=None, metavar="C",
                   help="search this catalog first (SCHOTT, HIKARI, or the stem of an .agf); repeatable")
    p.add_argument("--glass-catalog", action="append", default=None, metavar="PATH",
                   help="a Zemax .agf catalog (or a folder of them) to search too")
    p.add_argument("--glass-substitute", action="store_true", help="accept a successor glass (SK16 -> N-SK16)")
    p.add_argument("--wavelength-nm", type=float, nargs="+", metavar="W",
                   help="wavelengths in nm (default: F, d, C lines 486.1327, 587.5618, 656.2725)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_glass)


def glass_data(name: str, catalogs: list[str] | None = None, wavelength_nm: list[float] | None = None,
               glass_catalog: list[str] | None = None, substitute: bool = False) -> dict[str, Any]:
    """Everything ``lensrt glass --json`` prints."""
    import math

    from ..prescription.glass_lookup import GlassRequest, glass_policy, resolve_glass
    from ..units import FRAUNHOFER_NM
    with glass_policy(substitute=substitute, catalog_paths=glass_catalog or ()):
        mat, warns = resolve_glass(GlassRequest(name, [c.upper() for c in catalogs] if catalogs else None))
    waves = list(wavelength_nm or [FRAUNHOFER_NM["F"], FRAUNHOFER_NM["d"], FRAUNHOFER_NM["C"]])
    rng = mat.valid_range_nm
    out_of_range = [w for w in waves if rng is not None and not (rng[0] - 1e-9 <= w <= rng[1] + 1e-9)]
    limit = bool(getattr(mat, "range_is_limit", False))
    inside = [w for w in waves if w not in out_of_range or not limit]
    vd = mat.abbe_number()
    return {
        "name": mat.name, "asked": name, "catalog": getattr(mat, "catalog", ""),
        "source": getattr(mat, "source", "") or "n_d/V_d model", "formula": getattr(mat, "formula", ""),
        "valid_range_nm": list(rng) if rng is not None else None,
        "outside_range": "error" if limit else "extrapolated with a warning",
        "nd": float(mat.index(FRAUNHOFER_NM["d"])) if not limit or not rng or rng[0] <= FRAUNHOFER_NM["d"] <= rng[1]
        else None,
        "vd": vd if math.isfinite(vd) and (not limit or (rng and rng[0] <= 486.1327 and rng[1] >= 656.2725))
        else None,
        "indices": [{"wavelength_nm": w, "n": float(mat.index(w)), "extrapolated": w in out_of_range}
                    for w in inside],
        "no_data_nm": [w for w in out_of_range if limit],
        "packed_coefficients": list(mat.packed()),
        "warnings": [w.to_dict() for w in warns],
    }


def cmd_glass(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    d = glass_data(args.name, args.catalog, args.wavelength_nm, args.glass_catalog, args.glass_substitute)
    if args.json:
        print_json(d)
        return 0
    emit(f"{d['name']} ({d['catalog']})" if d["catalog"] else d["name"])
    emit(f"source: {d['source']}")
    if d["formula"]:
        emit(f"formula: {d['formula']}")
    if d["valid_range_nm"]:
        lo, hi = d["valid_range_nm"]
        emit(f"data range: {lo:g} - {hi:g} nm (outside it: {d['outside_range']})")
    if d["nd"] is not None:
        emit(f"n_d = {d['nd']:.6f}" + (f", V_d = {d['vd']:.3f}" if d["vd"] is not None else ""))
    rows = [[r["wavelength_nm"], r["n"], "extrapolated" if r["extrapolated"] else ""] for r in d["indices"]]
    if rows:
        emit(format_table(rows, ["wavelength_nm", "n", ""], digits=7))
    if d["no_data_nm"]:
        emit("no data at " + ", ".join(f"{w:g}" for w in d["no_data_nm"]) + " nm")
    for w in d["warnings"]:
        emit(f"warning [{w['code']}]: {w['text']}")
    return 0
