"""Colour filter arrays: Bayer (four phases), Fuji X-Trans 6x6, and custom patterns.

A CFA is a small periodic tile of channel indices (0 = R, 1 = G, 2 = B) laid over the
photosites from the top-left pixel (row 0, col 0) of the image (Field Guide p. 38).
Patterns are written row by row, rows separated by ``/``: ``"RG/GB"`` is Bayer RGGB.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import LensrtError

__all__ = ["CFA", "CHANNELS", "BAYER_PHASES", "XTRANS_PATTERN", "parse_cfa"]

#: channel names in index order
CHANNELS = ("R", "G", "B")

#: the four phases of the Bayer mosaic, named by the 2x2 tile read row by row
BAYER_PHASES = ("RGGB", "BGGR", "GRBG", "GBRG")

#: Fuji X-Trans 6x6 tile (as in dcraw's ``xtrans_abs``): 20 G, 8 R, 8 B per 36 photosites,
#: every row and column holds all three colours (Field Guide p. 38)
XTRANS_PATTERN = "GGRGGB/GGBGGR/BRGRBG/GGBGGR/GGRGGB/RBGBRG"


@dataclass(frozen=True)
class CFA:
    """A periodic colour filter array.

    Attributes
    ----------
    name : str
        ``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``, ``"XTRANS"`` or the custom pattern text.
    tile : tuple of tuple of int
        Channel index (0 R, 1 G, 2 B) of each photosite of one period, (row, col) from the
        top-left of the image.
    """

    name: str
    tile: tuple[tuple[int, ...], ...]

    @property
    def shape(self) -> tuple[int, int]:
        """Period of the pattern (rows, cols)."""
        return len(self.tile), len(self.tile[0])

    @property
    def is_bayer(self) -> bool:
        """True for the four 2x2 Bayer phases (these use colour-demosaicing)."""
        return self.name in BAYER_PHASES

    @property
    def pattern(self) -> str:
        """The tile as text, rows separated by ``/`` (round-trips through :func:`parse_cfa`)."""
        return "/".join("".join(CHANNELS[c] for c in row) for row in self.tile)

    def tile_array(self) -> np.ndarray:
        return np.asarray(self.tile, dtype=np.int8)

    def channel_map(self, rows: int, cols: int) -> np.ndarray:
        """Channel index of every photosite of a ``rows`` x ``cols`` frame (int8 array)."""
        return _channel_map(self.tile, rows, cols)

    def masks(self, rows: int, cols: int) -> np.ndarray:
        """Boolean masks, shape (rows, cols, 3): True where the photosite has that channel."""
        cmap = self.channel_map(rows, cols)
        return np.stack([cmap == c for c in range(3)], axis=-1)

    def fractions(self) -> np.ndarray:
        """Fraction of photosites of each channel (R, G, B)."""
        t = self.tile_array()
        return np.array([(t == c).mean() for c in range(3)])


@lru_cache(maxsize=16)
def _channel_map(tile: tuple[tuple[int, ...], ...], rows: int, cols: int) -> np.ndarray:
    t = np.asarray(tile, dtype=np.int8)
    reps = (-(-rows // t.shape[0]), -(-cols // t.shape[1]))
    out = np.tile(t, reps)[:rows, :cols]
    out.setflags(write=False)
    return out


def parse_cfa(text: str) -> CFA:
    """A CFA from its name or pattern.

    Parameters
    ----------
    text : str
        ``RGGB``, ``BGGR``, ``GRBG``, ``GBRG`` (Bayer phases), ``XTRANS`` (``X-Trans``), or a custom
        pattern of R/G/B letters with rows separated by ``/`` (e.g. ``"RGB/GBR/BRG"``).
    """
    key = text.strip().upper().replace("-", "").replace("_", "")
    if key in BAYER_PHASES:
        return CFA(key, (tuple(CHANNELS.index(c) for c in key[:2]), tuple(CHANNELS.index(c) for c in key[2:])))
    if key == "XTRANS":
        return CFA("XTRANS", parse_cfa(XTRANS_PATTERN).tile)
    rows = [r.strip() for r in key.split("/")]
    if not rows or any(not r for r in rows) or len({len(r) for r in rows}) != 1:
        raise LensrtError(f"CFA pattern {text!r} is not a rectangle of R/G/B letters",
                          hint="use RGGB, BGGR, GRBG, GBRG, XTRANS or rows like 'RG/GB'")
    bad = {c for r in rows for c in r} - set(CHANNELS)
    if bad:
        raise LensrtError(f"CFA pattern {text!r} has letters {sorted(bad)} other than R, G, B",
                          hint="use RGGB, BGGR, GRBG, GBRG, XTRANS or rows like 'RG/GB'")
    tile = tuple(tuple(CHANNELS.index(c) for c in r) for r in rows)
    present = {c for r in tile for c in r}
    if present != {0, 1, 2}:
        raise LensrtError(f"CFA pattern {text!r} lacks a channel (needs R, G and B)")
    if len(rows) == 2 and len(rows[0]) == 2 and "".join(rows) in BAYER_PHASES:
        return CFA("".join(rows), tile)
    return CFA("/".join(rows), tile)
