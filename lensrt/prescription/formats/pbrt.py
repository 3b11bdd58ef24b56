"""pbrt lens tables (``.dat``): radius, thickness, index, aperture diameter.

One row per surface, from the object side, four numbers: radius of curvature
(mm, 0 marks the aperture stop; the usual sign convention, R > 0 with its
centre toward the image), thickness (mm), refractive index of the medium
after the surface (0 on the stop row means air), and the clear aperture
DIAMETER (mm). ``#`` starts a comment.

ISET's ``isetlens`` writes the same table with a header: a comment ``# Focal length``
followed by a line with that one number (mm) before the rows. The reader accepts
it there (only there), and keeps it as the note ``stated_focal_length_mm``.

Column 2 comes in two conventions:

* ``"next"``: the distance from this surface to the next one (pbrt's scaled
  ``*.NNmm.dat`` files); the last row's value is 0 (the film distance is found
  by focusing);
* ``"previous"``: the distance from the previous surface to this one (the
  unscaled pbrt-v4 tables whose header names the column ``axpos``); the first
  row's value is 0.

``thickness="auto"`` picks ``"previous"`` when the first row's distance is 0
and a header comment names the column ``axpos`` (or the first surface is glass,
which cannot be 0 mm thick), and ``"next"`` otherwise: pbrt's scaled files kept
the ``axpos`` header of their originals, so the header alone does not decide.
An explicit value overrides the guess.

pbrt tables carry no system data, so the reader states its defaults in
``lens.notes["pbrt_defaults"]``: object at infinity; the aperture floats by the
stop's diameter; constant indices (no dispersion) at the wavelengths 486.1,
587.6 (primary) and 656.3 nm; the image surface at the paraxial focus (unless
the last row gives a distance); fields at 0, 0.7 and 1 times the largest
angle whose paraxial chief ray stays inside every clear aperture (the
half-vignetted field), or ``field_deg`` when given.
"""
from __future__ import annotations

import math
from pathlib import Path

from ...errors import PrescriptionError, located
from ..materials import AIR, ConstantIndex, Material
from ..model import Aperture, Fields, Lens, Surface, Wavelengths
from ._common import make_lens, parse_number, reject_other_format

__all__ = ["read_pbrt", "loads_pbrt", "THICKNESS_CONVENTIONS", "DEFAULT_WAVELENGTHS_NM"]

THICKNESS_CONVENTIONS = ("auto", "next", "previous")
DEFAULT_WAVELENGTHS_NM = (486.1, 587.6, 656.3)
DEFAULT_FIELD_FRACTIONS = (0.0, 0.7, 1.0)


def _paraxial(curv: list[float], thick: list[float], n_after: list[float]) -> tuple[list[float], list[float], float]:
    """ynu trace of the ray from infinity (y = 1, u = 0) and of the ray through vertex 1 (y = 0, u = 1).

    Returns the heights of both rays at every surface and the back focal
    distance of the first (from the last vertex; ``inf`` for an afocal lens).
    Field Guide p. 3-4: n'u' = nu - y c (n' - n); y_next = y + t u'.
    """
    ya, ua, yb, ub, n = 1.0, 0.0, 0.0, 1.0, 1.0
    ha, hb = [], []
    for i, (c, n2) in enumerate(zip(curv, n_after)):
        ha.append(ya)
        hb.append(yb)
        ua = (n * ua - ya * c * (n2 - n)) / n2
        ub = (n * ub - yb * c * (n2 - n)) / n2
        n = n2
        if i < len(curv) - 1:
            ya += thick[i] * ua
            yb += thick[i] * ub
    bfl = math.inf if ua == 0.0 else -ya / ua
    return ha, hb, bfl


def loads_pbrt(text: str, path: str | Path | None = None, thickness: str = "auto",
               field_deg: float | None = None) -> Lens:
    """Parse a pbrt lens table (see the module docstring for the conventions and defaults)."""
    spath = str(path) if path is not None else None
    if thickness not in THICKNESS_CONVENTIONS:
        raise PrescriptionError(f"unknown pbrt thickness convention {thickness!r}", path=spath,
                                hint="use next, previous or auto")
    reject_other_format(text, "pbrt", spath)
    comments, rows = [], []
    stated: tuple[int, float] | None = None
    for no, raw in enumerate(text.splitlines(), start=1):
        body, _, comment = raw.partition("#")
        if comment.strip() and not body.strip():
            comments.append(comment.strip().strip('"'))
        toks = body.split()
        if not toks:
            continue
        if len(toks) == 1 and not rows and stated is None and comments and "focal length" in comments[-1].lower():
            stated = (no, parse_number(toks[0], "focal length", path=spath, line=no))  # ISET's header line
            continue
        if len(toks) != 4:
            raise PrescriptionError(f"{len(toks)} columns where a pbrt lens row has 4 "
                                    "(radius, thickness, index, aperture diameter)", path=spath, line=no)
        vals = [parse_number(t, what, path=spath, line=no) for t, what in
                zip(toks, ("radius", "thickness", "refractive index", "aperture diameter"))]
        rows.append((no, vals))
    if not rows:
        raise PrescriptionError("no lens rows: this is not a pbrt lens table", path=spath,
                                hint="each row is 'radius thickness index aperture-diameter'")
    convention = thickness
    col2 = [v[1] for _, v in rows]
    if convention == "auto":
        # pbrt's scaled *.NNmm.dat files kept the "axpos" header of their originals, so the header
        # alone does not decide: "previous" needs the first row's distance to be 0 as well
        axpos = any("axpos" in c.lower() for c in comments)
        glass_first = rows[0][1][2] not in (0.0, 1.0)
        convention = "previous" if col2[0] == 0.0 and (axpos or glass_first) else "next"
    if convention == "previous":
        if col2[0] != 0.0:
            raise PrescriptionError(f"the first row's axial distance is {col2[0]:g}, not 0, in the 'previous' "
                                    "convention", path=spath, line=rows[0][0],
                                    hint="use the 'next' convention (--pbrt-thickness next) for this file")
        gaps = col2[1:] + [0.0]
    else:
        gaps = col2
    curv, n_after, sds, mats, stops = [], [], [], [], []
    for (no, (r, _t, n, diam)), gap in zip(rows, gaps):
        stop = r == 0.0
        if n == 0.0 and not stop:
            raise PrescriptionError("index 0 on a row that is not the stop (radius 0)", path=spath, line=no,
                                    hint="give the refractive index after the surface (1 for air)")
        if diam <= 0.0:
            raise PrescriptionError(f"aperture diameter {diam:g} mm must be positive", path=spath, line=no)
        with located(spath, no):
            mat: Material = AIR if n in (0.0, 1.0) else ConstantIndex(n)
        curv.append(0.0 if stop else 1.0 / r)
        n_after.append(mat.index(587.6) if not mat.is_air else 1.0)
        sds.append(diam / 2.0)
        mats.append(mat)
        stops.append(stop)
    # image distance: the last row's gap if given, else the paraxial focus
    notes = []
    ha, hb, bfl = _paraxial(curv, gaps, n_after)
    last_line = rows[-1][0]
    if gaps[-1] != 0.0:
        image = gaps[-1]
        notes.append(("image_distance", "from the last row of the table"))
    else:
        if not math.isfinite(bfl) or bfl <= 0.0:
            raise PrescriptionError(f"the paraxial image lies {'at infinity' if not math.isfinite(bfl) else f'{-bfl:g} mm in front of the last surface'}; "
                                    "cannot place the image surface", path=spath, line=last_line,
                                    hint="check the radii, thicknesses and indices")
        image = bfl
    surfaces = []
    for k, (no, _) in enumerate(rows):
        with located(spath, no):
            surfaces.append(Surface(curvature_per_mm=curv[k], thickness_mm=gaps[k] if k < len(rows) - 1 else image,
                                    material=mats[k], semi_diameter_mm=sds[k], is_stop=stops[k], line=no))
    # field: option, or the paraxial chief-ray limit (half-vignetted field)
    if field_deg is None:
        if sum(stops) == 1:
            s = stops.index(True)
            if ha[s] == 0.0:
                raise PrescriptionError("the axial ray crosses the axis at the stop; cannot size the field",
                                        path=spath, line=rows[s][0], hint="pass a field angle (--pbrt-field-deg)")
            k = -hb[s] / ha[s]
            ratios = [sd / abs(yb + k * ya) for sd, ya, yb in zip(sds, ha, hb) if abs(yb + k * ya) > 1e-12]
            tan_max = min(ratios) if ratios else math.tan(math.radians(20.0))
            field_deg_used = math.degrees(math.atan(tan_max))
            how = "paraxial chief-ray limit of the clear apertures (half-vignetted field)"
        else:
            field_deg_used, how = 0.0, "on axis (the stop count is wrong; the model rejects it)"
    else:
        field_deg_used, how = float(field_deg), "given by the caller"
    field_deg_used = round(field_deg_used, 3)
    with located(spath, None):
        fields = Fields("angle", tuple(math.radians(fr * field_deg_used) for fr in DEFAULT_FIELD_FRACTIONS))
    notes.insert(0, ("pbrt_defaults", (
        "pbrt tables carry no system data: object at infinity; aperture floats by the stop diameter; constant "
        f"indices (no dispersion); wavelengths {', '.join(f'{w:g}' for w in DEFAULT_WAVELENGTHS_NM)} nm "
        f"(primary 587.6); fields 0, 0.7, 1 x {field_deg_used:g} deg ({how}); image surface at the paraxial "
        "focus unless the table gives the last distance")))
    notes.insert(1, ("pbrt_thickness", f"{convention} ({'detected' if thickness == 'auto' else 'option'})"))
    if stated is not None:
        notes.append(("stated_focal_length_mm", f"{stated[1]:g} (ISET isetlens header, line {stated[0]}; not used "
                                                "in the model)"))
    name = comments[0] if comments else (Path(spath).stem if spath else "pbrt lens")
    source = "pbrt lens table" + (f" {Path(spath).name}" if spath else "") + \
        (": " + "; ".join(comments) if comments else "")
    return make_lens(spath, surfaces=tuple(surfaces), aperture=Aperture("float_by_stop", 0.0), fields=fields,
                     wavelengths=Wavelengths(DEFAULT_WAVELENGTHS_NM, (), 1), object_distance_mm=math.inf,
                     name=name, source=source, notes=tuple(notes))


def read_pbrt(path: str | Path, text: str | None = None, thickness: str = "auto",
              field_deg: float | None = None) -> Lens:
    """Read a pbrt ``.dat`` lens table.

    Parameters
    ----------
    path : str or Path
        The table.
    text : str, optional
        Its decoded text (read from ``path`` when omitted).
    thickness : {"auto", "next", "previous"}
        Meaning of column 2 (module docstring); ``auto`` reads the header.
    field_deg : float, optional
        Largest field half-angle in degrees (default: the paraxial chief-ray
        limit of the clear apertures).
    """
    if text is None:
        from . import read_text
        text = read_text(path)
    return loads_pbrt(text, path, thickness=thickness, field_deg=field_deg)
