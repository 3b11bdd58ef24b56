"""What a render will cost and whether its camera can be set up: the checks ``render`` and ``render --plan`` share.

:func:`check_render` loads nothing itself: it takes the loaded scene and lens, applies ``--width``,
sets the camera up as the render would (f-number, focus distance, sensor preset) and estimates the
memory (:func:`lensrt.core.budget.estimate_render_bytes`), refusing above the limit. ``render --plan``
calls it too, so the plan says no to exactly what the render refuses.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..core.budget import MAX_SIDE_PX, MemoryEstimate, check_memory, estimate_render_bytes
from ..errors import LensrtError

__all__ = ["RenderCheck", "check_render"]


@dataclass(frozen=True)
class RenderCheck:
    """The scene as it will be rendered, its camera and its memory estimate."""

    scene: Any
    camera: Any
    memory: MemoryEstimate


def _check_preset(scene) -> None:
    preset = getattr(scene.sensor, "preset", None)
    if preset is None:
        return
    from ..sensor import get_preset
    get_preset(preset)  # a LensrtError naming the presets


def check_render(scene, lens, *, width: int | None = None, band_width_nm: float = 10.0, focus: str = "best",
                 limit_bytes: int | None = None) -> RenderCheck:
    """Everything a render checks before it allocates; raises :class:`LensrtError` on the first problem.

    Parameters
    ----------
    scene, lens
        The loaded scene and lens.
    width : int, optional
        ``--width`` (pixels); rows keep the aspect ratio.
    band_width_nm : float
        Output band width (nm), for the band count of the estimate.
    focus : str
        ``best`` or ``paraxial``.
    limit_bytes : int, optional
        ``--max-memory`` in bytes (default: :func:`lensrt.core.budget.default_limit_bytes`).
    """
    from .camera import setup_camera
    from .setup import bands as output_bands, scale_pixels
    from .plan import plan_render
    if width is not None:
        if not 1 <= width <= MAX_SIDE_PX:
            raise LensrtError(f"--width {width} must be 1..{MAX_SIDE_PX} pixels")
        scene = scale_pixels(scene, width)
    rows, cols = int(scene.sensor.pixels_y), int(scene.sensor.pixels_x)
    plan = plan_render(scene, lens)
    n_bands = output_bands(plan, band_width_nm)[2]
    memory = estimate_render_bytes(rows, cols, n_bands, f"a render of {scene.name!r}")
    check_memory(memory, limit_bytes)
    _check_preset(scene)
    camera = setup_camera(scene, lens, focus)
    return RenderCheck(scene, camera, memory)
