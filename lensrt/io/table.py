"""Plain-text tables for the terminal, and JSON that never holds NaN."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

__all__ = ["format_table", "format_cell", "Table", "to_jsonable", "dumps_json", "write_json"]


def _cell(value: Any, digits: int) -> str:
    if value is None:
        return "-"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        if math.isnan(v):
            return "-"  # undefined (no analysis presents nan as a result; notes say why)
        return f"{v:.{digits}f}" if abs(v) < 1e7 else f"{v:.{digits}g}"
    return str(value)


def format_cell(value: Any, digits: int = 4) -> str:
    """One table cell as text: floats with ``digits`` decimals, None and nan (undefined) as "-", inf spelled out."""
    return _cell(value, digits)


def format_table(rows: Sequence[Sequence[Any]], headers: Sequence[str], digits: int = 4,
                 title: str | None = None) -> str:
    """Right-aligned text table; floats with ``digits`` decimals."""
    cells = [[_cell(v, digits) for v in row] for row in rows]
    widths = [max([len(h)] + [len(r[i]) for r in cells]) for i, h in enumerate(headers)]
    lines = []
    if title:
        lines.append(title)
    lines.append("  ".join(h.rjust(w) for h, w in zip(headers, widths)))
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    return "\n".join(lines)


@dataclass
class Table:
    """A table before it is laid out: as text (:meth:`text`, :func:`format_table`) or as HTML
    (:func:`lensrt.report.html.html_table`)."""

    rows: Sequence[Sequence[Any]]
    headers: Sequence[str]
    digits: int = 4
    title: str | None = None

    def text(self) -> str:
        return format_table(self.rows, self.headers, self.digits, self.title)


def to_jsonable(value: Any) -> Any:
    """Convert numpy types and non-finite floats (-> None) for strict JSON."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if hasattr(value, "to_dict"):
        return to_jsonable(value.to_dict())
    return value


def dumps_json(value: Any, indent: int | None = 2) -> str:
    """Strict JSON text (no NaN/Infinity tokens) of ``value``."""
    return json.dumps(to_jsonable(value), indent=indent, allow_nan=False)


def write_json(path: str | Path, value: Any, indent: int | None = 2) -> Path:
    """Write :func:`dumps_json` of ``value`` and a newline to the file ``path``; returns the path."""
    p = Path(path)
    p.write_text(dumps_json(value, indent) + "\n")
    return p
