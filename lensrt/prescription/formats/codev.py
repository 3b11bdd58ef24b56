"""CODE V sequence (``.seq``) reader: the sequential, rotationally symmetric subset.

Commands (case-insensitive, ``;`` separates commands on one line, ``!``
starts a comment, ``&`` continues a line):

* lens data: ``SO``, ``S``, ``SI`` (curvature or radius per ``RDM``, thickness,
  glass), ``STO``, ``CIR`` (a clear semi-diameter; ``CIR EDG`` is a mechanical
  edge and ignored), ``ASP``/``CON``/``SPH`` with ``K`` and ``A`` .. ``J``
  (r^4, r^6, ... r^20 -> ``Surface.asphere[1]``, ``[2]``, ...), ``SLB``
  (label), ``RDY``/``CUY``/``THI``/``GLA`` on the current surface;
* specification: ``RDM``, ``DIM`` (M, C, I), ``EPD``/``FNO``/``NAO``, ``WL``
  (nm), ``REF``, ``WTW``, ``XAN``/``YAN``, ``XOB``/``YOB``, ``XIM``/``YIM``,
  ``XRI``/``YRI``, ``WTF``, ``VUX``/``VLX``/``VUY``/``VLY`` (kept in
  ``lens.notes`` as ``vignetting_vuy`` ... for the tracer), ``TITLE``;
* zoom data: ``ZOO``, ``POS`` (:mod:`lensrt.prescription.formats.codev_zoom`);
* paraxial solves ``PIM``, ``CUY UMY|UCY``, ``THI HMY|HCY``: applied at load
  time (:mod:`.codev_solves`); ``CUF 0`` (written in every ASP block) is read,
  a non-zero ``CUF`` (a Fresnel surface) is an error;
* ignored on purpose: ``LEN``, ``INI``, ``CCY``/``THC``/``GLC`` (variable
  codes), other solves and pickups (the value on the S line is the
  solved one and is kept), ``DER``, ``VAL``, ``POL``, ``GO`` (end), and the
  non-optical commands of :data:`~lensrt.prescription.formats.keywords.CODEV_NON_OPTICAL`
  (``DOR``, ``UID``, ...).

A thickness on ``SI`` is a defocus of the image surface from where the last
thickness puts it; it is added to the last surface's thickness. A radius (curvature)
on ``SI`` makes the image surface a sphere (``Lens.image_curvature_per_mm``). An object
thickness of 1e10 or more is infinite (CODE V's rule). Glass names may carry
a catalog suffix (``NSK16_SCHOTT``) and are looked up as
:mod:`lensrt.prescription.glass_lookup` says; fictitious glasses (``1.55:55.8``,
``517642``, ``517.642``) and ``PRV`` private catalogs are read
(:mod:`~lensrt.prescription.formats.codev_glass`). Without ``RDM`` the S lines
hold curvatures, without ``STO`` the stop is surface 1, a vignetting list
shorter than the fields is padded with 0 -- each an ``assumed_default``
warning. Commands lensrt does not know are ignored with a ``keyword_unknown``
warning.

Mirrors (``REFL``), decenters and tilts (``XDE`` .. ``CDE``, ``DAR``, ``REV``,
``BEN``) and apertures (``CIR ... OBS/HOL``, ``REX``/``REY``, ``ELX``/``ELY``,
``ADX``/``ADY``/``ARO``) and coordinate returns (``RET Sk``) are read by
:mod:`.codev_geometry`. Diffractive surfaces and the special surface types other than ``SPS ODD``,
``XYP`` and ``QBF`` (read by :mod:`.codev_shapes`) are errors naming the file, the line and the command.
"""
from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

from ...errors import PrescriptionError, located
from ...units import MM_PER_UNIT, deg_to_rad
from ..configurations import MultiConfigLens
from ..glass_lookup import GlassRequest, resolve_glass
from ..materials import AIR, Material
from ..model import Aperture, Fields, Lens, LoadWarning, Surface, Wavelengths
from ._common import emit_load_warnings, fmt_list, make_lens, parse_number, reject_other_format, substitution_note
from .codev_glass import PrivateCatalog, fictitious_glass
from .codev_shapes import special_coefficients, special_shape, special_surface
from .codev_solves import SOLVE_KINDS, apply_solves
from .codev_zoom import ZoomReader
from .keywords import CODEV_NON_OPTICAL, KeywordPolicy
from .codev_geometry import (GEOMETRY_COMMANDS, apply_coordinate_returns, geometry_command, image_transform,
                             new_row_geometry, row_geometry)

__all__ = ["read_seq", "loads_seq", "tokenize_seq", "UNSUPPORTED", "IGNORED"]

#: object thicknesses at or above this are infinite (CODE V)
INFINITE_THICKNESS = 1.0e10

IGNORED = {
    "LEN": "lens start", "INI": "designer initials", "CCY": "variable code", "THC": "variable code",
    "GLC": "variable code", "DER": "derivative increments",
    "VAL": "constraint value", "POL": "polarisation switch", "PIK": "pickup (picked value kept)",
    "PUX": "solve (solved value kept)", "PUY": "solve (solved value kept)", "PUI": "solve (solved value kept)",
    "PUC": "solve (solved value kept)", "PCY": "solve (solved value kept)", "PCX": "solve (solved value kept)",
    "EDG": "edge thickness solve (solved value kept)", "UMY": "solve (solved value kept)",
    "UCY": "solve (solved value kept)", "IMY": "solve (solved value kept)", "ICY": "solve (solved value kept)",
    "CA": "clear aperture mode", "WID": "wide-angle flag", "SPH": "spherical profile",
    "CLS": "wavelength colour labels (display)", "CUM": "mirror substrate curvature (drawing only)",
    "THM": "mirror substrate thickness (drawing only)",
}
UNSUPPORTED = {
    "XOD": "an offset decenter", "YOD": "an offset decenter",
    "ZOD": "an offset decenter", "REFL": "a mirror", "RMD": "a mirror/TIR mode", "DIF": "a diffractive surface",
    "HOE": "a holographic element", "GRT": "a grating", "HWL": "a diffractive surface", "HOR": "a diffractive surface",
    "HCT": "a diffractive surface", "HCO": "a diffractive surface", "DOE": "a diffractive surface",
    "XTO": "a toroidal surface", "YTO": "a toroidal surface", "AAS": "an anamorphic asphere",
    "CYL": "a cylinder", "ZRN": "a Zernike surface", "ZFR": "a Zernike surface",
    "XYP": "an XY polynomial surface", "UDS": "a user-defined surface", "CUX": "a toroidal curvature",
    "RDX": "a toroidal radius", "CIG": "a general aperture",
    "REG": "a general aperture", "ELG": "a general aperture",
    "INS": "a surface insertion", "DEL": "a surface deletion", "NSS": "a non-sequential surface",
    "NSO": "a non-sequential object",
    "NA": "an image-space NA aperture", "NAI": "an image-space NA aperture", "IMD": "image distance control",
    "KC": "a conic variable code",
}
_ASPH_LETTERS = "ABCDEFGHJ"  # r^4 ... r^20 (CODE V skips I)
_DIM = {"M": "mm", "MM": "mm", "C": "cm", "CM": "cm", "I": "in", "IN": "in"}
_FIELD_KEYS = {"AN": "angle", "OB": "object_height", "IM": "paraxial_image_height", "RI": "real_image_height"}
_KNOWN = set(IGNORED) | set(UNSUPPORTED) | GEOMETRY_COMMANDS | {
    "ZOO", "POS", "RDM", "TIT", "DIM", "EPD", "FNO", "NAO", "REF", "WTW", "WTF", "TEM", "PRE", "STO", "CIR", "ASP", "CON", "SLB",
    "RDY", "CUY", "THI", "GLA", "CUF", "PIM", "VUX", "VLX", "VUY", "VLY", "XAN", "YAN", "XOB", "YOB", "XIM", "YIM", "XRI", "YRI", "SPS", "SCO", "SCC"}


def tokenize_seq(text: str) -> list[tuple[int, list[str]]]:
    """Commands of a ``.seq`` text as (1-based line, tokens); quotes kept as one token."""
    out: list[tuple[int, list[str]]] = []
    pending: list[str] = []
    pending_line = 0
    for no, raw in enumerate(text.splitlines(), start=1):
        tokens: list[str] = []
        cmd_start = pending_line if pending else no
        cur, quote = "", ""
        cont = False
        for ch in raw:
            if quote:
                cur += ch
                if ch == quote:
                    quote = ""
                continue
            if ch in "'\"":
                quote = ch
                cur += ch
            elif ch == "!":
                break
            elif ch.isspace() or ch == ",":
                if cur:
                    tokens.append(cur)
                cur = ""
            elif ch == ";":
                if cur:
                    tokens.append(cur)
                cur = ""
                if pending or tokens:
                    out.append((cmd_start, pending + tokens))
                pending, tokens, cmd_start = [], [], no
            else:
                cur += ch
        if cur:
            tokens.append(cur)
        if tokens and tokens[-1].endswith("&"):  # '650.0&' continues as well as '650.0 &'
            tokens[-1] = tokens[-1][:-1]
            if not tokens[-1]:
                tokens.pop()
            cont = True
        if cont:
            pending, pending_line = pending + tokens, cmd_start
            continue
        if pending or tokens:
            out.append((cmd_start, pending + tokens))
        pending = []
    if pending:
        out.append((pending_line, pending))
    return out


class _Seq:
    def __init__(self, path: str | None) -> None:
        self.path = path
        self.radius_mode = False   # CODE V reads curvatures until RDM (see the docs' glass page)
        self.rdm_given = False
        self.dim = "mm"
        self.warnings: list[LoadWarning] = []
        self.keywords = KeywordPolicy("CODE V", dict(CODEV_NON_OPTICAL))
        self.prv: PrivateCatalog | None = None
        self.private: dict[str, Material] = {}
        self.rows: list[dict] = []          # SO, S..., SI as dicts
        self.spec: dict[str, tuple[list[str], int]] = {}
        self.title = ""
        self.notes: list[tuple[str, str]] = []
        self.subs: dict[str, str] = {}
        self.zoom = ZoomReader(path)  # ZOO / POS data (codev_zoom)

    def err(self, msg: str, line: int | None, hint: str | None = None) -> PrescriptionError:
        return PrescriptionError(msg, path=self.path, line=line, hint=hint)

    def num(self, tok: str, what: str, line: int) -> float:
        return parse_number(tok, what, path=self.path, line=line)

    def cur(self, cmd: str, line: int) -> dict:
        if not self.rows or self.rows[-1]["kind"] == "SI":
            raise self.err(f"{cmd} without a surface (it must follow SO or an S line)", line)
        return self.rows[-1]

    def surface_row(self, kind: str, toks: list[str], line: int) -> None:
        if kind != "SO" and not self.rows:
            raise self.err(f"{kind} before SO", line, "a sequence starts with 'SO 0 <object distance>'")
        if kind == "SO" and self.rows:
            raise self.err("a second SO", line)
        if self.rows and self.rows[-1]["kind"] == "SI":
            raise self.err(f"{kind} after SI", line, "SI is the image surface and comes last")
        if len(toks) < 2:
            raise self.err(f"{kind} needs a {'radius' if self.radius_mode else 'curvature'} and a thickness",
                           line)
        v = self.num(toks[0], "radius" if self.radius_mode else "curvature", line)
        curv = (0.0 if v == 0.0 else 1.0 / v) if self.radius_mode else v
        thick = parse_number(toks[1], "thickness", path=self.path, line=line, allow_inf=kind == "SO")
        glass, mirror = None, False
        if len(toks) > 2:
            glass = toks[2]
            if glass.upper() == "REFL":
                if kind != "S":
                    raise self.err(f"{kind} ... REFL: the object and image surfaces cannot be mirrors", line)
                glass, mirror = None, True
        if len(toks) > 3:
            raise self.err(f"unexpected {' '.join(toks[3:])!r} after the glass of {kind}", line)
        self.rows.append(dict(kind=kind, line=line, curv=curv, thick=thick, glass=glass, stop=False, sd=None,
                              conic=0.0, asph={}, label="", **new_row_geometry()))
        self.rows[-1]["mirror"] = mirror

    def command(self, line: int, toks: list[str]) -> bool:
        """Apply one command; returns False at GO."""
        name = toks[0].upper()
        args = toks[1:]
        if self.prv is not None:
            if not self.prv.command(toks, line):
                self.private.update(self.prv.glasses())
                self.prv = None
            return True
        if name == "PRV":
            self.prv = PrivateCatalog(self.path)
            return True
        if len(name) > 3 and name not in ("TITLE",) and name[:3] in _KNOWN:
            name = name[:3]  # CODE V reads the first three letters: STOP = STO
        if name in ("SO", "S", "SI"):
            self.surface_row("S" if name not in ("SO", "SI") else name, args, line)
            return True
        if name == "GO":
            return False
        if name == "RDM":
            self.radius_mode = not (args and args[0].upper().startswith("N"))
            self.rdm_given = True
            return True
        if name == "TIT" and self.zoom.title(args, line):
            return True
        if name in ("TIT", "TITLE"):
            self.title = " ".join(a.strip("'\"") for a in args)
            return True
        if name == "DIM":
            if not args or args[0].upper() not in _DIM:
                raise self.err(f"unknown DIM {' '.join(args)!r}", line, "use DIM M, C or I")
            self.dim = _DIM[args[0].upper()]
            return True
        if name in ("EPD", "FNO", "NAO", "WL", "REF", "WTW", "WTF", "TEM", "PRE") or \
                name[:1] in "XY" and name[1:] in _FIELD_KEYS or name in ("VUX", "VLX", "VUY", "VLY"):
            self.spec[name] = (args, line)
            return True
        if name == "STO":
            self.cur(name, line)["stop"] = True
            return True
        if geometry_command(self, name, args, line):
            return True
        if name in ("CIR", "SLB") and self.rows and self.rows[-1]["kind"] == "SI":
            return True  # the image surface's size and label do not change the optics
        if name == "CIR":
            row = self.cur(name, line)
            quals = [a.upper() for a in args if not _looks_number(a) and not a.upper().startswith("L'")]
            vals = [a for a in args if _looks_number(a)]
            if "EDG" in quals:
                return True  # mechanical edge aperture: no effect on the rays
            if any(q in ("HOL", "OBS") for q in quals) and vals:
                row["cir_obs"].append(self.num(vals[0], "obscuration radius", line))
                return True
            if not vals or any(q not in ("CLR",) for q in quals):
                raise self.err(f"cannot read CIR {' '.join(args)}", line, "use 'CIR <semi-diameter>'")
            row["sd"] = self.num(vals[0], "semi-diameter", line)
            return True
        if name in ("ASP", "CON"):
            self.cur(name, line)
            return True
        if name == "CUF":
            self.fresnel_curvature(args, line)
            return True
        if name == "K":
            self.cur(name, line)["conic"] = self.num(args[0], "conic constant", line)
            return True
        if len(name) == 1 and name in _ASPH_LETTERS:
            row = self.cur(name, line)
            row["asph"][_ASPH_LETTERS.index(name) + 1] = self.num(args[0], f"aspheric coefficient {name}", line)
            return True
        if name == "SLB":
            self.cur(name, line)["label"] = " ".join(a.strip("'\"") for a in args)
            return True
        if name == "PIM" or name in ("CUY", "THI") and args and args[0].upper() in SOLVE_KINDS:
            self.solve(name, args, line)
            return True
        if name in ("RDY", "CUY", "THI", "GLA"):
            if args and re.match(r"^S(\d+|O|I)$", args[0], re.IGNORECASE):
                raise self.err(f"{name} {args[0]}: commands that change another surface are not supported", line,
                               "write the value on that surface's S line")
            row = self.cur(name, line)
            if name == "THI":
                row["thick"] = self.num(args[0], "thickness", line)
            elif name == "GLA":
                row["glass"] = args[0]
            else:
                v = self.num(args[0], name, line)
                row["curv"] = v if name == "CUY" else (0.0 if v == 0.0 else 1.0 / v)
            return True
        if name in ("ZOO", "POS"):
            self.zoom.command(name, args, line)
            return True
        if name in ("SPS", "SCO", "SCC"):
            self.special(name, args, line)
            return True
        if name in UNSUPPORTED:
            raise self.err(f"{name}: {UNSUPPORTED[name]} is not supported", line,
                           "lensrt models rotationally symmetric, sequential, refractive lenses only")
        if name in IGNORED:
            return True
        if not re.match(r"^[A-Z][A-Z0-9]*$", name):
            raise self.err(f"cannot read {toks[0]!r}: not a command", line,
                           "a CODE V command starts with letters; a number belongs on the line before (& continues)")
        self.keywords.unread(toks[0], line)
        return True

    def solve(self, name: str, args: list[str], line: int) -> None:
        """Record ``PIM``, ``CUY UMY|UCY u`` or ``THI HMY|HCY h`` on the current surface (:mod:`.codev_solves`)."""
        if name == "PIM" and len(self.rows) > 1 and self.rows[-1]["kind"] == "SI":
            row = self.rows[-2]  # PIM after the lens data: the image solve on the last surface
        else:
            row = self.cur(name, line)
        kind = "PIM" if name == "PIM" else args[0].upper()
        if (name == "CUY") != (SOLVE_KINDS[kind][0] == "curvature"):
            raise self.err(f"{name} {kind}: a {SOLVE_KINDS[kind][0]} solve given as a {name.lower()} command", line,
                           "curvature solves are CUY UMY/UCY, thickness solves THI HMY/HCY or PIM")
        if kind == "PIM":
            value = 0.0
        elif len(args) < 2:
            raise self.err(f"{name} {kind} without a value", line, f"write e.g. '{name} {kind} 0'")
        else:
            value = self.num(args[1], f"{kind} solve value", line)
        row.setdefault("solves", []).append((kind, value, line))

    def special(self, name: str, args: list[str], line: int) -> None:
        """``SPS type [n]``, ``SCO name value ...`` and ``SCC`` (variable codes, ignored) on the current surface
        (:mod:`.codev_shapes`)."""
        row = self.cur(name, line)
        if row["kind"] != "S":
            raise self.err(f"{name} on the {'object' if row['kind'] == 'SO' else 'image'} surface", line,
                           "lensrt's object and image surfaces carry no special surface type")
        if name == "SPS":
            if row.get("sps") is not None:
                raise self.err(f"a second SPS on the surface of line {row['line']}", line, "one special type a surface")
            row["sps"] = special_surface(args, line, self.path)
        elif name == "SCO":
            special_coefficients(row.get("sps"), args, line, self.path)

    def fresnel_curvature(self, args: list[str], line: int) -> None:
        """``CUF c``: CODE V writes ``CUF 0`` in every ASP block it saves; 0 (no Fresnel base curvature) is a
        no-op, any other value is a Fresnel surface and an error."""
        self.cur("CUF", line)
        if not args:
            raise self.err("CUF without a value", line, "write 'CUF 0' or leave the command out")
        value = self.num(args[0], "CUF (Fresnel base curvature)", line)
        if value != 0.0:
            raise self.err(f"CUF {args[0]}: a Fresnel surface (a non-zero Fresnel base curvature) is not supported",
                           line, "lensrt traces the ASP profile as a real surface; CUF 0 (the default) reads")

    # -- assembly -----------------------------------------------------------
    def material(self, glass: str | None, line: int, surface: int | None = None) -> Material:
        """The medium named on an S line: air, a fictitious glass, a private or catalog glass."""
        if glass is None or glass.upper() == "AIR":
            return AIR
        with located(self.path, line):
            model = fictitious_glass(glass)
        if model is not None:
            self.warnings.append(LoadWarning("glass_model", f"fictitious glass {glass}: model glass n_d = "
                                             f"{model.nd:g}, V_d = {model.vd:g}", surface, line))
            return model
        name = glass.strip("'\"")
        req = GlassRequest(name, None, None, None, surface, line, self.primary_nm(), self.private)
        with located(self.path, line):
            found, warns = resolve_glass(req)
        self.warnings += warns
        base = re.sub(r"[_:][A-Za-z]+$", "", name) if "_" in name or ":" in name else name
        if found.name.replace("-", "").upper() != base.replace("-", "").upper() and name.upper() not in self.private:
            self.subs[name] = found.describe()
        return found

    def primary_nm(self) -> float:
        """The reference wavelength (nm) as far as the file has given it."""
        try:
            wl = [float(a) for a in self.spec.get("WL", ([], 0))[0]]
            ref = int(float(self.spec["REF"][0][0])) - 1 if "REF" in self.spec else len(wl) // 2
            return wl[ref] if 0 <= ref < len(wl) else 587.5618
        except (ValueError, IndexError):
            return 587.5618

    def build(self) -> Lens:
        f = MM_PER_UNIT[self.dim]
        if not self.rows:
            raise self.err("no SO/S/SI lines: this is not a CODE V lens sequence", None,
                           "a sequence lists 'SO', then one 'S' per surface, then 'SI'")
        obj = self.rows[0]
        body = [r for r in self.rows[1:] if r["kind"] == "S"]
        img = self.rows[-1] if self.rows[-1]["kind"] == "SI" else None
        if not body:
            raise self.err("the sequence has no S surfaces", obj["line"])
        if obj["curv"] != 0.0:
            raise self.err("curved object surface (SO)", obj["line"], "lensrt's object surface is a plane")
        if obj["stop"]:
            raise self.err("the object surface (SO) is marked STO", obj["line"])
        defocus = 0.0
        self.image_curvature = 0.0  # a spherical image surface: the SI radius
        if img is not None:
            if img["conic"] != 0.0 or img["asph"] or img.get("sps") is not None:
                raise self.err("aspheric image surface (SI)", img["line"], "lensrt's image surface is a plane or a "
                               "sphere (the SI radius)")
            self.image_curvature = img["curv"] / f
            defocus = img["thick"]
        self.assumed_defaults(body)
        surfaces: list[Surface] = []
        before = self.material(obj["glass"], obj["line"])
        for k, r in enumerate(body):
            with located(self.path, r["line"]):
                n = max(r["asph"]) if r["asph"] else 0
                asph = tuple(r["asph"].get(i, 0.0) * f ** (-1 - 2 * i) for i in range(0, n + 1)) if n else ()
                thick = r["thick"] + (defocus if k == len(body) - 1 else 0.0)
                geometry = row_geometry(r, f, self.path)
                shape, conic, asph = special_shape(r.get("sps"), r["conic"], asph, f, self.path)
                surfaces.append(Surface(
                    curvature_per_mm=r["curv"] / f, thickness_mm=thick * f,
                    material=before if r["mirror"] else self.material(r["glass"], r["line"], k), **geometry,
                    semi_diameter_mm=None if r["sd"] is None else r["sd"] * f, conic=conic, asphere=asph,
                    shape=shape, is_stop=r["stop"], label=r["label"], line=r["line"]))
                before = surfaces[-1].material
        surfaces = apply_coordinate_returns(surfaces, body, self.path, zoom=self.zoom.count is not None)
        self.image_transform = image_transform(img, f)
        if defocus:
            self.notes.append(("image_defocus_mm", f"{defocus * f:.12g} (SI thickness, added to the last "
                                                   "surface's thickness)"))
        return self.system(surfaces, obj, f)

    def assumed_defaults(self, body: list[dict]) -> None:
        """CODE V's defaults for what the file leaves out: curvature mode without RDM, the stop on S1."""
        if not self.rdm_given:
            self.warnings.append(LoadWarning("assumed_default", "no RDM command: the S lines' first values are "
                                             "read as curvatures (CODE V's default; RDM switches to radii)", None,
                                             None))
        if not any(r["stop"] for r in self.rows):
            body[0]["stop"] = True
            self.warnings.append(LoadWarning("assumed_default", "no STO command: the stop is surface 1 "
                                             "(CODE V's default)", 0, body[0]["line"]))

    def vignetting(self, n: int) -> None:
        """VUX/VLX/VUY/VLY into lens.notes; a list shorter than the fields is padded with 0 (CODE V's default)."""
        for key in ("VUX", "VLX", "VUY", "VLY"):
            v = self.values(key, "vignetting factor")
            if v is None or not any(v[0]):
                continue
            vals, line = v
            if len(vals) != n:
                self.warnings.append(LoadWarning(
                    "assumed_default", f"{key} gives {len(vals)} values for {n} fields: "
                    + ("the rest are 0 (no vignetting)" if len(vals) < n else f"values after the {n}th ignored"),
                    None, line))
                vals = (vals + [0.0] * n)[:n]
            if any(vals):
                self.notes.append((f"vignetting_{key.lower()}", fmt_list(vals)))

    def solved(self, surfaces: list[Surface], dist: float, obj_mat: Material, aperture: Aperture, fields: Fields,
               wavelengths: Wavelengths, f: float) -> list[Surface]:
        """The surfaces with the file's paraxial solves applied (:mod:`.codev_solves`); zoom files keep the
        values CODE V wrote for each position."""
        body = [r for r in self.rows[1:] if r["kind"] == "S"]
        solves = {k: r["solves"] for k, r in enumerate(body) if r.get("solves")}
        if not solves:
            return surfaces
        kept = "a zoom file" if self.zoom.count is not None else "a lens with decenters or tilts" if any(
            s.transform_before is not None or s.transform_after is not None for s in surfaces) or \
            self.image_transform is not None else None
        if kept:
            self.warnings.append(LoadWarning("keyword_ignored", f"paraxial solves in {kept}: the values the file "
                                             "writes are used (not re-solved)", None, None))
            return surfaces
        ref = wavelengths.nm[wavelengths.primary]
        stop = next(k for k, s in enumerate(surfaces) if s.is_stop)
        img = self.rows[-1] if self.rows[-1]["kind"] == "SI" else None
        out, found = apply_solves(
            surfaces, solves, stop=stop, object_distance_mm=dist, object_index=float(obj_mat.index(ref)),
            indices=[float(s.material.index(ref)) for s in surfaces], aperture=aperture, fields=fields,
            unit_mm=f, defocus_mm=(img["thick"] * f if img is not None else 0.0), path=self.path)
        self.warnings += found
        return out

    def values(self, key: str, what: str) -> tuple[list[float], int] | None:
        if key not in self.spec:
            return None
        args, line = self.spec[key]
        return [self.num(a, what, line) for a in args], line

    def system(self, surfaces: list[Surface], obj: dict, f: float) -> Lens:
        path = self.path
        aps = [k for k in ("EPD", "FNO", "NAO") if k in self.spec]
        if not aps:
            raise self.err("no system aperture (EPD, FNO or NAO)", None, "add e.g. 'EPD 25'")
        if len(aps) > 1:
            raise self.err(f"two system apertures ({' and '.join(aps)})", self.spec[aps[1]][1], "keep one")
        vals, ap_line = self.values(aps[0], "aperture value")  # type: ignore[misc]
        kind = {"EPD": "epd", "FNO": "image_fno", "NAO": "object_na"}[aps[0]]
        with located(path, ap_line):
            if not vals:
                raise self.err(f"{aps[0]} without a value", ap_line)
            aperture = Aperture(kind, vals[0] * f if kind == "epd" else vals[0])
        # fields
        kinds = sorted({k[1:] for k in self.spec if k[:1] in "XY" and k[1:] in _FIELD_KEYS})
        if len(kinds) > 1:
            raise self.err(f"two field definitions ({', '.join(kinds)})", self.spec["Y" + kinds[1]][1]
                           if "Y" + kinds[1] in self.spec else None, "keep one of XAN/YAN, XOB/YOB, XIM/YIM, XRI/YRI")
        if kinds:
            fk = _FIELD_KEYS[kinds[0]]
            ys = self.values("Y" + kinds[0], "field value") or ([0.0], None)
            n = len(ys[0])
            xs = self.values("X" + kinds[0], "field value") or ([0.0] * n, ys[1])
            if len(xs[0]) != n:
                raise self.err(f"X{kinds[0]} gives {len(xs[0])} values, Y{kinds[0]} {n}", xs[1])
            scale = deg_to_rad(1.0) if fk == "angle" else f
            wtf = self.values("WTF", "field weight") or ([1.0] * n, None)
            if len(wtf[0]) != n:
                raise self.err(f"WTF gives {len(wtf[0])} weights for {n} fields", wtf[1])
            with located(path, ys[1]):
                fields = Fields(fk, tuple(v * scale for v in ys[0]), tuple(v * scale for v in xs[0]), tuple(wtf[0]))
        else:
            fields = Fields()
            n = 1
            self.notes.append(("fields", "the file gives no field points: on-axis only"))
        self.vignetting(n)
        # wavelengths
        wl = self.values("WL", "wavelength")
        if wl is None:
            raise self.err("no wavelengths (WL)", None, "add e.g. 'WL 656.3 587.6 486.1'")
        nm, wl_line = wl
        wtw = self.values("WTW", "wavelength weight") or ([1.0] * len(nm), None)
        if len(wtw[0]) != len(nm):
            raise self.err(f"WTW gives {len(wtw[0])} weights for {len(nm)} wavelengths", wtw[1])
        ref = self.values("REF", "reference wavelength")
        if ref is not None and len(ref[0]) != 1:
            raise self.err(f"REF needs one wavelength number, not {len(ref[0])}", ref[1], "e.g. REF 2")
        primary = int(ref[0][0]) - 1 if ref else len(nm) // 2
        if ref is None and len(nm) > 1:
            self.warnings.append(LoadWarning(
                "assumed_default", f"no REF command: the reference wavelength is the middle one, {nm[primary]:g} nm "
                "(CODE V's default is not documented in any source lensrt found; rayoptics takes the first)",
                None, wl_line))
        if not 0 <= primary < len(nm):
            raise self.err(f"REF {primary + 1} is not one of the {len(nm)} wavelengths", ref[1] if ref else None)
        with located(path, wl_line):
            wavelengths = Wavelengths(tuple(nm), tuple(wtw[0]), primary)
        for key, default, unit in (("TEM", 20.0, "C"), ("PRE", 1.0, "atm")):
            v = self.values(key, key)
            if v is not None and v[0] and v[0][0] != default:
                msg = (f"{key} {v[0][0]:g} {unit}: lensrt uses catalog indices at 20 C and 1 atm "
                       "(thermal and pressure index changes are not modelled)")
                warnings.warn(f"{path}:{v[1]}: {msg}", UserWarning, stacklevel=3)
                self.notes.append(("environment", msg))
        dist = obj["thick"]
        dist = math.inf if dist >= INFINITE_THICKNESS else dist * f
        obj_mat = self.material(obj["glass"], obj["line"])
        sub = substitution_note(self.subs)
        if sub:
            self.notes.append(sub)
        if dist <= 0.0:
            raise self.err(f"object distance {dist:g} must be positive", obj["line"],
                           "SO's thickness is the distance from the object to surface 1")
        if self.prv is not None:
            raise self.err("PRV without END", None, "close the private catalog with END")
        surfaces = self.solved(surfaces, dist, obj_mat, aperture, fields, wavelengths, f)
        found = tuple(self.warnings + self.keywords.warnings)
        emit_load_warnings(path, found)
        return make_lens(path, surfaces=tuple(surfaces), aperture=aperture, fields=fields, wavelengths=wavelengths,
                         object_distance_mm=dist, object_material=obj_mat,
                         name=self.title, source=f"CODE V sequence {Path(path).name}" if path else "CODE V sequence",
                         notes=tuple(self.notes), warnings=found, image_transform=self.image_transform,
                         image_curvature_per_mm=self.image_curvature)


def _looks_number(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


def loads_seq(text: str, path: str | Path | None = None) -> Lens | MultiConfigLens:
    """Parse CODE V sequence text into a :class:`Lens` (a :class:`MultiConfigLens` for zoom data,
    :mod:`lensrt.prescription.formats.codev_zoom`)."""
    spath = str(path) if path is not None else None
    reject_other_format(text, "codev", spath)
    seq = _Seq(spath)
    for line, toks in tokenize_seq(text):
        with located(spath, line):
            if not seq.command(line, toks):
                break
    return seq.zoom.build(seq.build(), MM_PER_UNIT[seq.dim], seq.material,
                          [r.get("dtype", "basic") for r in seq.rows if r["kind"] == "S"])


def read_seq(path: str | Path, text: str | None = None) -> Lens | MultiConfigLens:
    """Read a CODE V ``.seq`` file into a :class:`Lens`."""
    if text is None:
        from . import read_text
        text = read_text(path)
    return loads_seq(text, path)
