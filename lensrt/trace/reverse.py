"""The lens seen from the image side: backward tracing with the same forward kernels.

A renderer traces from the sensor back through the lens into the scene. Rather
than a second set of kernels, :func:`reversed_lens` mirrors the prescription
(z -> z_last - z, x and y unchanged): surface order reversed, curvatures and
aspheric coefficients negated (the sag changes sign), each surface followed by
the medium that was in front of it, thicknesses shifted. The reversed lens's
first vertex is the old last vertex; its "object" is the old image plane, at
the old last thickness in front of it; its image surface lies ``scene_gap_mm``
behind its last vertex (the old first vertex). :func:`to_reversed` and
:func:`from_reversed` map points and directions between the two frames.

Tracing a ray forward and then its reverse through :func:`reversed_lens`
returns it to its origin (tested to 1e-10 mm in float64).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Aperture, Fields, Lens

__all__ = ["reversed_lens", "to_reversed", "from_reversed"]


def reversed_lens(lens: Lens, scene_gap_mm: float = 0.0) -> Lens:
    """``lens`` mirrored for tracing from the image side (module docstring).

    The aperture becomes ``float_by_stop`` (the stop keeps its semi-diameter; it must
    have one) and the field the object height 0: sample the reversed lens with explicit
    rays or stream sources, not with its field specification.
    """
    if lens.has_mirrors or not lens.is_centred:
        raise LensrtError("tracing from the image side (render) does not support mirrors, tilts/decenters "
                          "or surface apertures yet", path=lens.path,
                          hint="trace such lenses forward (trace, psf, bokeh spots and maps) or with the float64 "
                               "reference tracer")
    if lens.image_curvature_per_mm != 0.0:
        raise LensrtError("tracing from the image side (render) does not support a curved image surface yet",
                          path=lens.path, hint="trace such lenses forward (trace, ray, psf, bokeh) or with the float64 "
                                               "reference tracer")
    n = lens.n_surfaces
    media = lens.media()
    old = lens.surfaces
    surfaces = []
    for j in range(n):
        s = old[n - 1 - j]
        gap = old[n - 2 - j].thickness_mm if j < n - 1 else float(scene_gap_mm)
        surfaces.append(replace(s, curvature_per_mm=-s.curvature_per_mm,
                                asphere=tuple(-a for a in s.asphere), thickness_mm=gap,
                                shape=None if s.shape is None else s.shape.mirrored_in_z(),
                                material=media[n - 1 - j], line=None))
    obj = old[-1].thickness_mm
    return Lens(tuple(surfaces), aperture=Aperture("float_by_stop", 0.0),
                fields=Fields("object_height", (0.0,)), wavelengths=lens.wavelengths,
                object_distance_mm=obj if obj > 0 else 1e-9, object_material=media[n], iris=lens.iris,
                name=f"{lens.name} (reversed)", source=lens.source, notes=lens.notes)


def to_reversed(lens: Lens, points_mm: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and directions (n, 3) of ``lens``'s frame in the frame of :func:`reversed_lens`."""
    z_last = float(lens.vertex_z_mm()[lens.n_surfaces - 1])
    p = np.array(points_mm, dtype=np.float64, copy=True)
    d = np.array(directions, dtype=np.float64, copy=True)
    p[..., 2] = z_last - p[..., 2]
    d[..., 2] = -d[..., 2]
    return p, d


def from_reversed(lens: Lens, points_mm: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of :func:`to_reversed` (the mirror is its own inverse)."""
    return to_reversed(lens, points_mm, directions)
