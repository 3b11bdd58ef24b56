"""Which trace kernel a call runs: the generic one or the lens-specialised one (a small planner).

``kernel="generic"``
    one compiled module per precision for every lens (:mod:`.kernels`); nothing to
    compile for a new lens; the only choice for ``record=True`` or ``end < n_surfaces``.
``kernel="specialised"``
    generated per lens shape and options (:mod:`.specialised`): unrolled, only the code
    the lens needs; compiles once per shape (about a second or two per module on a GPU,
    several on a CPU; cached on disk by Warp).
``kernel="auto"`` (default)
    specialised on CUDA devices for enough rays to repay a compile
    (:data:`GPU_MIN_RAYS`; measured on an H100: 4.5x the generic kernel's rays/s in float32,
    3.9x in float64); generic on the CPU (there the branch-free specialised code is no
    faster -- a CPU core does not run 32 rays in lock step -- and costs a compile), and for
    shapes the generator leaves alone (:func:`lensrt.trace.shape.specialisable`).

The two variants trace the same rays (same samples) and agree to rounding; for a
given call the choice depends only on the arguments and the device, so results stay
reproducible. Each result says which kernel ran (``StreamResult.extra["kernel"]``,
``RayResult.kernel``).
"""
from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

from ..core.telemetry import upload
from ..errors import LensrtError
from .shape import LensShape, constants, lens_shape, specialisable

__all__ = ["KERNELS", "GPU_MIN_RAYS", "CPU_MIN_RAYS", "choose_kernel", "shape_and_constants", "params"]

KERNELS = ("auto", "generic", "specialised")
#: fewest rays for which "auto" specialises on a GPU
GPU_MIN_RAYS = 1 << 22
#: fewest rays for which "auto" specialises on the CPU (None: never)
CPU_MIN_RAYS: int | None = None

_CACHE: "OrderedDict[tuple, tuple[LensShape, np.ndarray]]" = OrderedDict()


def shape_and_constants(packed: Any, clip: bool = True) -> tuple[LensShape, np.ndarray]:
    """Shape and float64 constants of a :class:`~lensrt.trace.pack.PackedLens` (cached)."""
    key = (packed.lens, packed.host_iris.tobytes(), bool(clip))
    hit = _CACHE.get(key)
    if hit is None:
        shape = lens_shape(packed.host_surf, packed.host_media, packed.host_iris, clip)
        hit = (shape, constants(shape, packed.host_surf, packed.host_media, packed.host_iris))
        _CACHE[key] = hit
        if len(_CACHE) > 64:
            _CACHE.popitem(last=False)
    return hit


def choose_kernel(kernel: str, device: str, shape: LensShape, rays: int, *, possible: bool = True) -> str:
    """'generic' or 'specialised' for ``kernel`` in :data:`KERNELS` (module docstring).

    ``possible=False`` says the call needs a generic-only feature (records, an early end).
    """
    if kernel not in KERNELS:
        raise LensrtError(f"unknown kernel {kernel!r}", hint=f"use one of {', '.join(KERNELS)}")
    if kernel == "generic":
        return "generic"
    ok = possible and specialisable(shape)
    if kernel == "specialised":
        if not ok:
            why = "records and early ends need the generic kernel" if not possible else \
                ("the lens has mirrors, tilts/decenters, an ideal paraxial lens, surface kinds beyond the even "
                 "asphere, or too many constants or iris blades for the generator")
            raise LensrtError(f"no specialised kernel for this call: {why}", hint='use kernel="generic" or "auto"')
        return "specialised"
    if not ok:
        return "generic"
    if device.startswith("cuda"):
        return "specialised" if rays >= GPU_MIN_RAYS else "generic"
    return "specialised" if CPU_MIN_RAYS is not None and rays >= CPU_MIN_RAYS else "generic"


def params(kernels: Any, values: np.ndarray, device: str) -> Any:
    """The constants argument of a specialised kernel (a vector parameter or a device array)."""
    from ..device import warp
    wp = warp()
    if kernels.consts_mode == "param":
        return kernels.Consts(*(float(v) for v in values))
    return upload(np.asarray(values, dtype=np.float64), kernels.real, device)
