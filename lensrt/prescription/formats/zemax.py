"""Zemax OpticStudio ``.zmx`` reader: the sequential, rotationally symmetric subset.

Mirrors, coordinate breaks and surface apertures are read by
:mod:`.zemax_geometry` (see there). Supported (see the table in docs/how-to/import-zemax-codev-pbrt.md): ``UNIT`` (MM, CM, IN, M; lengths are
converted to mm), ``SURF`` with ``TYPE STANDARD`` or ``EVENASPH``, ``CURV``,
``DISZ`` (``INFINITY`` on the object surface), ``GLAS``, ``CONI``, ``PARM``
(EVENASPH: PARM 1 is the r^2 coefficient, PARM 2 r^4, ...), ``DIAM``
(semi-diameter), ``CLAP 0 r`` (a circular clear aperture), ``STOP``, ``COMM``;
system data ``ENPD``/``FNUM``/``OBNA``/``FLOA``, ``FTYP``, ``XFLN``/``YFLN``/
``FWGN`` (and the older ``XFLD``/``YFLD``/``FWGT``), ``WAVM``/``WAVL``/``WWGT``
(micrometres), ``PWAV``, ``GCAT``, ``NAME``, ``NOTE``, vignetting factors
``VDXN``/``VDYN``/``VCXN``/``VCYN`` (kept in ``lens.notes``).

Glass: looked up as :mod:`lensrt.prescription.glass_lookup` says -- the
catalogs ``GCAT`` names first, then every catalog lensrt has (vendor sheets,
the refractiveindex.info database, user ``.agf`` catalogs, aliases such as
``F_SILICA``); a successor only with ``--glass-substitute``, the line's n_d/V_d
only with ``--glass-model-fallback``; else one error. ``GLAS ___BLANK``
(OpticStudio's model glass) is a model glass by definition. Every
approximation is a :class:`~lensrt.prescription.model.LoadWarning` in
``lens.warnings`` (and a Python warning).

Display, optimisation and tolerancing data are ignored explicitly
(:data:`IGNORED`); merit-function operands after the last surface are
ignored. Everything that changes the optics but lies outside lensrt's model
(mirrors, coordinate breaks, tilts/decenters, non-sequential mode, gratings,
other surface types, unsupported multi-configuration operands, non-circular or decentred apertures,
a curved object surface, an aspheric image surface, ...) is an error naming the file,
the line and the construct; a spherical image surface (``CURV`` on the last SURF) is
``Lens.image_curvature_per_mm``. A keyword lensrt does not know is ignored with a
``keyword_unknown`` warning naming it and its line
(:mod:`~lensrt.prescription.formats.keywords`). ``FLOA`` floats on the stop's
semi-diameter, or where the stop has none on the file's other aperture.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from ...errors import PrescriptionError, located
from ...units import MM_PER_UNIT, NM_PER_UM, deg_to_rad
from ..configurations import MultiConfigLens
from ..glass_lookup import GlassRequest, resolve_glass
from ..limits import MAX_ZEMAX_PARM
from ..materials import AIR, ConstantIndex, Material, ModelGlass
from ..model import Aperture, Fields, Lens, LoadWarning, Surface, Wavelengths  # noqa: F401 (Lens in annotations)
from ..shapes import MAX_SHAPE_TERMS
from ._common import (LensFileWarning, emit_load_warnings, fmt_list, make_lens, parse_number, reject_other_format, substitution_note)
from .keywords import ZemaxKeywordPolicy
from .zemax_geometry import aperture_entry, coordbrk_transform, scbd_transform, surface_apertures
from .zemax_mce import MultiConfigReader
from .zemax_shapes import SHAPE_TYPES, zemax_shape

__all__ = ["read_zmx", "loads_zmx", "GlassFallbackWarning", "IGNORED", "UNSUPPORTED"]


class GlassFallbackWarning(LensFileWarning):
    """A model glass: the n_d/V_d of the file are used (``GLAS ___BLANK`` or ``--glass-model-fallback``)."""


#: keywords that never change the optics of a sequential lens, ignored on purpose
IGNORED: dict[str, str] = {
    "VERS": "file version", "MODE": "checked: SEQ only", "PFIL": "file settings", "LANG": "language",
    "HIDE": "display", "SLAB": "display label", "MIRR": "mirror-substrate display", "POPS": "physical optics",
    "FIMP": "import flag", "COAT": "coating (not modelled)", "COFN": "coating file names",
    "GFAC": "glass substitution settings", "GLRS": "glass settings", "GSTD": "glass settings",
    "NSCD": "non-sequential defaults", "RAIM": "ray aiming (an analysis setting)", "PUSH": "settings",
    "SDMA": "semi-diameter margin", "ROPD": "OPD reference", "PICB": "settings", "POLS": "polarisation",
    "TOL": "tolerance data", "MOFF": "multi-configuration operand", "HYPR": "settings",
    "RCMF": "settings", "VDSZ": "optimisation variable", "VPAR": "optimisation variable",
    "VCRV": "optimisation variable", "VTHI": "optimisation variable", "VCON": "optimisation variable",
    "PPAR": "parameter pickup (value stored)",
    "PZUP": "thickness pickup (value stored)", "MAZH": "settings", "MEMA": "mechanical semi-diameter",
    "OMMA": "mechanical settings", "OEMA": "mechanical settings", "FLAP": "floating aperture = DIAM",
    "DMFS": "merit function settings", "BLNK": "merit function comment", "AUTH": "author",
    "EFFL": "settings", "TCED": "settings", "CONF": "configuration settings",
    "DBDT": "settings", "PWFN": "settings", "OPDX": "merit operand", "ENVD": "checked: 20 C, 1 atm",
    "PUPD": "checked: uniform apodization", "OBDC": "checked: zero aperture decenter",
    "XDAT": "checked: zero extra data", "SCBD": "image surface tilt/decenter",
    "NOTE": "kept in lens.notes", "NAME": "lens name", "COMM": "surface label", "VANN": "checked: zero",
    "TRAC": "merit operand", "GLCB": "merit operand",
}

#: keywords of constructs outside lensrt's model, and what to tell the user
UNSUPPORTED: dict[str, str] = {
    "SPID": "a spider aperture", "UDAP": "a user-defined aperture", "RCAP": "a rectangular aperture",
    "DECX": "a surface decenter", "DECY": "a surface decenter",
    "TILT": "a surface tilt", "NSOB": "a non-sequential object", "GRAT": "a grating",
}

_SUPPORTED_TYPES = ("STANDARD", "EVENASPH", "COORDBRK", "PARAXIAL") + SHAPE_TYPES
_TYPE_NAMES = {
    "DGRATING": "a diffraction grating",
    "TOROIDAL": "a toroidal surface", "BICONICX": "a biconic surface", "BICONIC": "a biconic surface",
    "PARAXIAL": "an ideal paraxial lens", "ODDASPHE": "an odd asphere", "XOSPHERE": "an extended odd asphere",
    "XASPHERE": "an extended asphere", "SZERNSAG": "a Zernike sag surface",
    "FZERNSAG": "a Zernike fringe sag surface", "BINARY_1": "a binary optic",
    "BINARY_2": "a binary optic", "GRID_SAG": "a grid sag surface", "TILTSURF": "a tilted surface",
    "NONSEQCO": "a non-sequential component", "USERSURF": "a user-defined surface", "QED_TYPE": "a Q-type asphere",
}
_UNITS = {"MM": "mm", "CM": "cm", "IN": "in", "INCH": "in", "INCHES": "in", "M": "m", "METER": "m",
          "METERS": "m", "METR": "m"}
_FIELD_TYPES = {0: "angle", 1: "object_height", 2: "paraxial_image_height", 3: "real_image_height"}


@dataclass
class _Surf:
    number: int
    line: int
    type: str = "STANDARD"
    type_line: int | None = None
    curv: float = 0.0
    disz: float | None = None
    glass: list[str] | None = None
    glass_line: int | None = None
    conic: float = 0.0
    parm: dict[int, tuple[float, int]] = field(default_factory=dict)
    xdat: dict[int, tuple[float, int]] = field(default_factory=dict)
    diam: float | None = None
    clap: float | None = None
    stop: bool = False
    label: str = ""
    mirror: bool = False
    diam_fixed: bool = False
    apertures: list[tuple[str, float, float, int]] = field(default_factory=list)
    obdc: tuple[float, float] = (0.0, 0.0)
    scbd: tuple[list[float], int] | None = None
    #: an ``SCBD 2`` line (the tilt/decenter after the surface): refused on a lens surface
    scbd_after: tuple[list[float], int] | None = None


def _rest(raw: str, keyword: str) -> str:
    s = raw.strip()
    return s[len(keyword):].strip()


class _Reader:
    def __init__(self, path: str | None) -> None:
        self.path = path
        self.unit = "mm"
        self.surfs: list[_Surf] = []
        self.aperture: tuple[str, float, int] | None = None
        self.ftyp: list[str] | None = None
        self.ftyp_line: int | None = None
        self.fields: dict[str, tuple[list[float], int]] = {}
        self.waves: dict[int, tuple[float, float, int]] = {}
        self.wavl: tuple[list[float], int] | None = None
        self.wwgt: tuple[list[float], int] | None = None
        self.pwav: tuple[int, int] | None = None
        self.gcat: list[str] | None = None
        self.name = ""
        self.notes: list[tuple[str, str]] = []
        self.note_text: list[str] = []
        self.subs: dict[str, str] = {}
        self.warnings: list[LoadWarning] = []
        self.keywords = ZemaxKeywordPolicy()
        self.floa_line: int | None = None
        self.mce: MultiConfigReader | None = None  # multi-configuration rows (zemax_mce)
        self.in_mce = False

    # -- helpers -------------------------------------------------------------
    def err(self, message: str, line: int | None, hint: str | None = None) -> PrescriptionError:
        return PrescriptionError(message, path=self.path, line=line, hint=hint)

    def num(self, tok: str, what: str, line: int, allow_inf: bool = False) -> float:
        return parse_number(tok, what, path=self.path, line=line, allow_inf=allow_inf)

    def nums(self, toks: list[str], what: str, line: int) -> list[float]:
        return [self.num(t, what, line) for t in toks]

    def cur(self, kw: str, line: int) -> _Surf:
        if not self.surfs:
            raise self.err(f"{kw} appears before the first SURF", line,
                           "surface data must follow a 'SURF n' line")
        return self.surfs[-1]

    # -- one line ------------------------------------------------------------
    def line(self, raw: str, no: int, after_last_surf: bool) -> None:
        if self.in_mce:
            if self.mce.accepts(raw):  # type: ignore[union-attr]
                self.mce.add(raw, no)  # type: ignore[union-attr]
                return
            self.in_mce = False
        toks = raw.split()
        kw = toks[0].upper()
        args = toks[1:]
        if kw == "SURF":
            n = int(self.num(args[0], "surface number", no)) if args else -1
            if n != len(self.surfs):
                self._numbering_gap(n, args, no)
            self.surfs.append(_Surf(number=n, line=no))
            return
        if kw == "MODE":
            if not args or args[0].upper() != "SEQ":
                raise self.err(f"MODE {' '.join(args)}: only sequential (MODE SEQ) files are supported", no,
                               "non-sequential and mixed-mode systems are outside lensrt's model")
            return
        handler = getattr(self, "kw_" + kw, None)
        if handler is not None:
            try:
                handler(args, no, raw)
            except IndexError:  # a keyword without its values ("CURV" alone)
                raise self.err(f"{kw} without a value", no, f"give {kw} its value(s), or delete the line") from None
            return
        if kw in UNSUPPORTED:
            raise self.err(f"{kw}: {UNSUPPORTED[kw]} is not supported", no,
                           "lensrt models rotationally symmetric, sequential, refractive lenses only")
        if kw in IGNORED:
            return
        if after_last_surf and not raw[:1].isspace() and len(kw) == 4 and kw.isalnum():
            return  # a merit-function or tolerance operand: optimisation data, not optics
        self.keywords.unread(toks[0], no, len(self.surfs) - 2 if raw[:1].isspace() and self.surfs else None)

    # -- system data ---------------------------------------------------------
    def kw_UNIT(self, args, no, raw):
        if not args or args[0].upper() not in _UNITS:
            raise self.err(f"unknown lens unit {' '.join(args[:1])!r}", no, "use UNIT MM, CM, IN or M")
        self.unit = _UNITS[args[0].upper()]

    def kw_NAME(self, args, no, raw):
        self.name = _rest(raw, raw.split()[0]).strip('"')

    def kw_NOTE(self, args, no, raw):
        text = " ".join(args[1:]).strip() if args and args[0].isdigit() else " ".join(args)
        if text:
            self.note_text.append(text)

    def _set_aperture(self, kind: str, value: float, no: int) -> None:
        if self.aperture is not None and self.aperture[0] != kind:
            raise self.err(f"two system apertures ({self.aperture[0]} on line {self.aperture[2]} and {kind})", no,
                           "keep one of ENPD, FNUM, OBNA, FLOA")
        self.aperture = (kind, value, no)

    def kw_ENPD(self, args, no, raw):
        self._set_aperture("epd", self.num(args[0], "entrance pupil diameter", no), no)

    def kw_FNUM(self, args, no, raw):
        self._set_aperture("image_fno", self.num(args[0], "f-number", no), no)

    def kw_OBNA(self, args, no, raw):
        self._set_aperture("object_na", self.num(args[0], "object-space NA", no), no)

    def kw_FLOA(self, args, no, raw):
        self.floa_line = no  # resolved in _aperture: the stop's semi-diameter, else the other aperture given

    def kw_FTYP(self, args, no, raw):
        self.ftyp, self.ftyp_line = args, no

    def _field_list(self, key: str, args, no) -> None:
        self.fields[key] = (self.nums(args, f"{key} value", no), no)

    def kw_XFLN(self, args, no, raw):
        self._field_list("XFLN", args, no)

    def kw_YFLN(self, args, no, raw):
        self._field_list("YFLN", args, no)

    def kw_FWGN(self, args, no, raw):
        self._field_list("FWGN", args, no)

    kw_XFLD, kw_YFLD, kw_FWGT = kw_XFLN, kw_YFLN, kw_FWGN

    def kw_VDXN(self, args, no, raw):
        self._field_list("VDXN", args, no)

    def kw_VDYN(self, args, no, raw):
        self._field_list("VDYN", args, no)

    def kw_VCXN(self, args, no, raw):
        self._field_list("VCXN", args, no)

    def kw_VCYN(self, args, no, raw):
        self._field_list("VCYN", args, no)

    def kw_VANN(self, args, no, raw):
        if any(v != 0.0 for v in self.nums(args, "vignetting angle", no)):
            raise self.err("VANN: rotated vignetting (vignetting angle) is not supported", no)

    def kw_WAVM(self, args, no, raw):
        i = int(self.num(args[0], "wavelength number", no))
        w = self.num(args[1], "wavelength", no) if len(args) > 1 else 0.55
        wt = self.num(args[2], "wavelength weight", no) if len(args) > 2 else 1.0
        self.waves[i] = (w, wt, no)

    def kw_WAVL(self, args, no, raw):
        self.wavl = (self.nums(args, "wavelength", no), no)

    def kw_WWGT(self, args, no, raw):
        self.wwgt = (self.nums(args, "wavelength weight", no), no)

    def kw_PWAV(self, args, no, raw):
        self.pwav = (int(self.num(args[0], "primary wavelength number", no)), no)

    def kw_GCAT(self, args, no, raw):
        self.gcat = [a.upper() for a in args]

    def kw_ENVD(self, args, no, raw):
        vals = self.nums(args[:2], "environment value", no)
        if len(vals) == 2 and (vals[0] != 20.0 or vals[1] != 1.0):
            msg = (f"ENVD: temperature {vals[0]:g} C, pressure {vals[1]:g} atm; lensrt uses catalog indices "
                   "at 20 C and 1 atm (thermal index changes are not modelled)")
            warnings.warn(f"{self.path}:{no}: {msg}", UserWarning, stacklevel=4)
            self.notes.append(("environment", msg))

    def kw_PUPD(self, args, no, raw):
        if args and self.num(args[0], "apodization type", no) != 0:
            raise self.err("PUPD: pupil apodization is not supported", no, "use uniform apodization")

    def kw_MNUM(self, args, no, raw):
        count = int(self.num(args[0], "configuration count", no)) if args else 1
        if count != 1:
            current = int(self.num(args[1], "current configuration", no)) if len(args) > 1 else 1
            self.mce, self.in_mce = MultiConfigReader(self.path, count, current, no), True

    def _numbering_gap(self, n: int, args: list[str], no: int) -> None:
        """A SURF number that skips some (``SURF 39`` after ``SURF 37``, a surface deleted by hand): read as the next
        surface where the light between is in air -- there a skipped surface, were it a plane of zero thickness
        in air (what an empty row of OpticStudio's editor is), changes nothing -- with a ``surface_numbering``
        warning; any other order is an error."""
        prev = self.surfs[-1] if self.surfs else None
        if prev is None or n < len(self.surfs) or prev.glass is not None or self.mce is not None:
            why = "" if prev is None or n < len(self.surfs) else \
                (" after a surface whose medium is not air" if prev.glass is not None else " in a multi-configuration "
                 "file (its operands name surfaces by number)")
            raise self.err(f"SURF {args[0] if args else ''} out of order (expected SURF {len(self.surfs)}){why}", no,
                           "surfaces must be numbered 0 (object), 1, 2, ... in order")
        self.warnings.append(LoadWarning(
            "surface_numbering", f"SURF {n} follows SURF {prev.number}: read as surface {len(self.surfs)} (the light "
            f"between is in air, so a skipped plane surface of zero thickness would change nothing)", None, no))

    def glass(self, name: str, no: int) -> Material:
        """The material a multi-configuration GLSS row names (looked up as a GLAS line is)."""
        return self.material(_Surf(number=-1, line=no, glass=[name], glass_line=no))

    # -- surface data --------------------------------------------------------
    def kw_TYPE(self, args, no, raw):
        s = self.cur("TYPE", no)
        t = args[0].upper() if args else ""
        if t not in _SUPPORTED_TYPES:
            what = _TYPE_NAMES.get(t, f"surface type {t or '(none)'}")
            raise self.err(f"TYPE {t}: {what} is not supported", no,
                           f"lensrt reads the surface types {', '.join(_SUPPORTED_TYPES)}")
        s.type, s.type_line = t, no

    def kw_CURV(self, args, no, raw):
        self.cur("CURV", no).curv = self.num(args[0], "curvature", no)

    def kw_DISZ(self, args, no, raw):
        s = self.cur("DISZ", no)
        s.disz = self.num(args[0], "thickness", no, allow_inf=True)
        if math.isinf(s.disz) and s.number != 0:
            raise self.err("DISZ INFINITY on a lens surface", no, "only the object distance may be infinite")

    def kw_GLAS(self, args, no, raw):
        s = self.cur("GLAS", no)
        if not args:
            raise self.err("GLAS without a glass name", no)
        if args[0].upper() == "MIRROR":
            s.mirror = True
            return
        s.glass, s.glass_line = args, no

    def kw_CONI(self, args, no, raw):
        self.cur("CONI", no).conic = self.num(args[0], "conic constant", no)

    def kw_PARM(self, args, no, raw):
        s = self.cur("PARM", no)
        i = int(self.num(args[0], "parameter number", no))
        v = self.num(args[1], f"PARM {i}", no) if len(args) > 1 else 0.0
        if i < 1 and not (i == 0 and s.type == "TOROIDAL"):
            raise self.err(f"PARM {i}: parameter numbers start at 1", no)
        if i > MAX_ZEMAX_PARM:
            raise self.err(f"PARM {i}: parameter numbers of an even asphere stop at {MAX_ZEMAX_PARM}", no,
                           "PARM n is the r^(2n) coefficient; check the number")
        s.parm[i] = (v, no)

    def kw_DIAM(self, args, no, raw):
        d = self.num(args[0], "semi-diameter", no)
        if d < 0.0:
            raise self.err(f"DIAM {args[0]}: a negative semi-diameter", no,
                           "give the clear semi-diameter as a positive number (0: computed on load)")
        s = self.cur("DIAM", no)
        s.diam = d
        s.diam_fixed = len(args) > 1 and args[1] == "1"

    def kw_CLAP(self, args, no, raw):
        s = self.cur("CLAP", no)
        vals = [self.num(t, "clear aperture radius", no, allow_inf=True) for t in args]
        s.apertures.append(aperture_entry("CLAP", vals, no, self.path))

    def kw_OBSC(self, args, no, raw):
        s = self.cur("OBSC", no)
        vals = [self.num(t, "obscuration radius", no, allow_inf=True) for t in args]
        s.apertures.append(aperture_entry("OBSC", vals, no, self.path))

    def kw_SQAP(self, args, no, raw):
        s = self.cur("SQAP", no)
        s.apertures.append(aperture_entry("SQAP", self.nums(args, "aperture half-width", no), no, self.path))

    def kw_ELAP(self, args, no, raw):
        s = self.cur("ELAP", no)
        s.apertures.append(aperture_entry("ELAP", self.nums(args, "aperture half-width", no), no, self.path))

    def kw_STOP(self, args, no, raw):
        self.cur("STOP", no).stop = True

    def kw_COMM(self, args, no, raw):
        self.cur("COMM", no).label = _rest(raw, raw.split()[0]).strip('"')

    def kw_OBDC(self, args, no, raw):
        vals = self.nums(args[:2], "aperture decenter", no)
        self.cur("OBDC", no).obdc = (vals[0], vals[1] if len(vals) > 1 else 0.0)

    def kw_SCBD(self, args, no, raw):
        vals = self.nums(args, "tilt/decenter value", no)
        if any(v != 0.0 for v in vals[1:]):  # read at assembly (zemax_geometry.scbd_transform)
            if vals[0] == 2.0:
                self.cur("SCBD", no).scbd_after = (vals, no)
            else:
                self.cur("SCBD", no).scbd = (vals, no)

    def kw_XDAT(self, args, no, raw):
        s = self.cur("XDAT", no)
        v = self.num(args[1], "extra data value", no) if len(args) > 1 else 0.0
        if s.type in SHAPE_TYPES:
            i = int(self.num(args[0], "extra data number", no))
            if not 1 <= i <= MAX_SHAPE_TERMS + 3:
                raise self.err(f"XDAT {i}: extra data numbers of a {s.type} surface run 1..{MAX_SHAPE_TERMS + 3}", no)
            s.xdat[i] = (v, no)
        elif v != 0.0:
            raise self.err(f"XDAT: extra surface data is not supported for {s.type} surfaces", no)

    # -- glass -----------------------------------------------------------------
    def primary_nm(self) -> float:
        """The primary wavelength (nm) as far as the file has given it (for substitution messages)."""
        um = [self.waves[i][0] for i in sorted(self.waves)] if self.waves else \
            (self.wavl[0] if self.wavl is not None else [0.5875618])
        k = self.pwav[0] - 1 if self.pwav is not None else 0
        return (um[k] if 0 <= k < len(um) else um[0]) * NM_PER_UM

    def material(self, s: _Surf, surface: int | None = None) -> Material:
        """The medium after ``s`` (the GLAS line), found as :mod:`~lensrt.prescription.glass_lookup` says."""
        if s.glass is None:
            return AIR
        toks, no = s.glass, s.glass_line
        name = toks[0]
        nd = self.num(toks[3], "n_d", no) if len(toks) > 4 else 0.0
        vd = self.num(toks[4], "V_d", no) if len(toks) > 4 else 0.0
        real = nd >= 1.0 and vd > 0.0
        if name.upper() in ("___BLANK", "MODEL"):
            if vd == 0.0 and len(toks) > 4 and 0.5 <= nd <= 5.0 and nd != 1.0:
                return self._constant_model(name, nd, surface, no)
            if not real:
                raise self.err(f"GLAS {name}: a model glass needs n_d >= 1 and V_d > 0 on the line "
                               f"(found {nd:g}, {vd:g})", no, "give 'GLAS ___BLANK 1 0 nd vd'")
            with located(self.path, no):
                glass = ModelGlass(nd, vd)
            self.warnings.append(LoadWarning("glass_model", f"model glass n_d = {nd:g}, V_d = {vd:g} (GLAS {name}): "
                                             "a two-term Cauchy law through n_d and V_d", surface, no))
            return glass
        req = GlassRequest(name, self.gcat, nd if real else None, vd if real else None, surface, no,
                           self.primary_nm())
        with located(self.path, no):
            glass, warns = resolve_glass(req)
        self.warnings += warns
        if isinstance(glass, ModelGlass):
            self.notes.append((f"model_glass_{name}", f"n_d/V_d from the GLAS line (line {no}); in no catalog"))
        elif _norm_name(glass.name) != _norm_name(name):
            self.subs[name] = glass.describe()
        return glass

    def _constant_model(self, name: str, nd: float, surface: int | None, no: int) -> Material:
        """``GLAS ___BLANK 1 0 nd 0``: a model glass with V_d = 0, i.e. no dispersion to model -- a constant index.
        Monochromatic designs write it so (a 193 nm lithography lens: fused silica 1.56029 at 193.3 nm); an index
        below 1 there is one relative to air (helium-filled gaps: 0.999712), which Snell's law reads as it reads
        any index (only ratios enter)."""
        with located(self.path, no):
            glass = ConstantIndex(nd, name=f"n={nd:g}", exotic=nd < 1.0)
        below = "; an index below 1 is read as relative to air (only index ratios enter the trace)" \
            if nd < 1.0 else ""
        self.warnings.append(LoadWarning("glass_model", f"model glass n_d = {nd:g}, V_d = 0 (GLAS {name}): no "
                                         f"dispersion, a constant index at every wavelength{below}", surface, no))
        return glass

    # -- assemble --------------------------------------------------------------
    def build(self) -> Lens:
        f = MM_PER_UNIT[self.unit]
        if len(self.surfs) < 3:
            raise self.err(f"{len(self.surfs)} SURF blocks: a lens needs the object, at least one surface and "
                           "the image", self.surfs[-1].line if self.surfs else None)
        obj, img, body = self.surfs[0], self.surfs[-1], self.surfs[1:-1]
        for s, what in ((obj, "object"), (img, "image")):
            if (s.curv != 0.0 and what == "object") or s.conic != 0.0 or any(v for v, _ in s.parm.values()):
                raise self.err(f"curved {what} surface (SURF {s.number})", s.line,
                               "lensrt's object surface is a plane" if what == "object" else
                               "lensrt's image surface is a plane or a sphere (CURV only, no conic or PARM)")
            if s.stop:
                raise self.err(f"the {what} surface (SURF {s.number}) is marked STOP", s.line)
        surfaces: list[Surface] = []
        self.image_transform = None if img.scbd is None else scbd_transform(*img.scbd, f, self.path)
        with located(self.path, obj.line):
            object_medium = self.material(obj)
        for k, s in enumerate(body):
            self._check_scbd(s)
            with located(self.path, s.line):
                before = surfaces[-1].material if surfaces else object_medium
                if s.type == "COORDBRK":
                    surfaces.append(self._coordbrk(s, before, f))
                    continue
                if s.type == "PARAXIAL":
                    surfaces.append(self._paraxial(s, k, f))
                    continue
                asph: tuple[float, ...] = ()
                shape = None
                if s.type in SHAPE_TYPES:
                    shape, asph = zemax_shape(s.type, s.parm, s.xdat, f, self.path, s.type_line or s.line)
                    if not shape.rotational:
                        self._first_order_note(len(surfaces), s)
                elif s.type == "EVENASPH":
                    n = max(s.parm) if s.parm else 0
                    asph = tuple(s.parm.get(i, (0.0, 0))[0] * f ** (1 - 2 * i) for i in range(1, n + 1))
                elif any(v != 0.0 for v, _ in s.parm.values()):
                    bad = next(ln for v, ln in s.parm.values() if v != 0.0)
                    raise self.err("PARM on a STANDARD surface", bad, "use TYPE EVENASPH for aspheric terms")
                sd, entries, fixed = s.diam, list(s.apertures), s.diam_fixed
                if len(entries) == 1 and entries[0][:2] == ("CLAP", 0.0) and s.obdc == (0.0, 0.0):
                    sd, entries, fixed = entries[0][2], [], True  # a centred circular CLAP: the semi-diameter
                if sd is not None and sd <= 0.0:
                    sd = None  # DIAM 0: no semi-diameter given (computed on load)
                sd = self._automatic_inside_clap(s, sd, entries, fixed, len(surfaces))
                surfaces.append(Surface(
                    curvature_per_mm=s.curv / f, thickness_mm=(s.disz or 0.0) * f,
                    material=before if s.mirror else self.material(s, k),
                    semi_diameter_mm=None if sd is None else sd * f,
                    conic=s.conic, asphere=asph, shape=shape, is_stop=s.stop, label=s.label, line=s.line,
                    mirror=s.mirror,
                    apertures=surface_apertures(entries, s.obdc, f, self.path), semi_diameter_fixed=fixed,
                    transform_before=None if s.scbd is None else scbd_transform(*s.scbd, f, self.path)))
        return self._system(surfaces, obj, f)

    def _check_scbd(self, s: _Surf) -> None:
        """A lens surface's SCBD lines: "before" (``SCBD 1``) becomes its ``transform_before``
        (:func:`.zemax_geometry.scbd_transform`) on a surface of glass or air; "after" (``SCBD 2``) is refused."""
        if s.scbd_after is not None:
            raise self.err("SCBD 2: a tilt/decenter after a lens surface (explicit, pickup or reverse) is not read",
                           s.scbd_after[1], "write the frame change after the surface as a COORDBRK")
        if s.scbd is not None and s.type in ("COORDBRK", "PARAXIAL"):
            raise self.err(f"SCBD on a {s.type} surface is not read", s.scbd[1],
                           "write the frame change as a COORDBRK surface")

    def _automatic_inside_clap(self, s: _Surf, sd: float | None, entries: list, fixed: bool, index: int
                               ) -> float | None:
        """An automatic semi-diameter (``DIAM v 0``) that lies inside the surface's annular ``CLAP rmin rmax``
        would, clipping, stop every ray the CLAP passes; OpticStudio clips at the CLAP only. The CLAP's outer
        radius is then the semi-diameter, with a warning."""
        if fixed or sd is None or s.obdc != (0.0, 0.0):
            return sd
        clap = [e for e in entries if e[0] == "CLAP" and e[1] >= sd and math.isfinite(e[2])]
        if not clap:
            return sd
        self.warnings.append(LoadWarning(
            "semi_diameter_from_clap", f"surface {index + 1}: the automatic semi-diameter {sd:g} (DIAM, flag 0) lies "
            f"inside its CLAP {clap[0][1]:g} {clap[0][2]:g}, which would stop every ray; the CLAP's outer radius "
            f"{clap[0][2]:g} is the semi-diameter (OpticStudio clips at the CLAP only)", index, clap[0][3]))
        return clap[0][2]

    def _first_order_note(self, index: int, s: _Surf) -> None:
        self.warnings.append(LoadWarning(
            "first_order_y_section", f"surface {index + 1} ({s.type}) is not rotationally symmetric: paraxial "
            "(first-order) data use its y-section; real rays trace the full surface", index, s.type_line or s.line))

    def _coordbrk(self, s: _Surf, before: Material, f: float) -> Surface:
        """A COORDBRK: a plane dummy surface carrying the frame change (:mod:`.zemax_geometry`)."""
        if s.curv != 0.0 or s.conic != 0.0 or s.mirror or s.glass is not None or s.apertures:
            raise self.err("a coordinate break with a curvature, conic, glass or aperture", s.type_line or s.line,
                           "a COORDBRK surface only moves the frame (PARM 1..6 and its thickness)")
        label = s.label or "coordinate break"
        return Surface(thickness_mm=(s.disz or 0.0) * f, material=before, is_stop=s.stop, label=label, line=s.line,
                       transform_before=coordbrk_transform(s.parm, f, self.path, s.type_line or s.line))

    def _paraxial(self, s: _Surf, k: int, f: float) -> Surface:
        """A TYPE PARAXIAL surface: an ideal lens of focal length PARM 1 (lens units), OPD mode PARM 2."""
        line = s.type_line or s.line
        bad = [i for i, (v, _) in s.parm.items() if i > 2 and v != 0.0]
        if bad or s.mirror or s.apertures:
            raise self.err(f"TYPE PARAXIAL with {'PARM ' + str(bad[0]) if bad else 'a mirror or surface aperture'}",
                           line, "an ideal paraxial lens has a focal length (PARM 1) and an OPD mode (PARM 2) only")
        focal, mode = s.parm.get(1, (0.0, line))[0], s.parm.get(2, (0.0, line))[0]
        if focal == 0.0:
            raise self.err("TYPE PARAXIAL with focal length 0 (PARM 1)", s.parm.get(1, (0.0, line))[1],
                           "give the ideal lens's focal length in lens units")
        if mode not in (0.0, 1.0, 2.0, 3.0):
            raise self.err(f"TYPE PARAXIAL OPD mode {mode:g} (PARM 2) is not 0, 1, 2 or 3", s.parm[2][1])
        if s.curv != 0.0 or s.conic != 0.0:
            self.warnings.append(LoadWarning("keyword_ignored", "CURV/CONI of a TYPE PARAXIAL surface: an ideal "
                                             "lens is a plane (OpticStudio ignores them too)", k, s.line))
        self.warnings.append(LoadWarning(
            "ideal_lens_opd", f"TYPE PARAXIAL (f = {focal:g}, OPD mode {int(mode)}): rays leave it as from a perfect "
            "lens; optical path lengths carry the lens's phase for an axial object at infinity, so wavefronts, PSFs "
            "and MTFs through it are exact only for a collimated axial beam entering it", k, line))
        sd = s.diam if s.diam is not None and s.diam > 0.0 else None
        return Surface(thickness_mm=(s.disz or 0.0) * f, material=self.material(s, k),
                       semi_diameter_mm=None if sd is None else sd * f, is_stop=s.stop,
                       label=s.label or "ideal paraxial lens", line=s.line, semi_diameter_fixed=s.diam_fixed,
                       ideal_focal_mm=focal * f, ideal_opd_mode=int(mode))

    def _aperture(self, surfaces: list[Surface], f: float) -> Aperture:
        """The system aperture; FLOA floats on the stop's semi-diameter, or, where the stop has none, on the
        other aperture the file gives (ENPD, FNUM, OBNA), with a warning."""
        stop_sd = next((s.semi_diameter_mm for s in surfaces if s.is_stop), None)
        if self.floa_line is not None:
            if stop_sd is not None:
                if self.aperture is not None:
                    self.warnings.append(LoadWarning(
                        "keyword_ignored", f"FLOA: the aperture floats on the stop's semi-diameter "
                        f"({stop_sd:g} mm); the {self.aperture[0]} on line {self.aperture[2]} is not used", None,
                        self.aperture[2]))
                return Aperture("float_by_stop", 0.0)
            if self.aperture is None:
                raise self.err("FLOA: the aperture floats on the stop's semi-diameter, but the stop surface has "
                               "no DIAM/CLAP and the file gives no other aperture", self.floa_line,
                               "give the stop a 'DIAM <semi-diameter>' or the system an 'ENPD <diameter>'")
            self.warnings.append(LoadWarning(
                "assumed_default", f"FLOA without a stop semi-diameter: the stop is sized by the "
                f"{self.aperture[0]} on line {self.aperture[2]}", None, self.floa_line))
        if self.aperture is None:
            raise self.err("no system aperture (ENPD, FNUM, OBNA or FLOA)", None,
                           "add e.g. 'ENPD 10' (entrance pupil diameter in lens units)")
        kind, value, ap_line = self.aperture
        with located(self.path, ap_line):
            return Aperture(kind, value * f if kind == "epd" else value)

    def _system(self, surfaces: list[Surface], obj: _Surf, f: float) -> Lens:
        path, notes = self.path, list(self.notes)
        aperture = self._aperture(surfaces, f)
        # fields
        ftyp = self.ftyp or []
        ftype_code = int(self.num(ftyp[0], "field type", self.ftyp_line)) if ftyp else 0
        if ftype_code not in _FIELD_TYPES:
            raise self.err(f"FTYP {ftype_code}: field type not supported (theodolite angles?)", self.ftyp_line,
                           "use angles, object heights, paraxial or real image heights")
        kind_f = _FIELD_TYPES[ftype_code]
        if len(ftyp) > 1 and ftyp[1] not in ("0",):
            notes.append(("field_normalization", "rectangular in the Zemax file; lensrt normalises radially"))
        yv, yline = self.fields.get("YFLN", ([0.0], None))
        nfld = int(self.num(ftyp[2], "field count", self.ftyp_line)) if len(ftyp) > 2 else len(yv)
        if nfld < 1 or nfld > len(yv):
            raise self.err(f"FTYP says {nfld} fields but YFLN gives {len(yv)}", self.ftyp_line or yline)
        xv = self.fields.get("XFLN", ([0.0] * nfld, None))[0]
        wv = self.fields.get("FWGN", ([1.0] * nfld, None))[0]
        if len(xv) < nfld or len(wv) < nfld:
            raise self.err(f"{nfld} fields but fewer XFLN/FWGN values", yline)
        scale = deg_to_rad(1.0) if kind_f == "angle" else f
        with located(path, yline):
            fields = Fields(kind_f, tuple(v * scale for v in yv[:nfld]), tuple(v * scale for v in xv[:nfld]),
                            tuple(wv[:nfld]))
        notes += _vignetting_notes(self.fields, nfld)
        if "YFLN" not in self.fields:
            notes.append(("fields", "the file gives no field points: on-axis only"))
        # wavelengths (micrometres in the file)
        nwav = int(self.num(ftyp[3], "wavelength count", self.ftyp_line)) if len(ftyp) > 3 else None
        if self.waves:
            idx = sorted(self.waves)
            nwav = nwav if nwav is not None else len(idx)
            missing = [i for i in range(1, nwav + 1) if i not in self.waves]
            if missing:
                raise self.err(f"wavelength {missing[0]} of {nwav} has no WAVM line", self.ftyp_line)
            um = [self.waves[i][0] for i in range(1, nwav + 1)]
            wts = [self.waves[i][1] for i in range(1, nwav + 1)]
            wline = self.waves[1][2]
        elif self.wavl is not None:
            um, wline = self.wavl
            wts = self.wwgt[0] if self.wwgt is not None else [1.0] * len(um)
            if len(wts) != len(um):
                raise self.err(f"WWGT gives {len(wts)} weights for {len(um)} wavelengths", self.wwgt[1])
        else:
            um, wts, wline = [0.55], [1.0], None
            notes.append(("wavelengths", "the file gives no wavelengths: 550 nm (OpticStudio's default)"))
        primary = 0
        if self.pwav is not None:
            primary = self.pwav[0] - 1
            if not 0 <= primary < len(um):
                raise self.err(f"PWAV {self.pwav[0]} is not one of the {len(um)} wavelengths", self.pwav[1])
        with located(path, wline):
            wavelengths = Wavelengths(tuple(round(w * NM_PER_UM, 6) for w in um), tuple(wts), primary)
        if obj.disz is None:
            raise self.err("the object surface (SURF 0) has no DISZ", obj.line, "give 'DISZ INFINITY' or a distance")
        if self.note_text:
            notes.append(("zemax_note", " ".join(self.note_text)[:500]))
        with located(path, obj.line):
            obj_mat = self.material(obj)
        sub = substitution_note(self.subs)
        if sub:
            notes.append(sub)
        if obj.disz <= 0.0:
            raise self.err(f"object distance DISZ {obj.disz:g} must be positive", obj.line,
                           "SURF 0's DISZ is the distance from the object to surface 1 (or INFINITY)")
        found = tuple(self.warnings + self.keywords.warnings)
        emit_load_warnings(path, found, GlassFallbackWarning)
        return make_lens(path, surfaces=tuple(surfaces), aperture=aperture, fields=fields, wavelengths=wavelengths,
                         object_distance_mm=obj.disz * f, object_material=obj_mat, name=self.name,
                         source=f"Zemax file {Path(path).name}" if path else "Zemax file", notes=tuple(notes),
                         warnings=found, image_transform=self.image_transform,
                         image_curvature_per_mm=self.surfs[-1].curv / MM_PER_UNIT[self.unit])


def _norm_name(name: str) -> str:
    return "".join(ch for ch in name.upper() if ch not in " -_.")


def _vignetting_notes(fields: dict[str, tuple[list[float], int | None]], n: int) -> list[tuple[str, str]]:
    """Zemax VDX/VDY/VCX/VCY as CODE V-style VUX/VLX/VUY/VLY (fractions of the pupil radius cut away).

    Zemax maps Py' = VDY + (1 - VCY) Py, so the upper rim moves to 1 - VUY with
    VUY = VCY - VDY and the lower rim to -(1 - VLY) with VLY = VCY + VDY.
    """
    out = []
    for axis in ("X", "Y"):
        vd = fields.get(f"VD{axis}N", ([0.0] * n, None))[0][:n]
        vc = fields.get(f"VC{axis}N", ([0.0] * n, None))[0][:n]
        vd, vc = vd + [0.0] * (n - len(vd)), vc + [0.0] * (n - len(vc))
        if any(vd) or any(vc):
            out.append((f"vignetting_vu{axis.lower()}", fmt_list([c - d for c, d in zip(vc, vd)])))
            out.append((f"vignetting_vl{axis.lower()}", fmt_list([c + d for c, d in zip(vc, vd)])))
    return out


def loads_zmx(text: str, path: str | Path | None = None) -> Lens | MultiConfigLens:
    """Parse ``.zmx`` text (already decoded) into a :class:`Lens` (a :class:`MultiConfigLens`
    for a multi-configuration file, :mod:`lensrt.prescription.formats.zemax_mce`)."""
    spath = str(path) if path is not None else None
    reject_other_format(text, "zemax", spath)
    lines = text.splitlines()
    starts = [i for i, ln in enumerate(lines) if ln.split()[:1] == ["SURF"] or ln.split()[:1] == ["surf"]]
    if not starts:
        raise PrescriptionError("no SURF lines: this is not a Zemax lens file", path=spath,
                                hint="a .zmx file lists its surfaces as 'SURF 0', 'SURF 1', ...")
    last_surf = starts[-1]
    reader = _Reader(spath)
    after = False
    for i, raw in enumerate(lines):
        if not raw.strip():
            continue
        if i > last_surf and not raw[:1].isspace() and raw.split()[0].upper() not in (
                "CURV", "DISZ", "GLAS", "CONI", "PARM", "DIAM", "STOP", "TYPE", "CLAP", "OBSC", "SQAP", "ELAP",
                "OBDC"):
            after = True
        with located(spath, i + 1):
            reader.line(raw, i + 1, after)
    lens = reader.build()
    if reader.mce is None:
        return lens
    return reader.mce.build(lens, MM_PER_UNIT[reader.unit], reader.glass)


def read_zmx(path: str | Path, text: str | None = None) -> Lens | MultiConfigLens:
    """Read a Zemax ``.zmx`` file (UTF-16 with BOM, UTF-8 or ASCII) into a :class:`Lens`.

    Semi-diameters come from ``DIAM`` (or ``CLAP``); surfaces without one are
    left for :func:`lensrt.load_lens` to compute.
    """
    if text is None:
        from . import read_text
        text = read_text(path)
    return loads_zmx(text, path)
