"""Fuzzed lens files: every mutant either loads into a valid, NaN-free lens or raises LensrtError.

The four reference files (Zemax, CODE V, pbrt, native) are mutated with a fixed
``numpy.random.Generator`` seed: lines deleted, duplicated, swapped, truncated or
replaced by garbage; tokens replaced by other numbers (0, negative, huge, nan,
inf), words or nothing, or scaled. Any other exception type, or a lens with a
NaN anywhere, fails the test and names the mutation.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from lensrt.errors import LensrtError
from lensrt.loading import load_lens
from lensrt.prescription.model import Lens

ROOT = Path(__file__).resolve().parents[1]
SOURCES = [ROOT / "data" / "cooke_triplet.zmx", ROOT / "data" / "ag_dblgauss.seq", ROOT / "data" / "dgauss.50mm.dat",
           ROOT.parent / "lens_prescriptions" / "codev_dblgauss_100mm_f2.toml",
           # the glass and keyword syntax of issues 22/25: PRV, '&', n:v and six-digit glasses, DOR/UID,
           # F_SILICA, ___BLANK, GCAT of unshipped catalogs, FLOA, newer OpticStudio keywords
           ROOT / "data" / "glass_syntax.seq", ROOT / "data" / "glass_syntax.zmx",
           # mirrors, tilts/decenters and apertures (issue 17): COORDBRK, MIRROR, OBSC, SQAP, ELAP, OBDC;
           # REFL, ADE/BDE/YDE, DAR, BEN, CIR OBS, REX/REY/ADY
           ROOT / "data" / "folded_obscured.zmx", ROOT / "data" / "folded_tilted.seq",
           # the reader gaps of issue 17: CUF, solves (CUY UMY, PIM), a long glass code; SCBD on the image
           ROOT / "data" / "readers_keywords.seq", ROOT / "data" / "readers_keywords.zmx",
           # the ideal paraxial lens (issue 22): TYPE PARAXIAL with PARM 1 (focal length) and PARM 2 (OPD mode)
           ROOT / "data" / "kepler_paraxial_eyepiece.zmx",
           # surface types (issue 22): ODDASPHE, QED_TYPE (Qbfs, Qcon), XASPHERE, XOSPHERE, BICONICX, TOROIDAL,
           # XPOLYNOM, SZERNSAG
           ROOT / "data" / "shape_types.zmx",
           # zoom and focus (issue 18): MNUM/THIC/APER/YFIE/WAVE/LTTL rows, ZOO/POS, [[configuration]] and [focus]
           ROOT / "data" / "cooke_triplet_mce.zmx", ROOT / "data" / "ag_dblgauss_zoom.seq",
           ROOT.parent / "lens_prescriptions" / "fujinon_xf_90mm_f2_inner_focus.toml",
           # CODE V special surfaces (issue 22): SPS ODD / XYP / QBF with SCO and SCC
           ROOT / "data" / "special_surfaces.seq",
           # the long tail (issue 25): FZERNSAG, SCBD on a lens surface, a dummy inside a mirror's sag, a glass
           # name marked uncertain (SF12?); ZOO YDE/YDC and ZOO VUY/VLY
           ROOT / "data" / "fringe_telescope.zmx", ROOT / "data" / "zoom_decenter.seq"]
VARIANTS_PER_FILE = 60
SEED = 20260521
TOKENS = ["0", "-1", "1e308", "-1e308", "nan", "inf", "-inf", "1e-320", "0.5", "-37.5", "3", "x", "", "STOP", "[[",
          '"', "=", "GLAS", "N-BK7", "1.2.3", "#", ";", "SURF", "&", "1e10", "PRV", "END", "PWL", "1.55:55.8",
          "517642", "0:0", "F_SILICA", "GERMANIUM", "IWDP", "FLOA", "___BLANK", "'MYBK7'", "SK1", "GCAT",
          "MIRROR", "REFL", "DAR", "BEN", "REV", "OBS", "COORDBRK", "90", "-45", "CUF", "PIM", "UMY", "HMY",
          "UCY", "SCBD", "517000.520000", "PARAXIAL",
          "ODDASPHE", "QED_TYPE", "XASPHERE", "XOSPHERE", "BICONICX", "TOROIDAL", "XPOLYNOM", "SZERNSAG", "XDAT",
          "PARM", "67", "2", "MNUM", "THIC", "ZOO", "POS", "TIT", "[[configuration]]", "thickness_mm", "floating",
          "FZERNSAG", "SF12?", "YDE", "YDC", "VUY", "37", "38"]


def _mutate(lines: list[str], rng: np.random.Generator) -> tuple[list[str], str]:
    out = list(lines)
    i = int(rng.integers(len(out)))
    kind = int(rng.integers(7))
    if kind == 0:
        del out[i]
        return out, f"delete line {i + 1}"
    if kind == 1:
        out.insert(i, out[i])
        return out, f"duplicate line {i + 1}"
    if kind == 2:
        j = int(rng.integers(len(out)))
        out[i], out[j] = out[j], out[i]
        return out, f"swap lines {i + 1} and {j + 1}"
    if kind == 3:
        cut = int(rng.integers(1, len(out) + 1))
        return out[:cut], f"truncate after line {cut}"
    if kind == 4:
        junk = "".join(chr(int(c)) for c in rng.integers(33, 127, int(rng.integers(1, 30))))
        out[i] = junk
        return out, f"line {i + 1} -> {junk!r}"
    toks = out[i].split(" ")
    k = int(rng.integers(len(toks)))
    old = toks[k]
    if kind == 5:
        toks[k] = TOKENS[int(rng.integers(len(TOKENS)))]
    else:
        try:
            toks[k] = repr(float(old) * float(rng.choice([-1.0, 0.0, 0.1, 10.0, 1e6, -3.0])))
        except ValueError:
            toks[k] = old[::-1]
    out[i] = " ".join(toks)
    return out, f"line {i + 1}: token {old!r} -> {toks[k]!r}"


def _floats(lens: Lens) -> list[float]:
    vals = [lens.object_distance_mm, lens.aperture.value, lens.iris.rotation_rad]
    vals += list(lens.fields.y) + list(lens.fields.x) + list(lens.fields.weights)
    vals += list(lens.wavelengths.nm) + list(lens.wavelengths.weights)
    for s in lens.surfaces:
        vals += [s.curvature_per_mm, s.thickness_mm, s.conic, s.semi_diameter_mm, *s.asphere]
        vals += [] if s.ideal_focal_mm is None else [s.ideal_focal_mm]
    vals += [float(v) for v in np.ravel(lens.indices(np.array(lens.wavelengths.nm)))]
    return vals


def _check_valid(lens: Lens, what: str) -> None:
    assert isinstance(lens, Lens), what
    vals = _floats(lens)
    assert all(v is not None for v in vals), f"{what}: a missing value in a loaded lens"
    assert not any(math.isnan(v) for v in vals), f"{what}: NaN in the loaded lens"
    assert all(math.isfinite(v) for v in vals[1:]), f"{what}: an infinite value besides the object distance"
    assert all(s.semi_diameter_mm > 0 for s in lens.surfaces), what


@pytest.mark.parametrize("source", SOURCES, ids=lambda p: p.name)
def test_mutants_load_or_fail_cleanly(source: Path, tmp_path: Path) -> None:
    rng = np.random.default_rng([SEED, SOURCES.index(source)])
    lines = source.read_text(encoding="utf-8").splitlines()
    loaded = failed = 0
    for n in range(VARIANTS_PER_FILE):
        mutant, what = _mutate(lines, rng)
        if rng.random() < 0.3:  # a second mutation now and then
            mutant, what2 = _mutate(mutant or [""], rng)
            what = f"{what}; {what2}"
        path = tmp_path / f"v{n}" / source.name
        path.parent.mkdir()
        path.write_text("\n".join(mutant) + "\n", encoding="utf-8")
        label = f"{source.name} variant {n} ({what})"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                lens = load_lens(path)
        except LensrtError as err:
            msg = str(err)
            assert msg and "\n" not in msg, label
            assert str(path) in msg or msg.startswith("no lens file"), f"{label}: no file name in {msg!r}"
            failed += 1
            continue
        except Exception as err:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{label}: {type(err).__name__}: {err}")
        _check_valid(lens, label)
        loaded += 1
    # the mutations must exercise both outcomes
    assert loaded > 0 and failed > 0, (loaded, failed)


def test_variant_count() -> None:
    assert VARIANTS_PER_FILE * len(SOURCES) >= 200
