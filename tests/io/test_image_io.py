"""Image I/O: EXR (float/half/uint, layers, metadata, spectral, raw), 8/16-bit PNG, 16-bit TIFF."""
from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from lensrt.errors import LensrtError
from lensrt.io.exr import read_exr, read_spectral_exr, write_exr, write_image_exr, write_spectral_exr
from lensrt.io.png import write_image, write_png, write_tiff
from lensrt.io.raw import read_raw_exr, write_raw_exr
from lensrt.sensor import average_frames, electrons_to_raw, get_preset, sensor_from_spec


def test_exr_pixel_types_layers_and_metadata(tmp_path):
    rng = np.random.default_rng(0)
    chans = {"R": rng.random((5, 7), dtype=np.float32), "layer.G": rng.random((5, 7)).astype(np.float16),
             "ids": rng.integers(0, 2 ** 32 - 1, (5, 7), dtype=np.uint32), "f64": rng.random((5, 7))}
    meta = {"lensrt:note": "hello", "lensrt:exposure_s": 1 / 3, "lensrt:n": 7, "lensrt:list": [1.5, 2.0]}
    path = write_exr(tmp_path / "a.exr", chans, meta)
    back, m = read_exr(path)
    assert back["R"].dtype == np.float32 and np.array_equal(back["R"], chans["R"])
    assert back["layer.G"].dtype == np.float16 and np.array_equal(back["layer.G"], chans["layer.G"])
    assert back["ids"].dtype == np.uint32 and np.array_equal(back["ids"], chans["ids"])
    assert np.array_equal(back["f64"], chans["f64"].astype(np.float32))
    assert m["lensrt:note"] == "hello" and float(m["lensrt:exposure_s"]) == 1 / 3 and int(m["lensrt:n"]) == 7
    assert json.loads(m["lensrt:list"]) == [1.5, 2.0]


def test_exr_errors(tmp_path):
    with pytest.raises(LensrtError):
        write_exr(tmp_path / "b.exr", {"a": np.zeros((2, 2), np.float32), "b": np.zeros((3, 2), np.float32)})
    with pytest.raises(LensrtError):
        write_exr(tmp_path / "b.exr", {"a": np.zeros((2, 2), np.int32)})
    with pytest.raises(LensrtError):
        read_exr(tmp_path / "missing.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an exr")
    with pytest.raises(LensrtError):
        read_exr(tmp_path / "junk.exr")


def test_image_and_spectral_exr_round_trip(tmp_path):
    img = np.random.default_rng(1).random((4, 6, 3)).astype(np.float32)
    chans, _ = read_exr(write_image_exr(tmp_path / "rgb.exr", img, layer="linear"))
    assert np.array_equal(np.stack([chans[f"linear.{c}"] for c in "RGB"], -1), img)
    wl = np.array([400.0, 550.0, 700.5])
    E = np.random.default_rng(2).random((3, 5, 3)).astype(np.float32) * 1e-3
    write_spectral_exr(tmp_path / "E.exr", E, wl, metadata={"lensrt:bin_width_nm": 10.0})
    E2, wl2, meta = read_spectral_exr(tmp_path / "E.exr")
    assert np.array_equal(E2, E) and np.array_equal(wl2, wl) and meta["lensrt:units"] == "W/(m^2 nm)"


def test_raw_exr_round_trip(tmp_path):
    sensor = sensor_from_spec({"preset": "apsc_16mp", "cfa": "XTRANS"})
    raw = electrons_to_raw(sensor, np.full((12, 18), 3000.0, np.float32), 0.02, rng=np.random.default_rng(0), iso=400)
    back = read_raw_exr(write_raw_exr(tmp_path / "raw.exr", raw))
    assert back.dn.dtype == np.uint16 and np.array_equal(back.dn, raw.dn)
    assert back.cfa == raw.cfa and back.iso == 400 and back.exposure_s == 0.02
    assert back.black_level_dn == raw.black_level_dn and back.white_level_dn == raw.white_level_dn
    assert back.g_e_per_dn == raw.g_e_per_dn and back.meta["sensor"] == "apsc_16mp"
    chans, _ = read_exr(tmp_path / "raw.exr")
    assert chans["raw"].dtype == np.uint32  # stored as an EXR UINT channel
    avg = average_frames([raw, raw])
    back = read_raw_exr(write_raw_exr(tmp_path / "avg.exr", avg))
    assert back.dn.dtype == np.float32 and back.n_frames == 2


def _decode_png16(path):
    """Independent minimal PNG decoder (filter types 0 and 1, 16-bit) for the test."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, text = 8, b"", {}
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        assert struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0] == zlib.crc32(kind + body)
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
        elif kind == b"IDAT":
            idat += body
        elif kind == b"tEXt":
            k, v = body.split(b"\0", 1)
            text[k.decode()] = v.decode()
        pos += 12 + n
    ch = 3 if ctype == 2 else 1
    bpp = 2 * ch
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * bpp)
    out = np.empty((h, w * bpp), np.uint8)
    for r in range(h):
        line = rows[r, 1:].astype(np.int64)
        if rows[r, 0] == 1:
            for i in range(bpp, line.size):
                line[i] = (line[i] + line[i - bpp]) % 256
        out[r] = line
    img = out.view(">u2").reshape(h, w, ch).astype(np.uint16)
    return (img if ch == 3 else img[..., 0]), depth, text


def test_png16_exact(tmp_path):
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 65536, (9, 11, 3), dtype=np.uint16)
    write_png(tmp_path / "a.png", rgb, 16, {"Software": "lensrt"})
    img, depth, text = _decode_png16(tmp_path / "a.png")
    assert depth == 16 and np.array_equal(img, rgb) and text["Software"] == "lensrt"
    # Pillow agrees: the high bytes of RGB, every bit of greyscale
    assert np.array_equal(np.array(Image.open(tmp_path / "a.png")), (rgb >> 8).astype(np.uint8))
    write_png(tmp_path / "g.png", rgb[..., 1], 16)
    assert np.array_equal(np.array(Image.open(tmp_path / "g.png")).astype(np.uint16), rgb[..., 1])


def test_png8_and_float_quantisation(tmp_path):
    f = np.linspace(0, 1, 12).reshape(3, 4)
    write_image(tmp_path / "f.png", np.stack([f, f, f], -1))
    back = np.array(Image.open(tmp_path / "f.png"))
    assert back.dtype == np.uint8 and np.array_equal(back[..., 0], np.round(f * 255).astype(np.uint8))
    with pytest.raises(LensrtError):
        write_png(tmp_path / "x.png", np.zeros((2, 2), np.uint16), 8)
    with pytest.raises(LensrtError):
        write_image(tmp_path / "x.jpg", f)


def _read_tiff(path):
    """Independent reader for the baseline uncompressed TIFF written by lensrt."""
    data = path.read_bytes()
    assert data[:4] == b"II*\0"
    (ifd,) = struct.unpack("<I", data[4:8])
    (n,) = struct.unpack("<H", data[ifd:ifd + 2])
    tags = {}
    for i in range(n):
        code, typ, count, value = struct.unpack("<HHII", data[ifd + 2 + 12 * i: ifd + 14 + 12 * i])
        tags[code] = value & 0xFFFF if (typ == 3 and count == 1) else value
    w, h, spp, off, nbytes = tags[256], tags[257], tags[277], tags[273], tags[279]
    assert tags[259] == 1 and nbytes == w * h * spp * 2
    return np.frombuffer(data[off:off + nbytes], "<u2").reshape(h, w, spp), tags


def test_tiff16_exact(tmp_path):
    rgb = np.random.default_rng(4).integers(0, 65536, (7, 5, 3), dtype=np.uint16)
    write_tiff(tmp_path / "a.tif", rgb)
    img, tags = _read_tiff(tmp_path / "a.tif")
    assert np.array_equal(img, rgb) and tags[262] == 2
    assert np.array_equal(np.array(Image.open(tmp_path / "a.tif")), (rgb >> 8).astype(np.uint8))
    write_tiff(tmp_path / "g.tif", rgb[..., 2])
    assert np.array_equal(np.array(Image.open(tmp_path / "g.tif")).astype(np.uint16), rgb[..., 2])


def test_preset_is_not_mutated_by_io():
    assert get_preset("apsc_16mp").cfa.name == "RGGB"


@pytest.mark.parametrize("cfa", ["GRBG", "XTRANS"])
def test_dng_round_trips_through_rawpy(tmp_path, cfa):
    pytest.importorskip("pidng")
    rawpy = pytest.importorskip("rawpy")
    from lensrt.io.dng import write_dng
    sensor = sensor_from_spec({"cfa": cfa})
    raw = electrons_to_raw(sensor, np.random.default_rng(0).uniform(100, 60000, (36, 48)).astype(np.float32), 0.01,
                           rng=np.random.default_rng(1))
    path = write_dng(tmp_path / "x.dng", raw)
    with rawpy.imread(str(path)) as d:
        assert np.array_equal(d.raw_image_visible, raw.dn)
        assert np.array_equal(np.asarray(d.raw_pattern) % 3 if cfa == "XTRANS" else d.raw_pattern,
                              raw.cfa.tile_array() if cfa == "XTRANS" else [[1, 0], [2, 3]])
        assert d.black_level_per_channel[0] == raw.black_level_dn and d.white_level == raw.white_level_dn
