"""Bokeh: defocused point sources through the real lens, one at a time or as a map across the frame
(``lensrt bokeh``).

Files:

- ``entry``    bokeh_spot, bokeh_map, bokeh_near_far: the user's entry points
- ``image``    BokehImage (XYZ on the sensor frame with its variance) and the sensor frame
- ``sources``  point sources: a grid over the frame at chosen depths, or one at a field point
- ``focus``    focusing the lens (unit focusing), blur predictions, stop radius for an f-number
- ``light``    the sources' spectrum and the CIE tables the kernel samples
- ``trace``    stream windows: many sources' rays into windows of one frame
- ``job``      a bokeh map as a parallel Job (chunks of sources, windows pasted in order)
- ``measure``  disc level, area, ring ratio, annulus radii, polygon angles, colour fringes of one spot
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "bokeh_spot": "entry",
    "bokeh_map": "entry",
    "bokeh_near_far": "entry",
    "BokehImage": "image",
    "Focus": "focus",
    "focus_lens": "focus",
    "map_sources": "sources",
    "spot_source": "sources",
})
