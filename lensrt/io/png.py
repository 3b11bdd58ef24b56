"""PNG (8 and 16 bit) and 16-bit TIFF output of display images.

8-bit PNG goes through Pillow (installed with matplotlib, which lensrt depends on). Pillow
cannot write 16-bit RGB images, so 16-bit PNG and TIFF are written here with the standard
library only: PNG per ISO/IEC 15948 (IHDR, tEXt, zlib-compressed IDAT with the Sub filter,
IEND) and baseline uncompressed TIFF 6.0 (one strip, little-endian). Images are (rows, cols)
or (rows, cols, 3), origin top-left; uint8 / uint16 arrays are written as they are, float
arrays in [0, 1] are quantised (round(v * (2^bits - 1))).
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import LensrtError
from .paths import output_file

__all__ = ["write_png", "write_tiff", "write_image"]


def _levels(image: np.ndarray, bits: int) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3)):
        raise LensrtError(f"image must be (rows, cols) or (rows, cols, 3); got {img.shape}")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    dt = np.uint8 if bits == 8 else np.uint16
    if img.dtype.kind == "f":
        if not np.all(np.isfinite(img)):
            raise LensrtError("image holds NaN or infinite values")
        top = (1 << bits) - 1
        return (np.clip(img, 0.0, 1.0) * top + 0.5).astype(dt)
    if img.dtype == np.uint8 and bits == 16:
        return img.astype(np.uint16) * 257
    if img.dtype == np.uint16 and bits == 8:
        raise LensrtError("a 16-bit image written as 8-bit PNG would lose its low bits; pass bits=16 or a float image")
    if img.dtype != dt:
        raise LensrtError(f"image dtype {img.dtype} cannot be written with {bits} bits (use uint8/uint16 or float)")
    return img


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_png(path: str | Path, image: np.ndarray, bits: int = 8, text: Mapping[str, str] | None = None,
              compress_level: int = 6) -> Path:
    """Write an 8- or 16-bit PNG (grey or RGB) with optional tEXt metadata."""
    if bits not in (8, 16):
        raise LensrtError(f"PNG bit depth {bits} must be 8 or 16")
    img = _levels(image, bits)
    path = output_file(path, ".png")
    if bits == 8:
        from PIL import Image, PngImagePlugin
        info = PngImagePlugin.PngInfo()
        for k, v in (text or {}).items():
            info.add_text(str(k), str(v))
        Image.fromarray(img).save(path, format="PNG", pnginfo=info, compress_level=compress_level)
        return path
    rows, cols = img.shape[:2]
    channels = 1 if img.ndim == 2 else 3
    bpp = 2 * channels
    raw = np.ascontiguousarray(img.astype(">u2")).view(np.uint8).reshape(rows, cols * bpp)
    # Sub filter (type 1): each byte minus the byte one pixel to the left, modulo 256
    filt = raw.copy()
    filt[:, bpp:] -= raw[:, :-bpp]
    data = np.concatenate([np.ones((rows, 1), np.uint8), filt], axis=1).tobytes()
    ihdr = struct.pack(">IIBBBBB", cols, rows, 16, 0 if channels == 1 else 2, 0, 0, 0)
    parts = [b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", ihdr)]
    for k, v in (text or {}).items():
        parts.append(_chunk(b"tEXt", str(k).encode("latin-1", "replace")[:79] + b"\0" + str(v).encode("latin-1", "replace")))
    parts += [_chunk(b"IDAT", zlib.compress(data, compress_level)), _chunk(b"IEND", b"")]
    path.write_bytes(b"".join(parts))
    return path


def write_tiff(path: str | Path, image: np.ndarray, bits: int = 16, description: str = "") -> Path:
    """Write a baseline uncompressed TIFF (8 or 16 bits per sample, grey or RGB)."""
    if bits not in (8, 16):
        raise LensrtError(f"TIFF bit depth {bits} must be 8 or 16")
    img = _levels(image, bits)
    rows, cols = img.shape[:2]
    spp = 1 if img.ndim == 2 else 3
    pixels = np.ascontiguousarray(img.astype("<u2" if bits == 16 else np.uint8)).tobytes()
    desc = (description or "lensrt").encode("ascii", "replace") + b"\0"
    n_tags = 14
    ifd_offset = 8
    extra = ifd_offset + 2 + n_tags * 12 + 4
    bps_off = extra
    xres_off = bps_off + 2 * spp
    yres_off = xres_off + 8
    desc_off = yres_off + 8
    pix_off = desc_off + len(desc)
    pix_off += pix_off % 2
    SHORT, LONG, RATIONAL, ASCII = 3, 4, 5, 2

    def tag(code: int, typ: int, count: int, value: int) -> bytes:
        if typ == SHORT and count == 1:
            return struct.pack("<HHIHH", code, typ, count, value, 0)
        return struct.pack("<HHII", code, typ, count, value)

    tags = [tag(256, LONG, 1, cols), tag(257, LONG, 1, rows),
            tag(258, SHORT, spp, bps_off) if spp > 1 else tag(258, SHORT, 1, bits),
            tag(259, SHORT, 1, 1), tag(262, SHORT, 1, 2 if spp == 3 else 1),
            tag(270, ASCII, len(desc), desc_off), tag(273, LONG, 1, pix_off), tag(277, SHORT, 1, spp),
            tag(278, LONG, 1, rows), tag(279, LONG, 1, len(pixels)), tag(282, RATIONAL, 1, xres_off),
            tag(283, RATIONAL, 1, yres_off), tag(284, SHORT, 1, 1), tag(296, SHORT, 1, 2)]
    assert len(tags) == n_tags
    head = b"II*\0" + struct.pack("<I", ifd_offset) + struct.pack("<H", n_tags) + b"".join(tags) + struct.pack("<I", 0)
    body = (struct.pack("<" + "H" * spp, *([bits] * spp)) + struct.pack("<II", 72, 1) + struct.pack("<II", 72, 1)
            + desc)
    blob = head + body
    blob += b"\0" * (pix_off - len(blob))
    path = output_file(path)
    with path.open("wb") as fh:
        fh.write(blob)
        fh.write(pixels)
    return path


def write_image(path: str | Path, image: np.ndarray, bits: int | None = None, text: Mapping[str, str] | None = None) -> Path:
    """Write by extension: ``.png`` (8 bit unless ``bits=16`` or a uint16 image), ``.tif``/``.tiff`` (16 bit)."""
    path = Path(path)
    ext = path.suffix.lower()
    img = np.asarray(image)
    if ext == ".png":
        b = bits or (16 if img.dtype == np.uint16 else 8)
        return write_png(path, img, b, text)
    if ext in (".tif", ".tiff"):
        return write_tiff(path, img, bits or 16, description="; ".join(f"{k}={v}" for k, v in (text or {}).items()))
    raise LensrtError(f"cannot write image format {ext!r}", hint="use .png or .tif (or .exr for linear data)")
