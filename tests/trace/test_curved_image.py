"""Spherical image surfaces (``Lens.image_curvature_per_mm``): readers, the float64 reference, the kernels, optiland.

optiland's two samples with a curved image surface -- the Hubble telescope (R = -635 mm behind two mirrors) and
Navarro's wide-angle schematic eye (the retina, R = -12 mm) -- exported by optiland to ``.zmx`` load, and rays
traced from optiland's own ray state at surface 1 end on the curved image where optiland's rays end (1e-9 mm;
both tracers given optiland's refractive indices, so this compares the ray tracing). The generic kernel (general
variant) meets the curved image as the reference tracer does (1e-12 mm in float64). First-order data stay y-nu.
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from trace_cases import library_lens

from lensrt.errors import PrescriptionError
from lensrt.loading import load_lens
from lensrt.paraxial.first_order import first_order
from lensrt.prescription.formats.codev import loads_seq
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.materials import ConstantIndex
from lensrt.trace import trace
from lensrt.trace.api import RayBatch
from lensrt.trace.reference import trace_reference
from lensrt.trace.status import OK

CURVED = ("HubbleTelescope", "NavarroWideAngleEye")


def _optiland_sample(name: str):
    optiland = pytest.importorskip("optiland")
    import importlib
    import pkgutil
    import optiland.samples as samples
    for info in pkgutil.iter_modules(samples.__path__):
        mod = importlib.import_module(f"optiland.samples.{info.name}")
        if hasattr(mod, name) and getattr(mod, name).__module__ == mod.__name__:
            return getattr(mod, name)()
    raise AssertionError(f"optiland {optiland.__version__} has no sample {name}")


@pytest.mark.parametrize("name", CURVED)
def test_optiland_curved_image_samples_match_optiland_rays(name: str, tmp_path: Path) -> None:
    import optiland.backend as be
    from optiland.fileio import save_zemax_file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op = _optiland_sample(name)
        save_zemax_file(op, str(tmp_path / f"{name}.zmx"))
        lens = load_lens(tmp_path / f"{name}.zmx")
    sg = op.surface_group
    assert lens.image_curvature_per_mm == pytest.approx(1.0 / float(be.to_numpy(sg.surfaces[-1].geometry.radius)),
                                                        rel=1e-15)
    wl_um = float(op.primary_wavelength)
    # optiland's indices (its samples use non-dispersive materials; the exported n_d/V_d model glass disperses)
    n_op = [float(np.ravel(be.to_numpy(s.material_post.n(wl_um)))[0]) for s in sg.surfaces]
    surfs = tuple(s if s.material.is_air or s.mirror else dataclasses.replace(s, material=ConstantIndex(n_op[i + 1]))
                  for i, s in enumerate(lens.surfaces))
    lens = lens.replace(surfaces=surfs)
    assert np.allclose(lens.indices(wl_um * 1000.0), n_op[:lens.n_surfaces + 1], rtol=0, atol=1e-15)
    vertex_z = np.ravel(be.to_numpy(sg.positions))
    g = np.linspace(-1.0, 1.0, 5)
    px, py = (a.ravel() for a in np.meshgrid(g, g))
    inside = px * px + py * py <= 1.0
    worst, n_rays = 0.0, 0
    for hy in (0.0, 0.7, 1.0):
        op.trace_generic(0.0, hy, px[inside], py[inside], wl_um)
        x, y, z = (be.to_numpy(a) for a in (sg.x, sg.y, sg.z))
        L, M, N = (be.to_numpy(a) for a in (sg.L, sg.M, sg.N))
        for j in range(x.shape[1]):
            d = (float(L[0, j]), float(M[0, j]), float(N[0, j]))
            start = (x[1, j] - d[0], y[1, j] - d[1], z[1, j] - vertex_z[1] - d[2])  # 1 mm before surface 1
            ref = trace_reference(lens, start, d, wl_um * 1000.0, clip=False)
            assert ref.status == OK
            hit = ref.hits[-1]
            # the image point in the image's vertex frame: x, y, and the sag of the curved surface
            worst = max(worst, abs(hit.x_mm - x[-1, j]), abs(hit.y_mm - y[-1, j]),
                        abs(hit.z_mm - (z[-1, j] - vertex_z[-1])))
            c = lens.image_curvature_per_mm
            r2 = hit.x_mm ** 2 + hit.y_mm ** 2
            assert hit.z_mm == pytest.approx(c * r2 / (1 + math.sqrt(1 - c * c * r2)), abs=1e-9)
            n_rays += 1
    assert n_rays == 39 and worst < 1e-9


def _curved_triplet(radius_mm: float):
    return library_lens("cooke_triplet_50mm_f5").replace(image_curvature_per_mm=1.0 / radius_mm)


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_kernel_meets_the_curved_image_as_the_reference(precision: str, device: str, tmp_path: Path) -> None:
    """The generic kernel (general variant: a curved image packs the lens as general) against the reference
    tracer, on a refractive lens with a concave (R = -60 mm) image and on the Hubble telescope (mirrors)."""
    from test_trace_kernels import FLOAT32_BOUND_MM
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from optiland.fileio import save_zemax_file
        save_zemax_file(_optiland_sample("HubbleTelescope"), str(tmp_path / "h.zmx"))
        hubble = load_lens(tmp_path / "h.zmx")
    for lens, half, z0 in ((_curved_triplet(-60.0), 5.0, -5.0), (hubble, 1100.0, -10.0)):
        rng = np.random.default_rng(7)
        xy = rng.uniform(-half, half, (40, 2))
        d = np.column_stack([rng.uniform(-0.004, 0.004, (40, 2)) if half > 100 else rng.uniform(-0.3, 0.3, (40, 2)),
                             np.ones(40)])
        d /= np.linalg.norm(d, axis=1)[:, None]
        o = np.column_stack([xy, np.full(40, z0)])
        res = trace(lens, RayBatch(o, d, np.full(40, 550.0)), precision, device, kernel="generic", clip=False,
                    record=True)
        bound = 1e-12 if precision == "float64" else FLOAT32_BOUND_MM * (1.0 if half < 100 else 100.0)
        ok = 0
        for k in range(40):
            ref = trace_reference(lens, tuple(o[k]), tuple(d[k]), 550.0, clip=False)
            assert (res.status[k], res.surface[k]) == (ref.status, ref.surface)
            if ref.status != OK:
                continue
            ok += 1
            hits = np.array([[h.x_mm, h.y_mm, h.z_mm, h.L, h.M, h.N] for h in ref.hits])
            scale = max(1.0, float(np.max(np.abs(hits[:, :3]))) / 1000.0)
            assert np.max(np.abs(res.records[k, :, :6] - hits)) < bound * scale
            assert abs(ref.hits[-1].z_mm) > 0.0  # the image point lies off the vertex plane: the sphere was met
        assert ok >= 20


def test_first_order_does_not_depend_on_the_image_curvature() -> None:
    flat = library_lens("cooke_triplet_50mm_f5")
    curved = _curved_triplet(-60.0)
    a, b = first_order(flat), first_order(curved)
    assert (a.efl_mm, a.bfl_mm, a.f_number) == (b.efl_mm, b.bfl_mm, b.f_number)


SEQ = "RDM\nEPD 10\nYAN 0 10\nWL 587.6\nSO 0 1e11\nS 50 5 1.5168:64.17\n  STO\nS -50 45\nSI {si}\nGO\n"


def test_readers_and_round_trip() -> None:
    lens = loads_seq(SEQ.format(si="-80 0"), "c.seq")
    assert lens.image_curvature_per_mm == -1.0 / 80.0
    assert loads_seq(SEQ.format(si="0 0"), "c.seq").image_curvature_per_mm == 0.0
    back = loads_native(dumps_native(lens))
    assert back.image_curvature_per_mm == lens.image_curvature_per_mm
    text = dumps_native(lens).replace(f"image_curvature_per_mm = {lens.image_curvature_per_mm!r}",
                                      "image_radius_mm = -80.0")
    assert loads_native(text).image_curvature_per_mm == -1.0 / 80.0
    flat = dumps_native(loads_seq(SEQ.format(si="0 0"), "c.seq"))
    assert "image_" not in flat.split("[aperture]")[0]  # a plane image writes nothing


@pytest.mark.parametrize("text,needle", [
    (dumps_native(loads_seq(SEQ.format(si="-80 0"), "c.seq")).replace("image_curvature_per_mm", "image_radius_mm = 5\n"
                                                                        "image_curvature_per_mm"), "both image_radius"),
    (dumps_native(loads_seq(SEQ.format(si="0 0"), "c.seq")).replace("[system]", "[system]\nimage_radius_mm = 'x'"),
     "image_radius_mm must be a number"),
])
def test_bad_image_curvature_is_one_error(text: str, needle: str) -> None:
    with pytest.raises(PrescriptionError, match=needle) as err:
        loads_native(text, "bad.toml")
    assert "\n" not in str(err.value)


ZMX = """VERS 1 0 0
MODE SEQ
UNIT MM X W X CM MR CPMM
ENPD 10
FTYP 0 0 1 1 0 0 0
YFLN 0
XFLN 0
WAVM 1 0.5876 1
SURF 0
  DISZ INFINITY
SURF 1
  STOP
  CURV 0.02
  DISZ 5
  GLAS ___BLANK 1 0 1.5168 64.17 0 0 0 0 0 0
SURF 2
  CURV -0.02
  DISZ 45
SURF 3
{image}"""


def test_zemax_image_curvature_and_aspheric_image_refused() -> None:
    from lensrt.prescription.formats.zemax import loads_zmx
    assert loads_zmx(ZMX.format(image="  CURV -0.0125\n"), "ok.zmx").image_curvature_per_mm == -0.0125
    assert loads_zmx(ZMX.format(image=""), "ok.zmx").image_curvature_per_mm == 0.0
    with pytest.raises(PrescriptionError, match="curved image surface .*plane or a sphere") as err:
        loads_zmx(ZMX.format(image="  CURV -0.01\n  CONI -1\n"), "bad.zmx")
    assert str(err.value).startswith("bad.zmx:") and "\n" not in str(err.value)
    with pytest.raises(PrescriptionError, match="curved object surface"):
        loads_zmx(ZMX.format(image="").replace("SURF 0\n", "SURF 0\n  CURV 0.01\n"), "bad.zmx")


def test_specialised_kernel_and_image_side_tracing_refuse_a_curved_image(device: str) -> None:
    from lensrt.errors import LensrtError
    from lensrt.trace import reversed_lens
    lens = _curved_triplet(-60.0)
    o, d = np.array([[0.0, 1.0, -5.0]]), np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(LensrtError, match="no specialised kernel"):
        trace(lens, RayBatch(o, d, np.full(1, 550.0)), "float32", device, kernel="specialised")
    assert trace(lens, RayBatch(o, d, np.full(1, 550.0)), "float32", device, kernel="auto").kernel == "generic"
    with pytest.raises(LensrtError, match="curved image surface"):
        reversed_lens(lens)
