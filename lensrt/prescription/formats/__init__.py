"""Lens file formats: one reader (and writer where it makes sense) per format.

:func:`read_lens` picks the reader from the file extension (or ``format=``),
after checks common to every format: the file exists, is not empty, is text.
"""
from __future__ import annotations

import codecs
from importlib import import_module
from pathlib import Path
from typing import Any, Callable

from ...errors import PrescriptionError, located
from ..configurations import MultiConfigLens, single_configuration
from ..model import Lens
from ._common import LensFileWarning, emit_load_warnings

__all__ = ["FORMATS", "read_lens", "read_text", "detect_format", "read_any", "read_configurations",
           "LensFileWarning", "emit_load_warnings"]

#: format name -> (module, reader function, file extensions)
FORMATS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "native": ("native", "read_native", (".toml",)),
    "zemax": ("zemax", "read_zmx", (".zmx",)),
    "codev": ("codev", "read_seq", (".seq",)),
    "pbrt": ("pbrt", "read_pbrt", (".dat",)),
}


def read_text(path: str | Path) -> str:
    """Read a lens file as text: UTF-16/UTF-8 with BOM, UTF-8, or Latin-1.

    Raises :class:`PrescriptionError` for a missing, empty or binary file.
    """
    p = Path(path)
    if not p.exists():
        raise PrescriptionError("file not found", path=p, hint="check the path")
    if p.is_dir():
        raise PrescriptionError("is a directory, not a lens file", path=p)
    data = p.read_bytes()
    if not data.strip():
        raise PrescriptionError("file is empty", path=p)
    for bom, enc in ((codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
                     (codecs.BOM_UTF16_BE, "utf-16")):
        if data.startswith(bom):
            try:
                text = data.decode(enc)
            except UnicodeDecodeError as err:
                raise PrescriptionError(f"cannot decode as {enc}: {err.reason}", path=p) from None
            break
    else:
        if b"\x00" in data[:4096]:
            # UTF-16 without BOM has a NUL in every other byte; anything else is binary
            even, odd = data[0:4096:2], data[1:4096:2]
            if odd.count(0) > 0.8 * len(odd):
                text = data.decode("utf-16-le", errors="strict")
            elif even.count(0) > 0.8 * len(even):
                text = data.decode("utf-16-be", errors="strict")
            else:
                raise PrescriptionError("binary data, not a text lens file", path=p,
                                        hint="give a .toml, .zmx, .seq or .dat lens file")
        else:
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                text = data.decode("latin-1")
    bad = sum(1 for ch in text[:4096] if ord(ch) < 32 and ch not in "\t\r\n\f")
    if bad > 0.01 * min(len(text), 4096) + 2:
        raise PrescriptionError("binary data, not a text lens file", path=p,
                                hint="give a .toml, .zmx, .seq or .dat lens file")
    if not text.strip():
        raise PrescriptionError("file is empty", path=p)
    return text


def detect_format(path: str | Path, text: str | None = None) -> str:
    """Format name for ``path``: from its extension, else from its content."""
    ext = Path(path).suffix.lower()
    for name, (_, _, exts) in FORMATS.items():
        if ext in exts:
            return name
    if text is not None:
        head = text[:2000]
        if "[[surface]]" in head or "format = \"lensrt-lens\"" in head:
            return "native"
        if "SURF " in head or "VERS " in head:
            return "zemax"
        if head.lstrip().upper().startswith(("RDM", "LEN", "TITLE")) or "\nSO " in head:
            return "codev"
    raise PrescriptionError(f"unknown lens file type {ext or '(no extension)'!r}", path=path,
                            hint="use .toml (native), .zmx (Zemax), .seq (CODE V) or .dat (pbrt), "
                                 "or pass --format")


def read_lens(path: str | Path, format: str | None = None, config: int | str | None = None,
              **options: Any) -> Lens:
    """Read a lens file of any supported format into a :class:`Lens`.

    A multi-configuration file (zoom or focus positions) gives configuration
    ``config`` (a name or a 1-based number; default the file's current one);
    :func:`read_configurations` gives them all.

    Parameters
    ----------
    path : str or Path
        The lens file.
    format : str, optional
        One of :data:`FORMATS`; by default from the extension.
    **options
        Reader options named ``<format>_<option>`` (e.g. ``pbrt_thickness="next"``,
        ``pbrt_field_deg=20``); ``None`` values are ignored. An option for
        another format than the file's is an error. The glass options of every
        format: ``glass_substitute``, ``glass_model_fallback`` (bool) and
        ``glass_catalog`` (paths of ``.agf`` files or folders), see
        :mod:`lensrt.prescription.glass_lookup`. ``aperture_rule`` (any format)
        sets :attr:`Lens.aperture_rule`: which semi-diameters vignette.

    Notes
    -----
    Semi-diameters the file does not give are left as ``None`` here; use
    :func:`lensrt.load_lens` for a lens with computed clear apertures.
    """
    found = read_any(path, format, **options)
    if isinstance(found, MultiConfigLens):
        return found.configuration(config)
    if config is not None:
        single_configuration(found).index_of(config)  # only "1" names the one configuration
    return found


def read_configurations(path: str | Path, format: str | None = None, **options: Any) -> MultiConfigLens:
    """Every configuration of a lens file (a plain lens file has one)."""
    found = read_any(path, format, **options)
    return found if isinstance(found, MultiConfigLens) else single_configuration(found)


def read_any(path: str | Path, format: str | None = None, **options: Any) -> Lens | MultiConfigLens:
    """What the format's reader gives: a :class:`Lens`, or a :class:`MultiConfigLens` for a
    multi-configuration file. Options as for :func:`read_lens`."""
    text = read_text(path)
    fmt = format or detect_format(path, text)
    rule = options.pop("aperture_rule", None)
    if fmt not in FORMATS:
        raise PrescriptionError(f"unknown format {fmt!r}", path=path, hint=f"use one of {', '.join(FORMATS)}")
    kwargs = {}
    glass = {k: options.pop(k) for k in ("glass_substitute", "glass_model_fallback", "glass_catalog")
             if k in options}
    for key, value in options.items():
        if value is None:
            continue
        prefix, _, name = key.partition("_")
        if prefix != fmt or not name:
            raise PrescriptionError(f"option {key.replace('_', '-')} does not apply to a {fmt} file", path=path,
                                    hint="options are named after the format they apply to (pbrt-thickness)")
        kwargs[name] = value
    module, func, _ = FORMATS[fmt]
    reader: Callable[..., Lens | MultiConfigLens] = getattr(import_module(f"{__name__}.{module}"), func)
    lens = _read_with_glass_policy(reader, path, text, kwargs, glass)
    if rule is not None:
        with located(path):
            if isinstance(lens, MultiConfigLens):
                return lens.with_base(lens.base.replace(aperture_rule=rule)).validate()
            lens = lens.replace(aperture_rule=rule)
    return lens


def _read_with_glass_policy(reader: Callable[..., Lens], path: str | Path, text: str, kwargs: dict,
                            glass: dict) -> Lens:
    if not any(v for v in glass.values()):
        return reader(path, text=text, **kwargs)
    from ..glass_lookup import glass_policy
    paths = glass.get("glass_catalog") or ()
    with glass_policy(bool(glass.get("glass_substitute")), bool(glass.get("glass_model_fallback")),
                      [paths] if isinstance(paths, (str, Path)) else list(paths)):
        return reader(path, text=text, **kwargs)
