"""Mirrors, coordinate transforms, surface apertures: the model, the readers, ynu, the kernels' refusal.

Oracles: closed forms (a concave mirror's focal length -R/2; a 45 deg fold
sends the axis along -y in lensrt's documented tilt convention), exact
identities (a decenter followed by its inverse is no transform; CODE V's DAR
equals a basic decenter plus REV on the same values; OpticStudio's
coordinate-break/mirror/coordinate-break fold equals CODE V's ADE + BEN), the
float64 reference tracer against the paraxial trace near the axis, and the
rayoptics corpus (loads without tracebacks).
"""
from __future__ import annotations

import importlib.util
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from geometry_cases import cassegrain_system, folded_system, mangin_system, tilted_decentred_system

from lensrt.errors import LensrtError, PrescriptionError
from lensrt.paraxial.first_order import first_order
from lensrt.prescription.formats.codev import loads_seq
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.formats.zemax import loads_zmx
from lensrt.prescription.frames import surface_frames
from lensrt.prescription.geometry import CoordinateTransform, SurfaceAperture
from lensrt.prescription.materials import AIR
from lensrt.prescription.model import Aperture, Fields, Lens, Surface, Wavelengths
from lensrt.trace.pack import S_SD2, pack_arrays
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK, VIGNETTED

ROOT = Path(__file__).resolve().parents[2]


def _frames_close(a: Lens, b: Lens, tol: float = 1e-12) -> bool:
    fa, fb = surface_frames(a)[-1], surface_frames(b)[-1]
    return bool(np.allclose(fa[0], fb[0], atol=tol) and np.allclose(fa[1], fb[1], atol=tol))


def test_transform_and_its_inverse_cancel() -> None:
    t = CoordinateTransform(1.0, -2.0, 0.5, 0.1, -0.2, 0.3, order=0)
    o, a = t.apply(np.zeros(3), np.eye(3))
    o2, a2 = t.inverse().apply(o, a)
    assert np.allclose(o2, 0.0, atol=1e-15) and np.allclose(a2, np.eye(3), atol=1e-15)
    assert CoordinateTransform().is_identity and Surface(transform_before=CoordinateTransform()).transform_before is None


def test_tilt_sign_convention() -> None:
    """alpha > 0 turns +z toward +y, beta > 0 toward -x, gamma > 0 turns +x toward +y (module docstring)."""
    z_alpha = CoordinateTransform(tilt_x_rad=0.1).rotation()[:, 2]
    z_beta = CoordinateTransform(tilt_y_rad=0.1).rotation()[:, 2]
    x_gamma = CoordinateTransform(tilt_z_rad=0.1).rotation()[:, 0]
    assert z_alpha[1] > 0 and z_beta[0] < 0 and x_gamma[1] > 0


def test_fold_mirror_sends_the_axis_down_and_ynu_unfolds_it() -> None:
    lens = folded_system()
    o, a = surface_frames(lens)[-1]
    assert np.allclose(o, [0.0, -55.0, 44.0], atol=1e-12)  # 55 mm along -y from the mirror at z = 44
    assert np.allclose(a[:, 2], [0.0, 1.0, 0.0], atol=1e-15)  # local +z along +y: light travels local -z = -y
    # a real ray parallel to the axis near it crosses the folded axis at the paraxial focus
    fo = first_order(lens)
    ray = trace_reference(lens, (0.0, 1e-4, -1.0), (0.0, 0.0, 1.0), lens.wavelengths.primary_nm)
    assert ray.status == OK
    z_cross = ray.z_mm - ray.y_mm * ray.N / ray.M  # axis crossing along the unfolded axis
    assert z_cross == pytest.approx(fo.rear_focal_z_mm, abs=1e-6)


ZMX_FOLD = """UNIT MM
ENPD 10
FTYP 0 0 1 1 0 0 0
YFLN 0
WAVM 1 0.5875618 1
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  CURV 0.016666666666666666
  DISZ 4
  GLAS N-BK7
SURF 2
  CURV -0.005
  DISZ 40
SURF 3
  TYPE COORDBRK
  PARM 1 0
  PARM 2 0
  PARM 3 45
  PARM 4 0
  PARM 5 0
  PARM 6 0
  DISZ 0
SURF 4
  DISZ 0
  GLAS MIRROR 0 0 1.5 40
SURF 5
  TYPE COORDBRK
  PARM 3 45
  DISZ -55
SURF 6
  DISZ 0
"""

SEQ_FOLD = """RDM Y
DIM M
EPD 10
WL 587.5618
YAN 0
SO 0 1e11
S 60 4 N-BK7_SCHOTT
  STO
S -200 40
S 0 -55 REFL
  ADE 45
  BEN
SI 0 0
GO
"""


def test_zemax_coordinate_breaks_and_codev_bend_place_the_image_alike() -> None:
    zmx, seq = loads_zmx(ZMX_FOLD), loads_seq(SEQ_FOLD)
    assert zmx.surfaces[2].transform_before == CoordinateTransform(tilt_x_rad=math.radians(45.0))
    assert zmx.surfaces[3].mirror and zmx.surfaces[3].material == AIR
    assert seq.surfaces[2].mirror and seq.surfaces[2].transform_after is not None
    assert _frames_close(zmx, seq)
    assert first_order(zmx).efl_mm == pytest.approx(first_order(seq).efl_mm, rel=1e-12)


def test_codev_dar_equals_basic_decenter_then_rev() -> None:
    head = "RDM Y\nEPD 10\nWL 587.6\nYAN 0\nSO 0 1e11\nS 60 4 N-BK7_SCHOTT\n  STO\n"
    dar = loads_seq(head + "S -200 10\n  YDE 2; ADE 5; BDE -3\n  DAR\nS 0 30\nSI 0 0\n")
    rev = loads_seq(head + "S -200 10\n  YDE 2; ADE 5; BDE -3\nS 0 30\n  YDE 2; ADE 5; BDE -3\n  REV\n"
                    "SI 0 0\n")
    # DAR returns after surface 2; basic + REV returns after surface 3, which sits 10 mm along the tilted axis
    o_dar = surface_frames(dar)[2]
    o_rev = surface_frames(rev)[2]
    assert not np.allclose(o_dar[0], o_rev[0])
    assert np.allclose(surface_frames(dar)[1][1], surface_frames(rev)[1][1], atol=1e-15)  # surface 2 tilted alike
    assert np.allclose(surface_frames(rev)[-1][1], np.eye(3), atol=1e-15)  # REV restores the axes
    assert np.allclose(surface_frames(dar)[-1][1], np.eye(3), atol=1e-15)


def test_concave_mirror_focal_length_is_minus_r_over_two() -> None:
    seq = loads_seq("RDM Y\nEPD 20\nWL 550\nYAN 0\nSO 0 1e11\nS -200 -100 REFL\n  STO\nSI 0 0\n")
    fo = first_order(seq)
    assert fo.efl_mm == pytest.approx(100.0, rel=1e-14)
    assert fo.rear_focal_length_mm == pytest.approx(-100.0, rel=1e-14)  # rayoptics' efl: n'/Phi, n' = -1
    assert fo.bfl_mm == pytest.approx(-100.0, rel=1e-14)


@pytest.mark.parametrize("make", [mangin_system, cassegrain_system])
def test_paraxial_focus_of_catadioptric_systems_matches_real_rays(make) -> None:
    lens = make()
    fo = first_order(lens)
    h = 1e-4
    ray = trace_reference(lens, (0.0, h, -1.0), (0.0, 0.0, 1.0), lens.wavelengths.primary_nm, clip=False)
    assert ray.status == OK
    z_cross = ray.z_mm - ray.y_mm * ray.N / ray.M
    assert z_cross == pytest.approx(fo.rear_focal_z_mm, abs=1e-6 * abs(fo.efl_mm))


def test_surface_apertures() -> None:
    ring = SurfaceAperture("annulus", 5.0, 2.0)
    assert ring.passes(3.0, 0.0) and not ring.passes(1.0, 0.0) and not ring.passes(5.5, 0.0)
    rect = SurfaceAperture("rectangle", 2.0, 1.0, decenter_y_mm=3.0)
    assert rect.passes(1.9, 3.9) and not rect.passes(0.0, 0.0)
    ell = SurfaceAperture("ellipse", 2.0, 1.0, rotation_rad=math.pi / 2)
    assert ell.passes(0.0, 1.9) and not ell.passes(1.9, 0.0)
    with pytest.raises(PrescriptionError, match="inner radius"):
        SurfaceAperture("annulus", 1.0, 2.0)


def test_mirror_material_must_be_the_medium_before() -> None:
    from lensrt.prescription.materials import ModelGlass
    with pytest.raises(PrescriptionError, match="a mirror's material"):
        Lens((Surface(0.0, 5.0, ModelGlass(1.5, 60.0), is_stop=True), Surface(0.0, -5.0, AIR, mirror=True)),
             aperture=Aperture("epd", 5.0))


def test_opticstudio_rule_clips_only_user_defined_semi_diameters() -> None:
    base = Lens((Surface(0.0, 5.0, AIR, semi_diameter_mm=1.0, semi_diameter_auto=True),
                 Surface(0.0, 5.0, AIR, semi_diameter_mm=4.0, is_stop=True),
                 Surface(0.0, 5.0, AIR, semi_diameter_mm=1.0, semi_diameter_fixed=True)),
                aperture=Aperture("epd", 8.0))
    ours = base.replace(aperture_rule="opticstudio")
    assert [base.clips_semi_diameter(i) for i in range(3)] == [True, True, True]
    assert [ours.clips_semi_diameter(i) for i in range(3)] == [False, True, True]
    surf, _, _ = pack_arrays(ours)
    assert surf[0, S_SD2] == -1.0 and surf[2, S_SD2] > 0.0
    wl = 587.6
    assert trace_reference(base, (0.0, 2.0, -1.0), (0, 0, 1), wl).status == VIGNETTED
    r = trace_reference(ours, (0.0, 2.0, -1.0), (0, 0, 1), wl)
    assert (r.status, r.surface) == (VIGNETTED, 2)
    assert trace_reference(ours, (0.0, 0.5, -1.0), (0, 0, 1), wl).status == OK


def test_geometry_lenses_pack_with_their_frames() -> None:
    from lensrt.trace.pack import S_APER, S_GEOM, S_SIGN
    surf, _, _ = pack_arrays(cassegrain_system())
    assert np.all(surf[:, S_GEOM] == 1.0) and list(surf[:, S_SIGN]) == [1.0, 1.0, -1.0, 1.0]
    assert surf[0, S_APER] == 1.0  # the obscuration: a circle
    plain, _, _ = pack_arrays(cassegrain_system().replace(surfaces=tuple(
        Surface(s.curvature_per_mm, abs(s.thickness_mm), AIR, is_stop=s.is_stop) for s in cassegrain_system().surfaces)))
    assert np.all(plain[:, S_GEOM] == 0.0)


@pytest.mark.parametrize("make", [folded_system, tilted_decentred_system, mangin_system, cassegrain_system])
def test_native_round_trip_is_exact(make) -> None:
    lens = make().replace(aperture_rule="opticstudio",
                          image_transform=CoordinateTransform(0.25, 0.0, 0.0, math.radians(7.0), 0.0, 0.0, 1))
    lens = lens.replace_surface(0, semi_diameter_mm=6.0, semi_diameter_fixed=True)
    assert loads_native(dumps_native(lens)) == lens


def test_general_tracer_matches_the_centred_one_on_a_plain_lens() -> None:
    from lensrt.library import resolve_lens_path
    from lensrt.loading import load_lens
    from lensrt.trace.reference_general import trace_general
    lens = load_lens(resolve_lens_path("codev_dblgauss_100mm_f2"))
    for y in (0.0, 5.0, 12.0):
        d = (0.0, math.sin(0.2), math.cos(0.2))
        a = trace_reference(lens, (0.0, y, -10.0), d, 587.6)
        b = trace_general(lens, (0.0, y, -10.0), d, 587.6)
        assert (a.status, a.surface) == (b.status, b.surface)
        assert abs(a.x_mm - b.x_mm) + abs(a.y_mm - b.y_mm) + abs(a.opl_mm - b.opl_mm) < 1e-9


def _corpus_script():
    spec = importlib.util.spec_from_file_location("corpus_load_count", ROOT / "benchmarks" / "corpus_load_count.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


def test_rayoptics_corpus_loads_without_tracebacks(capsys) -> None:
    pytest.importorskip("rayoptics")
    mod = _corpus_script()
    assert len(mod.corpus_files()) == 41
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert mod.main([]) == 0
    out = capsys.readouterr().out
    loaded = int(out.rsplit("loaded ", 1)[1].split(",")[0])
    assert loaded >= 33 and "tracebacks 0" in out


def _threemir() -> Lens:
    ro = pytest.importorskip("rayoptics")
    from lensrt.loading import load_lens
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_lens(Path(ro.__file__).parent / "codev" / "tests" / "threemir.seq")


def _spot(lens: Lens) -> np.ndarray:
    from lensrt.trace.aiming import aim_rays, field_point
    px, py = np.array([0.0, 0.3, -0.3, 0.0, 0.0]), np.array([0.0, 0.0, 0.0, 0.3, -0.3])
    o, d, ok = aim_rays(lens, field_point(lens, 0.0, 0.0), px, py, 500.0, "real")
    assert ok.all()
    rays = [trace_reference(lens, o[k], d[k], 500.0, clip=False) for k in range(len(px))]
    assert all(r.status == OK for r in rays)
    return np.array([[r.x_mm, r.y_mm] for r in rays])


def test_codev_off_axis_three_mirror_telescope_focuses_on_its_tilted_image() -> None:
    """threemir.seq (rayoptics' corpus): three mirrors decentred and tilted with DAR, the image surface
    decentred and tilted. Designed to image the axial field at the image origin: it does (a few um) with
    lensrt's tilt convention, and is 0.3 m off with the tilt signs flipped -- the sign convention's evidence."""
    from dataclasses import replace
    lens = _threemir()
    spot = _spot(lens)
    assert np.max(np.abs(spot)) < 2e-3
    flip = lambda t: None if t is None else replace(t, tilt_x_rad=-t.tilt_x_rad, tilt_y_rad=-t.tilt_y_rad)  # noqa: E731
    flipped = lens.replace(surfaces=tuple(replace(s, transform_before=flip(s.transform_before),
                                                  transform_after=flip(s.transform_after)) for s in lens.surfaces),
                           image_transform=flip(lens.image_transform))
    assert np.max(np.abs(_spot(flipped))) > 100.0


def test_afocal_lens_reports_angular_magnification() -> None:
    """A Keplerian telescope f1 = 100, f2 = 20 (thin-ish, same glass): u'/u = -f1/f2 = -5 paraxially."""
    from lensrt.prescription.materials import ConstantIndex
    g = ConstantIndex(1.5)
    c1, c2 = 2 / 100.0, 2 / 20.0  # zero-thickness planoconvex: Phi = c (n - 1) = 1 / f
    lens = Lens((Surface(c1, 0.0, g, is_stop=True), Surface(0.0, 120.0, AIR),
                 Surface(c2, 0.0, g), Surface(0.0, 10.0, AIR)),
                aperture=Aperture("epd", 10.0), fields=Fields("angle", (0.0, 0.01)), wavelengths=Wavelengths((550.0,)))
    fo = first_order(lens)
    assert fo.afocal and math.isinf(fo.efl_mm)
    assert fo.angular_magnification == pytest.approx(-5.0, rel=1e-12)
    assert fo.exit_pupil_diameter_mm == pytest.approx(2.0, rel=1e-12)  # D / |M|
    from lensrt.views.first_order import info_data
    d = info_data(lens)
    assert d["afocal"] and d["angular_magnification"] == fo.angular_magnification and d["seidel"] is None
    with pytest.raises(LensrtError, match="afocal"):
        info_data(lens, sensor="full-frame")


def test_zemax_clap_with_infinite_outer_radius_is_a_central_obscuration() -> None:
    """optiland exports a mirror's central hole as ``CLAP r INF``: everything outside r passes."""
    lens = loads_zmx(ZMX_FOLD.replace("  GLAS MIRROR 0 0 1.5 40\n", "  GLAS MIRROR 0 0 1.5 40\n  CLAP 2 INF\n"))
    assert lens.surfaces[3].apertures == (SurfaceAperture("circle", 2.0, obscuration=True),)
    with pytest.raises(PrescriptionError, match="blocks every ray"):
        loads_zmx(ZMX_FOLD.replace("  GLAS MIRROR 0 0 1.5 40\n", "  GLAS MIRROR 0 0 1.5 40\n  OBSC 0 INF\n"))
