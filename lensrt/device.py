"""Warp initialisation, device choice and precision.

Warp is imported lazily (loading a lens never starts it). :func:`resolve_device`
never switches device silently: asking for CUDA where there is none is an error;
``None``/``"auto"`` means "CUDA if Warp sees one, else CPU" and says which.
"""
from __future__ import annotations

import os
from typing import Any

from .errors import LensrtError

__all__ = ["warp", "resolve_device", "cuda_available", "PRECISIONS", "check_precision", "describe_device"]

PRECISIONS = ("float64", "float32")
_WP: Any = None


def warp() -> Any:
    """The ``warp`` module, initialised quietly on first use."""
    global _WP
    if _WP is None:
        import warp as wp
        if os.environ.get("LENSRT_WARP_VERBOSE", "") == "":
            # Warp 1.19: messages below log_level (its init banner, "Module ... load" lines)
            # are suppressed; warnings and errors still show
            wp.config.log_level = wp.LOG_WARNING
        _init_filtering_stderr(wp)
        _WP = wp
    return _WP


_NO_DRIVER = "Could not find or load the NVIDIA CUDA driver"


def _init_filtering_stderr(wp: Any) -> None:
    """``wp.init()`` without the native "no CUDA driver" line on CPU-only machines.

    Warp's C++ core prints it straight to file descriptor 2 when libcuda is
    absent; lensrt says which device it uses itself, so that line is dropped and
    anything else the native code prints is passed through.
    """
    import sys
    import tempfile
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real stderr (embedded interpreters)
        wp.init()
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        for line in tmp.read().decode("utf-8", "replace").splitlines():
            if _NO_DRIVER not in line and line.strip():
                print(line, file=sys.stderr)


def cuda_available() -> bool:
    """True when Warp sees at least one CUDA device."""
    return warp().get_cuda_device_count() > 0


def resolve_device(device: str | None = None) -> str:
    """Warp device name for ``device``.

    ``None``, ``"auto"``: ``"cuda:0"`` when available, else ``"cpu"``;
    ``"cuda"``: ``"cuda:0"`` (an error if there is no CUDA device);
    ``"cpu"`` or ``"cuda:N"``: checked and returned.
    """
    wp = warp()
    if device in (None, "", "auto"):
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    if device == "cpu":
        return "cpu"
    if device == "cuda":
        device = "cuda:0"
    if isinstance(device, str) and device.startswith("cuda"):
        n = wp.get_cuda_device_count()
        try:
            idx = int(device.split(":")[1])
        except (IndexError, ValueError):
            raise LensrtError(f"device {device!r} is not cpu, cuda or cuda:N") from None
        if idx >= n:
            raise LensrtError(f"device {device} requested but Warp sees {n} CUDA device(s)",
                              hint="use --device cpu, or run on a machine with an NVIDIA GPU")
        return device
    raise LensrtError(f"unknown device {device!r}", hint="use cpu, cuda or cuda:N")


def describe_device(device: str) -> str:
    """Human-readable name of a Warp device (GPU model or CPU)."""
    wp = warp()
    d = wp.get_device(device)
    return f"{device} ({d.name})" if device.startswith("cuda") else "cpu"


def check_precision(precision: str) -> str:
    """Validate a precision name ('float64' or 'float32')."""
    if precision not in PRECISIONS:
        raise LensrtError(f"unknown precision {precision!r}", hint="use float64 or float32")
    return precision
