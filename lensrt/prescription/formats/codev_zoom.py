"""CODE V zoom data: ``ZOO`` commands (one value per zoom position) and ``POS``.

Read::

    ZOO THI S5 1.86 25.27 48.678      ! thickness after surface 5 in positions 1, 2, 3
    ZOO THI SO 1e10 2000 700          ! the object distance (1e10 and above: infinity)
    ZOO RDY S3 ...   ZOO CUY S3 ...   ZOO K S3 ...   ZOO GLA S3 NBK7_SCHOTT ...   ZOO CIR S8 ...
    ZOO EPD 20 25 30                  ! (or FNO, NAO: the file's aperture kind)
    ZOO YAN F3 14 8 5                 ! (XAN, YOB, XOB, YIM, XIM, YRI, XRI: the file's field kind)
    ZOO WL W2 587.6 ...               ! ZOO WTW W2 ..., ZOO WTF F2 ...
    ZOO STO S10 S11 S10               ! the stop surface per position
    ZOO YDE S2 0 1.25 -1.25           ! (or XDE) a basic decenter of surface 2 per position; on a DAR, REV or
                                      ! BEN surface an error
    ZOO VUY F1 0.1 0.1 0.1            ! (VLY, VUX, VLX) a field's vignetting factor per position: read only where
                                      ! every position repeats the sequence's own factor (nothing zooms)
    ZOO REF 2 2 2
    POS 2                             ! the current position (default 1)

and what CODE V writes around them when it saves a zoomed lens::

    ZOO 3                             ! the number of positions (then every ZOO row gives 3 values)
    ZOO TIT                           ! the positions carry titles:
    TIT Z1 'wide'                     ! the title of position 1 (CODE V writes ""wide"": quotes stripped)
    ZOO THC S5 100 100 100            ! variable/solve codes per position (THC, CCY, GLC, YDC, ...): no
                                      ! optics, skipped

Every ``ZOO`` command must give the same number of positions (``ZOO n`` or the
first one sets it). Any other zoomed item is an error naming it.
"""
from __future__ import annotations

import math
import re
from typing import Callable

from ...errors import PrescriptionError
from ...units import deg_to_rad
from ..configurations import ConfigOperand, MultiConfigLens
from ..materials import Material
from ..model import Lens
from ._common import parse_number

__all__ = ["ZOOM_ITEMS", "ZoomReader"]

#: zoomed item -> (configuration operand kind, qualifier: S surface, F field, W wavelength, - none)
ZOOM_ITEMS: dict[str, tuple[str, str]] = {
    "THI": ("thickness", "S"), "RDY": ("curvature", "S"), "CUY": ("curvature", "S"), "K": ("conic", "S"),
    "GLA": ("material", "S"), "CIR": ("semi_diameter", "S"), "STO": ("stop_surface", "-"),
    "EPD": ("aperture", "-"), "FNO": ("aperture", "-"), "NAO": ("aperture", "-"),
    "WL": ("wavelength", "W"), "WTW": ("wavelength_weight", "W"), "WTF": ("field_weight", "F"),
    "REF": ("primary_wavelength", "-"), "XDE": ("decenter_x", "S"), "YDE": ("decenter_y", "S"),
    **{f"{a}{k}": ("field_y" if a == "Y" else "field_x", "F") for a in "XY" for k in ("AN", "OB", "IM", "RI")},
}
#: CODE V's per-position optimisation codes (variable, frozen, solve): they carry no optics
ZOOM_CODES = frozenset({"THC", "CCY", "GLC", "KC", *(f"{c}C" for c in "ABCDEFGHJ"),
                        *(f"{a}DC" for a in "XYZABC")})
#: vignetting factors: zoomed only where every position repeats the sequence's value (:meth:`ZoomReader.vignetting`)
VIGNETTING_ITEMS = ("VUX", "VLX", "VUY", "VLY")
_SURF = re.compile(r"^S(\d+|O|I)$", re.IGNORECASE)
_QUAL = re.compile(r"^([FW])(\d+)$", re.IGNORECASE)


class ZoomReader:
    """Collects ``ZOO``/``POS`` commands of a sequence and builds the :class:`MultiConfigLens`."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        self.count: int | None = None
        self.current = 0
        self.pos_line: int | None = None
        self.items: list[tuple[str, str, list[str], int]] = []  # item, qualifier, values, line
        self.count_line: int | None = None
        self.titles: dict[int, str] = {}  # position (0-based) -> TIT Zk title
        self.vignetting_rows: list[tuple[str, list[str], int]] = []  # ZOO VUY F1 v1 .. vn (item, args, line)

    def err(self, msg: str, line: int | None, hint: str | None = None) -> PrescriptionError:
        return PrescriptionError(msg, path=self.path, line=line, hint=hint)

    def command(self, name: str, args: list[str], line: int) -> None:
        """Record a ``ZOO`` or ``POS`` command."""
        if name == "POS":
            if len(args) != 1:
                raise self.err("POS needs one position number", line, "e.g. POS 2")
            self.current = int(parse_number(args[0], "position", path=self.path, line=line)) - 1
            self.pos_line = line
            return
        if not args:
            raise self.err("ZOO without an item", line, "e.g. ZOO THI S5 1.86 25.27 48.678")
        item = args[0].upper()
        if item.isdigit() and len(args) == 1:
            self.declare(int(item), line)
            return
        if item == "TIT" and len(args) == 1:
            return  # the titles follow as TIT Zk lines
        if item in ZOOM_CODES:
            return
        if item in VIGNETTING_ITEMS:
            self.vignetting_rows.append((item, args[1:], line))
            self.count = self.count if self.count is not None else max(len(args) - 2, 1)
            return
        if item not in ZOOM_ITEMS:
            raise self.err(f"ZOO {item}: zooming {item} is not supported", line,
                           f"lensrt zooms {', '.join(sorted(ZOOM_ITEMS))}")
        need = ZOOM_ITEMS[item][1]
        qual, values = "", args[1:]
        if need != "-":
            if not values:
                raise self.err(f"ZOO {item} needs a {'surface (S5)' if need == 'S' else need + '1'}", line)
            qual, values = values[0].upper(), values[1:]
            ok = _SURF.match(qual) if need == "S" else (_QUAL.match(qual) and qual[0] == need)
            if not ok:
                raise self.err(f"ZOO {item} {qual}: expected a {'surface such as S5' if need == 'S' else need + 'n'}",
                               line)
        if not values:
            raise self.err(f"ZOO {item} {qual} gives no values", line)
        if self.count is None:
            self.count = len(values)
        elif len(values) != self.count:
            raise self.err(f"ZOO {item} {qual} gives {len(values)} positions, the first ZOO command {self.count}",
                           line, "every ZOO command gives one value per zoom position")
        self.items.append((item, qual, values, line))

    def declare(self, count: int, line: int) -> None:
        """``ZOO n``: the number of zoom positions."""
        if count < 1 or (self.count is not None and count != self.count):
            raise self.err(f"ZOO {count}: " + ("a zoom needs at least one position" if count < 1 else
                           f"an earlier ZOO command gives {self.count} positions"), line)
        self.count, self.count_line = count, line

    def title(self, args: list[str], line: int) -> bool:
        """``TIT Zk 'name'``: the title of position k (True when ``args`` is one)."""
        m = re.match(r"^Z(\d+)$", args[0], re.IGNORECASE) if args else None
        if m is None:
            return False
        k = int(m.group(1)) - 1
        if self.count is not None and not 0 <= k < self.count:
            raise self.err(f"TIT {args[0]}: position {k + 1} is not one of the {self.count} zoom positions", line)
        name = " ".join(a.strip("'\"") for a in args[1:]).strip()
        self.titles[k] = name
        return True

    def vignetting(self, lens: Lens) -> None:
        """``ZOO VUY F1 ...`` (VLY, VUX, VLX): every position must repeat the sequence's own factor of that field
        (``lens.notes``' ``vignetting_vuy``, 0 where absent); lensrt does not vary vignetting factors by position."""
        for item, args, line in self.vignetting_rows:
            if not args or not (_QUAL.match(args[0]) and args[0][0].upper() == "F"):
                raise self.err(f"ZOO {item} needs a field (F1)", line)
            k = int(args[0][1:]) - 1
            if not 0 <= k < len(lens.fields.y):
                raise self.err(f"ZOO {item} {args[0]}: field {k + 1} is not one of the {len(lens.fields.y)} fields",
                               line)
            base = [float(v) for v in lens.meta.get(f"vignetting_{item.lower()}", "").split()] or \
                [0.0] * len(lens.fields.y)
            vals = [parse_number(v, f"ZOO {item} value", path=self.path, line=line) for v in args[1:]]
            if len(vals) != self.count:
                raise self.err(f"ZOO {item} {args[0]} gives {len(vals)} positions, the zoom {self.count}", line,
                               "every ZOO command gives one value per zoom position")
            if any(abs(v - base[k]) > 1e-9 * max(1.0, abs(base[k])) for v in vals):
                raise self.err(f"ZOO {item} {args[0]}: a vignetting factor that changes with the zoom position "
                               "is not supported", line, f"lensrt reads {item} once for every position; give the "
                               f"field's {item} on the {item} line and drop ZOO {item}")

    def build(self, lens: Lens, unit_mm: float, glass: Callable[[str, int], Material],
              decenter_types: list[str] | None = None) -> Lens | MultiConfigLens:
        """The zoom positions over ``lens`` (the S lines' values are shared where nothing is zoomed);
        ``decenter_types`` (basic, dar, rev, ben per lens surface) guard zoomed decenters."""
        self.vignetting(lens)
        for item, qual, _, line in self.items:
            if item not in ("XDE", "YDE") or not qual[1:].isdigit() or decenter_types is None:
                continue
            k = int(qual[1:]) - 1
            if 0 <= k < len(decenter_types) and decenter_types[k] != "basic":
                raise self.err(f"ZOO {item} {qual}: the surface's decenter is {decenter_types[k].upper()}; lensrt "
                               "zooms basic decenters only", line)
        if self.count is None:
            if self.pos_line is not None and self.current != 0:
                raise self.err(f"POS {self.current + 1}: the sequence has no ZOO data", self.pos_line)
            return lens
        if not 0 <= self.current < self.count:
            raise self.err(f"POS {self.current + 1} is not one of the {self.count} zoom positions", self.pos_line)
        ops = [self.operand(item, qual, values, line, lens, unit_mm, glass) for item, qual, values, line in self.items]
        names = [self.titles.get(k) or f"Z{k + 1}" for k in range(self.count)]
        if len(set(names)) != len(names):  # repeated titles: keep them readable and distinct
            names = [f"Z{k + 1} {n}" if n != f"Z{k + 1}" else n for k, n in enumerate(names)]
        names = tuple(names)
        return MultiConfigLens(lens, names, tuple(ops), self.current).validate()

    def operand(self, item: str, qual: str, values: list[str], line: int, lens: Lens, unit_mm: float,
                glass: Callable[[str, int], Material]) -> ConfigOperand:
        kind, need = ZOOM_ITEMS[item]
        index = -1
        if need == "S":
            if qual == "SI":
                raise self.err(f"ZOO {item} SI: the image surface's data are not zoomed by lensrt", line,
                               "zoom the thickness of the last lens surface instead")
            if qual == "SO":
                if item != "THI":
                    raise self.err(f"ZOO {item} SO: only the object distance (THI) of SO can be zoomed", line)
                kind = "object_distance"
            else:
                index = int(qual[1:]) - 1
                if not 0 <= index < lens.n_surfaces:
                    raise self.err(f"ZOO {item} {qual}: surface {index + 1} is not one of the lens's surfaces "
                                   f"1..{lens.n_surfaces}", line)
        elif need in "FW":
            index = int(qual[1:]) - 1
        vals = tuple(self.value(item, kind, v, line, lens, unit_mm, glass) for v in values)
        return ConfigOperand(kind, index, vals, source=f"ZOO {item} {qual}".strip(), line=line)

    def value(self, item: str, kind: str, tok: str, line: int, lens: Lens, unit_mm: float,
              glass: Callable[[str, int], Material]) -> object:
        if kind == "material":
            return glass(tok, line)
        if kind == "stop_surface":
            m = _SURF.match(tok)
            if not m or not m.group(1).isdigit():
                raise self.err(f"ZOO STO {tok}: expected a surface such as S10", line)
            return int(m.group(1)) - 1
        v = parse_number(tok, f"ZOO {item} value", path=self.path, line=line)
        if kind == "object_distance":
            return math.inf if v >= 1e10 else v * unit_mm
        if kind in ("thickness", "semi_diameter", "decenter_x", "decenter_y"):
            return v * unit_mm
        if kind == "curvature":
            return (0.0 if v == 0.0 else unit_mm / v) if item == "RDY" else v / unit_mm
        if kind == "aperture":
            if {"EPD": "epd", "FNO": "image_fno", "NAO": "object_na"}[item] != lens.aperture.kind:
                raise self.err(f"ZOO {item}: the sequence's aperture is not {item}", line,
                               "zoom the aperture the sequence specifies")
            return v * unit_mm if item == "EPD" else v
        if kind in ("field_y", "field_x"):
            return deg_to_rad(v) if item[1:] == "AN" else v * unit_mm
        if kind == "primary_wavelength":
            return int(v) - 1
        return v
