"""CODE V ``RET Sk`` (return to surface k's coordinate system).

The oracle is the meaning of the command, checked two independent ways:

* geometry: the surface that carries ``RET Sk`` lies exactly in surface k's
  frame (:func:`~lensrt.prescription.frames.surface_frames`, which composes
  the stored transforms -- not the reader's inverse computation);
* rays: a detour of decentred, tilted dummy planes (same medium, so no ray
  bends there) followed by ``RET Sk`` must trace exactly like the file
  without the detour, whose returning surface sits right after surface k
  (float64 reference tracer, image intercepts to 1e-9 mm). The returning
  surface lies behind the detour, so the trace also runs a negative transfer,
  as CODE V does.
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from lensrt.errors import PrescriptionError
from lensrt.prescription.formats.codev import loads_seq
from lensrt.prescription.frames import surface_frames
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

TOL_MM = 1e-9
WL = 587.56

HEAD = """RDM
TITLE 'coordinate return'
EPD 10
DIM M
WL 587.56
YAN 0 3
SO 0 1e10
S 50 5 1.5168:64.2
  STO
S -50 10
"""
TAIL = """S 60 4 1.5168:64.2
S -60 40
SI 0 0
"""
#: surface 3 is a plane dummy (the return target); 4 and 5 a decentred, tilted detour; 6 returns to 3
DETOUR_TO_DUMMY = """S 0 0
S 0 12
  XDE 0.7; YDE -1.2; ZDE 0.5; ADE 4; BDE -3; CDE 20
S 0 3
S 0 30
  RET S3
"""
#: surface 3 carries a basic decenter (kept by every later surface); 4 is a dummy detour; 5 returns to 3
DETOUR_TO_TILTED = """S 0 7
  XDE -0.4; YDE 0.9; ADE -2.5; BDE 1.5; CDE -12
S 0 -4
  YDE 3; ADE 30; DAR
S 0 25
  RET S3
"""


def _load(text: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return loads_seq(text)


def _image_points(lens) -> np.ndarray:
    """Image-plane intercepts (local x, y) of a fan of skew rays across the 10 mm beam, two field angles."""
    out = []
    for tan_y in (0.0, 0.05):
        for x, y in ((0.0, 0.0), (3.0, -2.0), (-4.0, 1.0), (0.5, 4.5), (-2.0, -4.0)):
            r = trace_reference(lens, (x, y, -10.0), (0.01, tan_y, 1.0), WL, clip=False)
            assert r.status == OK
            out.append((r.x_mm, r.y_mm))
    return np.array(out)


@pytest.mark.parametrize("detour,k,j", [(DETOUR_TO_DUMMY, 3, 6), (DETOUR_TO_TILTED, 3, 5)])
def test_return_puts_the_surface_in_surface_k_frame(detour: str, k: int, j: int) -> None:
    lens = _load(HEAD + detour + TAIL)
    frames = surface_frames(lens)
    (o_j, a_j), (o_k, a_k) = frames[j - 1], frames[k - 1]
    np.testing.assert_allclose(o_j, o_k, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a_j, a_k, rtol=0, atol=1e-12)
    # the returning surface's thickness runs along surface k's z axis
    np.testing.assert_allclose(frames[j][0], o_k + a_k[:, 2] * lens.surfaces[j - 1].thickness_mm, rtol=0, atol=1e-12)
    assert lens.surfaces[j - 1].transform_before is not None


@pytest.mark.parametrize("detour,short", [
    (DETOUR_TO_DUMMY, "S 0 0\nS 0 30\n"),
    (DETOUR_TO_TILTED, "S 0 0\n  XDE -0.4; YDE 0.9; ADE -2.5; BDE 1.5; CDE -12\nS 0 25\n"),
])
def test_return_traces_like_the_file_without_the_detour(detour: str, short: str) -> None:
    with_ret, without = _load(HEAD + detour + TAIL), _load(HEAD + short + TAIL)
    assert with_ret.n_surfaces == without.n_surfaces + (2 if detour is DETOUR_TO_DUMMY else 1)
    fa, fb = surface_frames(with_ret)[-1], surface_frames(without)[-1]
    np.testing.assert_allclose(fa[0], fb[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fa[1], fb[1], rtol=0, atol=1e-12)
    pa, pb = _image_points(with_ret), _image_points(without)
    assert np.abs(pa - pb).max() < TOL_MM
    # the detour really moves things: the returning surface without RET lands elsewhere
    moved = _load(HEAD + detour.replace("  RET S3\n", "") + TAIL)
    assert np.abs(_image_points(moved) - pb).max() > 1e-3


def test_return_round_trips_through_native_toml() -> None:
    from lensrt.prescription.formats.native import dumps_native, loads_native
    lens = _load(HEAD + DETOUR_TO_TILTED + TAIL)
    again = loads_native(dumps_native(lens))
    for s, t in zip(lens.surfaces, again.surfaces):
        assert (s.transform_before is None) == (t.transform_before is None)
        if s.transform_before is not None:  # tilts go through degrees in the file: 1 ulp
            assert dataclasses.astuple(t.transform_before) == pytest.approx(dataclasses.astuple(s.transform_before),
                                                                            rel=1e-14, abs=1e-15)
    np.testing.assert_allclose(_image_points(again), _image_points(lens), rtol=0, atol=TOL_MM)


@pytest.mark.parametrize("edit,needle", [
    (("  RET S3", "  RET S7"), "surface 7 is not an earlier S surface"),
    (("  RET S3", "  RET S6"), "surface 6 is not an earlier S surface"),
    (("  RET S3", "  RET"), "cannot read RET"),
    (("  RET S3", "  RET 3"), "cannot read RET"),
    (("  RET S3", "  RET SI"), "cannot read RET"),
    (("  RET S3", "  RET SO"), "cannot read RET"),
    (("  RET S3", "  RET S-1"), "cannot read RET"),
    (("  RET S3", "  RET S2.5"), "cannot read RET"),
    (("  RET S3", "  RET S2 S3"), "cannot read RET"),
    (("  RET S3", "  RET S0"), "surface 0 is not an earlier S surface"),
    (("  RET S3", "  RET S99999999999999999999"), "is not an earlier S surface"),
    (("  RET S3", "  RET S3; XDE 1"), "RET S3 and a decenter on one surface"),
    (("  RET S3", "  RET S3; DAR"), "RET S3 and a decenter on one surface"),
    (("SI 0 0", "SI 0 0\nRET S2"), "RET on the image surface"),
    (("SO 0 1e10", "SO 0 1e10\nRET S1"), "RET on the object surface"),
    (("EPD 10", "EPD 10\nZOO 2\nZOO THI S2 10 12"), "RET in a zoom file"),
])
def test_bad_returns_get_one_clear_error(edit: tuple[str, str], needle: str) -> None:
    text = (HEAD + DETOUR_TO_DUMMY + TAIL).replace(*edit, 1)
    with pytest.raises(PrescriptionError, match=needle) as info:
        _load(text)
    assert info.value.line is not None
