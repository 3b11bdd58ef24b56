"""Reading the scene image and its depth map, with one clear error for every bad input.

Image: PNG (8/16-bit, own decoder for 16-bit colour since Pillow reduces it to
8 bits), JPEG, TIFF (8-bit via Pillow, 16-bit via imageio, a dependency of
colour-demosaicing), EXR (``R``, ``G``, ``B`` or ``Y``, linear), ``.npy``
(linear). sRGB-encoded files are decoded with the IEC 61966-2-1 curve. Depth:
EXR (channel ``Z``, ``depth``, ``Y`` or ``R``), 16-bit PNG times a scale
(``depth_scale_m`` per code value), ``.npy``; metres, finite and positive.
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from ..errors import LensrtError

__all__ = ["read_image_linear", "read_depth_m", "MAX_PIXELS", "decode_png"]

#: the largest image accepted (pixels); larger inputs end in one error (memory, see pipeline.memory_bytes)
MAX_PIXELS = 64_000_000
_SRGB_EXT = {".png", ".jpg", ".jpeg", ".tif", ".tiff"}


def decode_png(path: Path, codes: bool = False) -> np.ndarray:
    """Decode a non-interlaced 8- or 16-bit grey/RGB(A) PNG to (rows, cols, channels) floats in [0, 1]
    (``codes``: the integer code values instead)."""
    data = path.read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise LensrtError("not a PNG file", path=path)
    pos, idat, ihdr = 8, [], None
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        pos += 12 + n
    if ihdr is None:
        raise LensrtError("PNG without a header", path=path)
    w, h, depth, ctype, _, _, interlace = ihdr
    chans = {0: 1, 2: 3, 4: 2, 6: 4}.get(ctype)
    if chans is None or depth not in (8, 16) or interlace:
        raise LensrtError(f"PNG colour type {ctype}, {depth} bits, interlace {interlace} is not supported",
                          path=path, hint="save it as a non-interlaced 8/16-bit grey or RGB PNG")
    bpp = chans * depth // 8
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8).reshape(h, 1 + w * bpp)
    out = np.zeros((h, w * bpp), dtype=np.int32)
    prev = np.zeros(w * bpp, dtype=np.int32)
    for r in range(h):  # undo the PNG row filters (ISO 15948 clause 9.2)
        f, line = int(raw[r, 0]), raw[r, 1:].astype(np.int32)
        if f == 0:
            cur = line
        elif f == 1:  # Sub: a running sum per byte lane
            cur = np.cumsum(line.reshape(w, bpp), axis=0).reshape(-1) & 255
        elif f == 2:
            cur = (line + prev) & 255
        else:  # Average, Paeth: sequential over pixels, vectorised over the bytes of a pixel
            cur = np.zeros_like(line)
            a = np.zeros(bpp, dtype=np.int32)
            c = np.zeros(bpp, dtype=np.int32)
            for i in range(w):
                sl = slice(i * bpp, (i + 1) * bpp)
                b = prev[sl]
                if f == 3:
                    pred = (a + b) >> 1
                else:
                    p = a + b - c
                    pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
                    pred = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
                cur[sl] = (line[sl] + pred) & 255
                a, c = cur[sl], b
        out[r], prev = cur, cur
    px = out.astype(np.uint8).reshape(h, w * bpp)
    if depth == 16:
        vals = px.reshape(h, w * chans, 2).astype(np.uint32)
        code = ((vals[..., 0] << 8) | vals[..., 1]).reshape(h, w, chans)
    else:
        code = px.reshape(h, w, chans).astype(np.uint32)
    return code.astype(np.float64) if codes else code / (65535.0 if depth == 16 else 255.0)


def _png_is_16bit_colour(path: Path) -> bool:
    """A 16-bit colour PNG (which Pillow would reduce to 8 bits)?"""
    with open(path, "rb") as fh:
        head = fh.read(29)
    return len(head) == 29 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[24] == 16 and head[25] in (2, 6)


def _read_pillow(path: Path) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                return np.asarray(im, dtype=np.float64)[..., None] / 65535.0
            if im.mode == "F":
                return np.asarray(im, dtype=np.float64)[..., None]
            return np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except (UnidentifiedImageError, OSError, ValueError) as err:
        raise LensrtError(f"cannot read the image: {err}", path=path,
                          hint="use a PNG, JPEG, TIFF, EXR or .npy file") from None


def _imread(path: Path) -> np.ndarray:
    """imageio's reader, quiet about its vendored-tifffile deprecation."""
    import warnings

    import imageio.v3 as iio
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return np.asarray(iio.imread(path))


def _read_tiff(path: Path) -> np.ndarray:
    try:
        a = _imread(path)
    except Exception:  # noqa: BLE001 - any reader failure: fall back to Pillow's message
        return _read_pillow(path)
    scale = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}.get(a.dtype, 1.0)
    return (a.astype(np.float64) / scale).reshape(a.shape[0], a.shape[1], -1)


def _read_exr_channels(path: Path, names: tuple[str, ...]) -> np.ndarray:
    from ..io.exr import read_exr
    chans, _ = read_exr(path)
    for group in names:
        keys = group.split(",")
        if all(k in chans for k in keys):
            return np.stack([np.asarray(chans[k], dtype=np.float64) for k in keys], axis=-1)
    raise LensrtError(f"the EXR has channels {', '.join(sorted(chans)) or 'none'}; none of {' / '.join(names)}",
                      path=path)


def _raw_pixels(path: Path) -> tuple[np.ndarray, bool]:
    """(pixels (rows, cols, channels), sRGB-encoded?) of an image file."""
    ext = path.suffix.lower()
    if ext == ".exr":
        return _read_exr_channels(path, ("R,G,B", "Y")), False
    if ext == ".npy":
        try:
            a = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as err:
            raise LensrtError(f"cannot read the array: {err}", path=path) from None
        return np.asarray(a, dtype=np.float64).reshape(a.shape[0], a.shape[1], -1) if a.ndim in (2, 3) else a, False
    if ext == ".png" and _png_is_16bit_colour(path):
        try:
            return decode_png(path), True
        except (zlib.error, struct.error, ValueError) as err:
            raise LensrtError(f"cannot read the PNG: {err}", path=path) from None
    if ext in (".tif", ".tiff"):
        return _read_tiff(path), True
    return _read_pillow(path), True


def read_image_linear(path: str | Path, encoding: str = "auto") -> np.ndarray:
    """A scene image as linear sRGB float32 (rows, cols, 3), row 0 at the top.

    ``encoding``: ``auto`` (sRGB for PNG/JPEG/TIFF, linear for EXR and .npy), ``srgb`` or ``linear``.
    Negative values are an error; linear values above 1 (HDR) are kept.
    """
    from ..colour import srgb_decode
    path = Path(path)
    if not path.is_file():
        raise LensrtError("the image file does not exist", path=path)
    arr, srgb = _raw_pixels(path)
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4) or min(arr.shape[:2]) < 2:
        raise LensrtError(f"an image of shape {arr.shape} is not a picture", path=path,
                          hint="give (rows, cols) grey or (rows, cols, 3) RGB, at least 2 x 2 pixels")
    if arr.shape[0] * arr.shape[1] > MAX_PIXELS:
        raise LensrtError(f"the image has {arr.shape[1]} x {arr.shape[0]} pixels, more than {MAX_PIXELS:.0e}",
                          path=path, hint="resample it to a smaller size")
    arr = arr[..., :3] if arr.shape[2] >= 3 else np.repeat(arr[..., :1], 3, axis=2)
    if not np.all(np.isfinite(arr)) or arr.min() < 0:
        raise LensrtError("the image holds negative, NaN or infinite values", path=path)
    if encoding not in ("auto", "srgb", "linear"):
        raise LensrtError(f"image encoding {encoding!r} is not auto, srgb or linear")
    if encoding == "srgb" or (encoding == "auto" and srgb):
        arr = srgb_decode(np.clip(arr, 0.0, 1.0))
    return np.ascontiguousarray(arr, dtype=np.float32)


def _depth_codes(path: Path) -> np.ndarray:
    """Integer code values (rows, cols, channels) of a PNG or TIFF depth map."""
    try:
        if path.suffix.lower() == ".png":
            return decode_png(path, codes=True)
        a = _imread(path)
    except LensrtError:
        raise
    except Exception as err:  # noqa: BLE001 - any decoder failure is a bad file
        raise LensrtError(f"cannot read the depth map: {err}", path=path) from None
    if a.dtype.kind not in "ui":
        raise LensrtError(f"a PNG/TIFF depth map must hold integer codes, not {a.dtype}", path=path,
                          hint="use EXR or .npy for depths in metres")
    return a.astype(np.float64).reshape(a.shape[0], a.shape[1], -1)


def read_depth_m(path: str | Path, shape: tuple[int, int], depth_scale_m: float | None = None) -> np.ndarray:
    """A depth map (metres, float64, ``shape`` = the image's (rows, cols)), checked.

    16-bit (or 8-bit) PNG/TIFF code values are multiplied by ``depth_scale_m`` (required for them).
    """
    path = Path(path)
    if not path.is_file():
        raise LensrtError("the depth file does not exist", path=path)
    ext = path.suffix.lower()
    if ext == ".exr":
        d = _read_exr_channels(path, ("Z", "depth", "Y", "R"))[..., 0]
    elif ext == ".npy":
        d, _ = _raw_pixels(path)
        d = d[..., 0] if d.ndim == 3 else d
    elif ext in (".png", ".tif", ".tiff"):
        if depth_scale_m is None or not depth_scale_m > 0:
            raise LensrtError("a PNG/TIFF depth map needs --depth-scale-m (metres per code value)", path=path)
        d = _depth_codes(path)[..., 0] * float(depth_scale_m)
    else:
        raise LensrtError(f"depth maps are EXR, 16-bit PNG/TIFF or .npy, not {ext or 'no extension'}", path=path)
    d = np.asarray(d, dtype=np.float64)
    if d.shape != tuple(shape):
        raise LensrtError(f"the depth map is {d.shape[1] if d.ndim > 1 else d.size} x {d.shape[0]} pixels, the image "
                          f"{shape[1]} x {shape[0]}", path=path, hint="give a depth map of the image's size")
    if not np.all(np.isfinite(d)):
        raise LensrtError(f"the depth map holds {int((~np.isfinite(d)).sum())} NaN or infinite values", path=path,
                          hint="give every pixel a finite distance in metres (a far value for the sky)")
    if d.min() <= 0:
        raise LensrtError(f"the depth map holds distances <= 0 m (smallest {d.min():g})", path=path,
                          hint="depths are positive distances in front of the lens, in metres")
    return d
