"""Read the tables of the CODE V listing tests/data/ag_dblgauss.lis (the published oracle).

Values are kept as printed (strings) so that tests can compare to the listing's own digits.
"""
from __future__ import annotations

import re
from pathlib import Path

LISTING = Path(__file__).resolve().parents[1] / "data" / "ag_dblgauss.lis"


def _block(lines: list[str], command: str) -> list[str]:
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f"CODE V> {command}"))
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("CODE V>"))
    return lines[start + 1:end]


def _rows(block: list[str]) -> dict[str, list[str]]:
    rows = {}
    for ln in block:
        parts = ln.split()
        if parts and (parts[0].isdigit() or parts[0] in ("EP", "STO", "IMG", "SUM")) and len(parts) > 2:
            rows[parts[0]] = parts[1:]
    return rows


def tho_table() -> dict[str, list[str]]:
    """``tho``: row label ('1'..'11', 'STO', 'SUM') -> [SA, TCO, TAS, SAS, PTB, DST, AX, LAT, PTZ]."""
    return _rows(_block(LISTING.read_text().splitlines(), "tho"))


def fio_table() -> dict[str, list[str]]:
    """``fio``: row label -> printed numbers (EP and IMG rows have no N*I columns)."""
    return _rows(_block(LISTING.read_text().splitlines(), "fio"))


def first_order_values() -> dict[str, str]:
    """The INFINITE CONJUGATES block: EFL, BFL, FFL, FNO, IMG DIS, OAL, HT, ANG, EP/XP DIA and THI."""
    lines = _block(LISTING.read_text().splitlines(), "lis")
    start = next(i for i, ln in enumerate(lines) if "INFINITE CONJUGATES" in ln)
    out, section = {}, ""
    for ln in lines[start + 1:]:
        m = re.match(r"\s+([A-Z][A-Z ]*?)\s+(-?\d+\.\d+)\s*$", ln)
        if m:
            out[(section + " " + m.group(1)).strip()] = m.group(2)
        elif ln.strip():
            section = ln.strip()
            if section == "PARAXIAL IMAGE":
                section = ""
    return out


def decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0
