"""Physical checks on a complete lens: surfaces that cross, impossible image positions.

These run once clear semi-diameters are known (given, or computed by the
loader), so they live apart from the per-field checks in :mod:`.model`.
"""
from __future__ import annotations

import numpy as np

from ..errors import PrescriptionError
from .model import Lens, LoadWarning

__all__ = ["check_geometry"]

#: sags may touch (cemented surfaces, a stop on a vertex) within this tolerance
CROSSING_TOL_MM = 1e-6


def check_geometry(lens: Lens, samples: int = 65, beam_heights_mm: np.ndarray | None = None,
                   image_distance_mm: float | None = None) -> list[LoadWarning]:
    """Raise :class:`PrescriptionError` if adjacent surfaces cross inside their clear apertures.

    For surfaces i and i+1 with semi-diameters given by the file, the later surface must
    never lie in front of the earlier one over the common aperture:
    ``z_i(r) <= t_i + z_{i+1}(r)`` for ``0 <= r <= min(sd_i, sd_{i+1})``. A
    negative thickness is thus allowed only where the sags make room for it.
    With ``beam_heights_mm`` (the axial beam's height at each surface, mm: the
    paraxial marginal ray, :func:`lensrt.paraxial.crossing.axial_beam_heights`)
    a crossing that begins beyond the axial beam on both surfaces is not an
    error but a returned ``edge_thickness`` :class:`LoadWarning`: the element's
    edge is negative at the file's semi-diameters (OpticStudio's automatic
    ones often reach there; CODE V, OpticStudio and rayoptics trace such files)
    while the on-axis light passes where it is positive. A crossing inside
    the axial beam stays an error.
    A dummy surface (the same medium on both sides, not a mirror or an ideal
    lens) is a reference plane, not matter: where it crosses a neighbour the
    result is a ``dummy_crossing`` warning (rays reach it by a backward
    segment, as OpticStudio traces them), and the real surfaces on either side
    of a run of dummies are compared with each other over the summed thickness.
    The image surface must lie behind the last vertex, unless the paraxial
    image is virtual: ``image_distance_mm`` (last vertex to the paraxial image;
    the loader passes :attr:`lensrt.paraxial.first_order.FirstOrder.image_distance_mm`)
    lies against the direction of travel. A
    diverging lens's file may then put the image surface at the virtual focus,
    where the rays leaving the lens meet when extended backwards (a negative
    last transfer, as in OpticStudio and CODE V). After an odd number of
    mirrors light travels toward -z and "behind" means toward -z too; surfaces
    with a coordinate transform between them are not compared (their sags do
    not share an axis).

    Parameters
    ----------
    lens : Lens
    samples : int
        Heights sampled per pair of surfaces.
    beam_heights_mm : ndarray, optional
        The axial beam's height at each surface (mm).
    image_distance_mm : float, optional
        Last vertex to the paraxial image (mm, a z offset like the last
        thickness, so negative after an odd number of mirrors); None when unknown (a negative last
        thickness is then refused).
    """
    surfaces = lens.surfaces
    media = lens.media()
    dummy = [not s.mirror and not s.is_ideal and media[j] == media[j + 1] for j, s in enumerate(surfaces)]
    found: list[LoadWarning] = []
    sign = 1.0
    for i in range(len(surfaces) - 1):
        a = surfaces[i]
        sign = -sign if a.mirror else sign
        # a dummy (the same medium on both sides) is a reference plane, not matter: compare it with its
        # neighbour only to note a backward segment, and compare the real surfaces on either side across it
        k, gap_mm = i + 1, a.thickness_mm
        if not dummy[i]:
            while k < len(surfaces) - 1 and dummy[k] and surfaces[k].transform_after is None \
                    and surfaces[k + 1].transform_before is None:
                gap_mm += surfaces[k].thickness_mm
                k += 1
            if dummy[k]:
                k, gap_mm = i + 1, a.thickness_mm  # dummies up to the last surface: nothing real behind
        for j, t_mm in ((i + 1, a.thickness_mm),) + (((k, gap_mm),) if k != i + 1 else ()):
            hit = _crossing(lens, i, j, t_mm, sign, samples, beam_heights_mm)
            if hit is None:
                continue
            if dummy[i] or dummy[j]:
                if hit.code != "edge_thickness":
                    hit = LoadWarning("dummy_crossing", hit.text.split(" -- ")[0] + "; surface "
                                      f"{(i if dummy[i] else j) + 1} is a dummy (the same medium on both sides): "
                                      "rays reach it by a backward segment, as OpticStudio traces them",
                                      i, a.line)
            elif hit.code == "crossing":
                raise PrescriptionError(hit.text, surface=i, line=a.line,
                                        hint="check the thickness, the radii and the semi-diameters")
            found.append(hit)
    last = surfaces[-1]
    sign = -sign if last.mirror else sign
    if sign * last.thickness_mm < 0.0 and last.transform_after is None and lens.is_centred:
        if image_distance_mm is not None and sign * image_distance_mm < 0.0:
            return found  # a virtual image: the image surface sits where the backward-extended rays meet
        real = "" if image_distance_mm is None else \
            f", but the paraxial image is real ({sign * image_distance_mm:.6g} mm behind the last vertex)"
        raise PrescriptionError(f"the image surface lies {-sign * last.thickness_mm:g} mm in front of the last "
                                f"surface{real}", surface=len(surfaces) - 1, line=last.line,
                                hint="the last thickness runs to the image; it may be negative only for a "
                                     "virtual image (a diverging beam leaving the lens)")
    return found


def _crossing(lens: Lens, i: int, j: int, gap_mm: float, sign: float, samples: int,
              beam_heights_mm: np.ndarray | None) -> LoadWarning | None:
    """Surfaces i and j (j > i, ``gap_mm`` apart at the vertices, only dummies between them): None when they do
    not cross within the file's semi-diameters, else a :class:`LoadWarning` coded ``edge_thickness`` (a
    crossing beyond the axial beam) or ``crossing`` (the caller decides whether that is an error)."""
    surfaces = lens.surfaces
    a, b = surfaces[i], surfaces[j]
    if a.transform_after is not None or b.transform_before is not None:
        return None  # their sags do not share an axis
    if a.semi_diameter_mm is None or b.semi_diameter_mm is None or a.semi_diameter_auto or b.semi_diameter_auto:
        # computed apertures are estimates (paraxial ones overshoot on wide lenses): only
        # the file's own semi-diameters can prove a crossing
        if j == i + 1 and sign * a.thickness_mm < 0.0 and not a.material.is_air:
            raise PrescriptionError(f"negative thickness {a.thickness_mm:g} mm inside glass "
                                    f"{a.material.describe()}", surface=i, line=a.line)
        return None
    r = np.linspace(0.0, min(a.semi_diameter_mm, b.semi_diameter_mm), samples)
    gap = sign * (gap_mm + np.asarray(b.sag(r)) - np.asarray(a.sag(r)))
    worst = int(np.argmin(gap))
    if gap[worst] >= -CROSSING_TOL_MM:
        return None
    begins = float(r[int(np.argmax(gap < -CROSSING_TOL_MM))])
    if beam_heights_mm is not None and begins > max(beam_heights_mm[i], beam_heights_mm[j]):
        return LoadWarning(
            "edge_thickness",
            f"surfaces {i + 1} and {j + 1} cross beyond the axial beam: from height {begins:.4g} mm (the "
            f"marginal ray reaches {max(beam_heights_mm[i], beam_heights_mm[j]):.4g} mm) to the "
            f"semi-diameter {r[-1]:.4g} mm surface {j + 1} lies up to {-gap[worst]:.4g} mm in front of "
            f"surface {i + 1}; rays through that zone cross the gap backwards", i, a.line)
    return LoadWarning("crossing", f"surfaces {i + 1} and {j + 1} cross: at height {r[worst]:.4g} mm surface "
                       f"{j + 1} lies {-gap[worst]:.4g} mm in front of surface {i + 1} (thickness {gap_mm:g} mm)",
                       i, a.line)
