"""PSFs and MTFs on real rays: Airy pattern of an aberration-free lens, defocus discs, wavefront signs, maps.

The aberration-free lens: a plano-convex singlet with the flat side toward a
collimated beam and a conic back surface. Inside the glass the axial beam is
still plane; a single refracting surface sends a plane wave in index n1 to a
perfect point in index n2 when it is the conic with k = -(n1/n2)^2 (a
Cartesian oval whose object point is at infinity): here glass -> air,
k = -n^2, a hyperboloid, with paraxial radius R = -(n - 1) f (focal length f
behind the back vertex, which is the rear principal plane). Its axial OPD is
zero to rounding, so its PSF is the Airy pattern and its MTF the
diffraction MTF, at the working f-number 1/(2 NA) of the real marginal ray.
The same singlet with a spherical back surface (k = 0) is the control: 1.6
waves of spherical aberration at f/8, which the same tests must reject.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from lensrt.analysis.psf import otf as mtf
from lensrt.analysis.psf.energy import encircled_energy
from lensrt.analysis.fields import FieldSpec, chief_height_table, sensor_grid_fields
from lensrt.analysis.psf.setup import make_setup
from lensrt.prescription.materials import ConstantIndex
from lensrt.prescription.model import Aperture, Fields, Iris, Lens, Surface, Wavelengths

N_GLASS, F_MM, F_NUMBER, WL = 1.5, 50.0, 8.0, 550.0
SEMI = F_MM / F_NUMBER / 2.0
AXIS = FieldSpec(0.0, 0.0, "axis")


def singlet(conic: float = -N_GLASS**2, blades: int = 0, field_deg: float = 1.0) -> Lens:
    """The plano-convex singlet of the module docstring (stop on the flat front face)."""
    s = (Surface(thickness_mm=5.0, material=ConstantIndex(N_GLASS), semi_diameter_mm=SEMI, is_stop=True),
         Surface(curvature_per_mm=-1.0 / ((N_GLASS - 1.0) * F_MM), conic=conic, thickness_mm=F_MM,
                 semi_diameter_mm=SEMI * 1.2))
    return Lens(s, aperture=Aperture("float_by_stop", 0.0), fields=Fields("angle", (0.0, math.radians(field_deg))),
                wavelengths=Wavelengths((WL,)), iris=Iris(blades=blades))


def marginal_working_f_number(lens: Lens) -> float:
    """1 / (2 NA) from the real marginal ray, traced on its own (not through the PSF code)."""
    from lensrt.trace import RayBatch, trace
    r = trace(lens, RayBatch([[0.0, SEMI * (1 - 1e-9), 0.0]], [[0.0, 0.0, 1.0]], WL), "float64", "cpu")
    assert r.ok[0]
    return 0.5 / math.hypot(r.direction[0, 0], r.direction[0, 1])


@pytest.fixture(scope="module")
def airy():
    from lensrt.analysis.psf.diffraction import diffraction_psf_at
    lens = singlet()
    freqs = np.linspace(0.0, 1.0 / (WL * 1e-6 * 8.0), 80)
    setup = make_setup(lens, focus="paraxial", device="cpu", method="diffraction", pixels=512,
                       mtf_curve_cpmm=tuple(freqs))
    return lens, diffraction_psf_at(setup, AXIS, "cpu")


def test_aberration_free_singlet_gives_the_airy_pattern(airy):
    lens, r = airy
    n_w = marginal_working_f_number(lens)
    assert r.kind == "diffraction-fft"
    assert r.metadata["opd_pv_waves"] < 1e-6
    assert abs(r.metadata["working_f_number"] / n_w - 1) < 5e-3
    lam_n = WL * 1e-6 * n_w
    rep = r.metadata["sampling"][0]
    assert rep["image_sampling_ok"] and rep["pupil_sampling_ok"]
    # pitch lambda N / Q with the grid's N = 1 / (2 NA_grid), NA_grid 2 % beyond the real pupil
    n_grid = r.metadata["grid_working_f_number"]
    assert math.isclose(r.grid.pitch_um, rep["pitch_um"]) and math.isclose(r.grid.pitch_um, WL * 1e-3 * n_grid / 4)
    assert 0.97 < n_grid / n_w < 0.99
    # first dark ring along the row and the column through the reference point: within one grid step
    n = r.grid.shape[0]
    row, col = n - 1 - n // 2, n // 2
    r0 = 1.2196698912665045 * lam_n
    for profile, coords in ((r.psf[row, col:], r.grid.x_mm[col:] - r.reference_mm[0]),
                            (r.psf[row::-1, col], r.grid.y_mm[row::-1] - r.reference_mm[1])):
        window = (coords > 0.7 * r0) & (coords < 1.3 * r0)
        zero = coords[window][np.argmin(profile[window])]
        assert abs(zero - r0) <= r.grid.pitch_mm
    # encircled energy at the first zero: 83.8 %
    ee = encircled_energy(r.psf, r.grid, r0, r.reference_mm, points=True)
    assert abs(ee - 0.8378) < 0.005
    # the PSF itself against the Airy formula, relative to the peak
    x, y = r.grid.mesh_mm()
    ref = mtf.airy_psf(np.hypot(x - r.reference_mm[0], y - r.reference_mm[1]), WL, n_w)
    assert np.max(np.abs(r.psf - ref)) < 0.01 * ref.max()


def test_aberration_free_singlet_has_the_diffraction_mtf(airy):
    lens, r = airy
    n_w = marginal_working_f_number(lens)
    f = np.asarray(r.metadata["mtf_curve_freqs_cpmm"])
    assert f[-1] > 0.99 * mtf.diffraction_cutoff_cpmm(WL, n_w)
    for key in ("mtf_curve_sagittal", "mtf_curve_tangential"):
        assert np.max(np.abs(r.estimates[key].value - mtf.diffraction_mtf(f, WL, n_w))) < 0.01
    ref = np.asarray(r.metadata["mtf_freqs_cpmm"])
    assert np.allclose(r.estimates["mtf_sagittal"].value, mtf.diffraction_mtf(ref, WL, n_w), atol=0.01)


def test_spherical_control_is_not_diffraction_limited():
    from lensrt.analysis.psf.diffraction import diffraction_psf_at
    lens = singlet(conic=0.0)
    f = np.linspace(0.0, 200.0, 21)
    setup = make_setup(lens, focus="paraxial", device="cpu", method="diffraction", mtf_curve_cpmm=tuple(f))
    r = diffraction_psf_at(setup, AXIS, "cpu")
    assert 1.0 < r.metadata["opd_pv_waves"] < 3.0
    n_w = marginal_working_f_number(lens)
    assert np.max(np.abs(r.estimates["mtf_curve_sagittal"].value - mtf.diffraction_mtf(f, WL, n_w))) > 0.3


def test_wavefront_of_a_defocused_perfect_lens_is_the_defocus_term():
    # observed dz behind the focus, the OPD (sign: pupil.py) is dz (cos(theta) - 1), exactly the term
    # PupilFunction.with_defocus adds: OPD sign and the reference sphere in one check
    from lensrt.analysis.wave.pupil_grid import defocus_opd_mm
    from lensrt.analysis.wave.wavefront import trace_wavefronts
    from lensrt.trace.aiming import field_point
    from lensrt.trace.stream import pupil_box
    lens = singlet()
    dz = 0.05
    fp = field_point(lens, 0.0, 0.0)
    assert lens.image_z_mm == 5.0 + F_MM  # the file's image surface is the focus
    wf = trace_wavefronts(lens, fp, pupil_box(lens, fp, [WL], device="cpu"), [WL], lens.image_z_mm + dz, 64, WL,
                          "cpu")[0]
    ok = wf.valid
    expect = defocus_opd_mm(wf.px[ok], wf.py[ok], wf.na, dz)
    assert np.max(np.abs(expect)) > 0.1 * WL * 1e-6  # a real test: a tenth of a wave and more
    assert np.max(np.abs(wf.opd_mm[ok] - expect)) < 1e-3 * WL * 1e-6


def _defocus_rms_exact(lens: Lens, dz: float, blades: int = 0) -> float:
    """RMS spot radius of the perfect singlet observed dz behind its focus, by quadrature.

    A ray entering at height h leaves the back surface at (h, z_s(h)) toward the focus F and crosses
    z = F + dz at -h dz / (F - z_s(h)); uniform flux over the entrance pupil (circle or iris polygon).
    """
    back = lens.surfaces[1]
    z_back = lens.surfaces[0].thickness_mm
    focus = z_back + F_MM

    def x_of(h: np.ndarray) -> np.ndarray:
        return h * dz / (focus - (z_back + back.sag(h)))

    if blades == 0:
        num = quad(lambda h: x_of(np.array([h]))[0] ** 2 * h, 0.0, SEMI, epsabs=0, epsrel=1e-12)[0]
        return math.sqrt(num / (0.5 * SEMI**2))
    # polygon inscribed in the stop circle, a vertex on +x: integrate r^2 over each sector in polar form
    sector = 2 * math.pi / blades
    num = den = 0.0
    for phi in np.linspace(0.0, sector, 2001)[:-1] + 0.5 * sector / 2000:
        edge = SEMI * math.cos(sector / 2) / math.cos(phi - sector / 2)
        num += quad(lambda h: x_of(np.array([h]))[0] ** 2 * h, 0.0, edge, epsrel=1e-10)[0]
        den += 0.5 * edge**2
    return math.sqrt(num / den)


@pytest.mark.parametrize("sampler,blades", [("random", 0), ("stratified", 0), ("sobol", 6)])
def test_defocus_disc_rms_matches_the_closed_form_within_its_standard_error(sampler, blades):
    from lensrt.analysis.psf.geometric import geometric_psf_at
    lens = singlet(blades=blades)
    dz = 0.5
    setup = make_setup(lens, focus=f"paraxial+{dz}", device="cpu", rays=1 << 16, sampler=sampler, pixels=64)
    r = geometric_psf_at(setup, AXIS, seed=11, device="cpu")
    rms = r.estimates["rms_radius_mm"]
    exact = _defocus_rms_exact(lens, dz, blades)
    assert abs(rms.value - exact) < 4 * rms.stderr + 1e-6 * exact
    assert 0 < rms.stderr < 3e-3 * exact
    # a uniform blur: half the light within R/sqrt(2) of a disc (polygon: close to it)
    if blades == 0:
        radius = dz * SEMI / (F_MM - lens.surfaces[1].sag(SEMI))
        ee50 = r.estimates["ee50_radius_mm"]
        assert abs(ee50.value - radius / math.sqrt(2)) < 4 * ee50.stderr + 0.5 * r.grid.pitch_mm
    assert r.samples == 1 << 16 and r.seconds > 0 and r.metadata["sampler"] == sampler


def test_best_focus_minimises_the_axial_rms_spot():
    from lensrt.analysis.psf.focus import best_focus_z_mm
    from lensrt.analysis.psf.geometric import geometric_psf_at
    lens = singlet(conic=0.0)  # spherical aberration: best focus lies in front of the paraxial focus
    z_best, rms_best = best_focus_z_mm(lens, device="cpu")
    z_par = make_setup(lens, focus="paraxial", device="cpu").plane_z_mm
    assert z_best < z_par
    vals = []
    for dz in (-0.02, 0.0, 0.02):
        setup = make_setup(lens, focus=f"best{dz:+g}", device="cpu", rays=1 << 15, pixels=32, precision="float64")
        vals.append(geometric_psf_at(setup, AXIS, 3, "cpu").estimates["rms_radius_mm"].value)
    assert vals[1] < vals[0] and vals[1] < vals[2]
    assert abs(vals[1] - rms_best) < 0.01 * rms_best


def test_iris_blades_shape_the_diffraction_pupil():
    # a hexagonal iris: clear area 3 sqrt(3) / (2 pi) = 0.827 of the circle, from the rays alone
    from lensrt.analysis.psf.diffraction import diffraction_psf_at
    areas = {}
    for blades in (0, 6):
        setup = make_setup(singlet(blades=blades), focus="paraxial", device="cpu", method="diffraction")
        r = diffraction_psf_at(setup, AXIS, "cpu")
        areas[blades] = r.metadata["working_f_number"] ** -2
    assert abs(areas[6] / areas[0] - 3 * math.sqrt(3) / (2 * math.pi)) < 0.01


def test_sensor_grid_lands_on_its_targets():
    from lensrt.analysis.pupil_rays import chief_ray_at
    from lensrt.loading import load_lens
    from lensrt.trace.aiming import field_point
    lens = load_lens("dgauss_50mm_f2")
    fields = sensor_grid_fields(lens, "aps-c", (3, 3), lens.image_z_mm, "cpu")
    assert [f.grid_index for f in fields] == [(r, c) for r in range(3) for c in range(3)]
    assert fields[0].target_mm == (-11.8, 7.85)  # row 0 at the top (+y), column 0 at the left
    for f in fields:
        q = chief_ray_at(lens, field_point(lens, f.hx, f.hy), [lens.wavelengths.primary_nm], lens.image_z_mm, "cpu")
        assert np.hypot(*(q.position_mm[0, :2] - np.asarray(f.target_mm))) < 1e-4
    table = chief_height_table(lens, lens.image_z_mm, device="cpu")
    assert np.all(np.diff(table.height_mm) > 0)


def test_psf_map_job_is_bit_identical_across_threads():
    from lensrt.parallel.local import LocalExecutor
    from lensrt.parallel.workloads import get_workload
    job = get_workload("psf-map")("grid=2,rays=8192,pixels=16", 5)
    with LocalExecutor("cpu") as ex:
        one = ex.run(job).value
    with LocalExecutor("cpu,cpu") as ex:
        two = ex.run(job).value
    assert one["psf"].shape == (4, 16, 16)
    for k in one:
        assert np.array_equal(one[k], two[k]), k


def test_auto_method_reports_its_choice():
    from lensrt.analysis.psf.map import psf_at
    fine = psf_at(make_setup(singlet(), focus="paraxial", device="cpu", method="auto"), AXIS, 0, "cpu")
    assert fine.kind == "diffraction-fft" and "Fresnel" in fine.metadata["method_reason"]
    blurred = psf_at(make_setup(singlet(), focus="paraxial+5", device="cpu", method="auto", rays=1 << 14,
                                pixels=32), AXIS, 0, "cpu")
    assert blurred.kind == "geometric" and "Nyquist" in blurred.metadata["method_reason"]


def test_system_mtf_is_the_product_of_its_parts(airy):
    from lensrt.analysis.psf.mtf_curves import Detector, mtf_curves
    lens, r = airy
    det = Detector(pixel_pitch_um=5.0, fill_factor=0.64, olpf_um=5.0)
    c = mtf_curves(r, lens, det)
    f = c["freqs_cpmm"]
    for k in ("sagittal", "tangential"):
        assert np.allclose(c[f"system_{k}"], c[f"lens_{k}"] * c[f"olpf_{k}"] * c[f"detector_{k}"])
    # on axis sagittal is along x: the detector's zero at 1 / aperture, the OLPF's at the Nyquist frequency
    assert math.isclose(det.aperture_um, 4.0)
    assert np.allclose(c["detector_sagittal"], np.abs(np.sinc(f * 4.0e-3)))
    assert np.allclose(c["olpf_sagittal"], np.abs(np.cos(np.pi * f * 5.0e-3)))
    assert c["nyquist_cpmm"] == 100.0
    # the diffraction limit is drawn at the lens's paraxial working f-number
    assert np.allclose(c["diffraction_limit"], mtf.diffraction_mtf(f, WL, c["diffraction_f_number"]))


def test_diffraction_and_geometric_psfs_share_the_centroid_off_axis():
    # in the Debye picture the centroid of the diffraction PSF is the intensity-weighted mean transverse ray
    # aberration -- the geometric centroid: checks the OPD sign, the pupil coordinates and the grids together
    from lensrt.analysis.psf.diffraction import diffraction_psf_at
    from lensrt.analysis.psf.geometric import geometric_psf_at
    from lensrt.analysis.psf.spectrum import line_spectrum
    from lensrt.loading import load_lens
    lens = load_lens("cooke_triplet_50mm_f5")
    setup = make_setup(lens, line_spectrum([587.56]), "best", "cpu", pixels=256, rays=1 << 18, precision="float64")
    f = FieldSpec(0.0, 1.0, "full")
    g = geometric_psf_at(setup, f, 1, "cpu")
    d = diffraction_psf_at(setup.with_(method="diffraction"), f, "cpu")
    assert d.metadata["opd_pv_waves"] > 1.5  # aberrated: the centroid is well off the chief ray
    dy_g = g.estimates["centroid_y_mm"].value - g.reference_mm[1]
    dy_d = d.estimates["centroid_y_mm"].value - d.reference_mm[1]
    assert abs(dy_g) > 3e-3
    assert abs(dy_d - dy_g) < 0.02 * abs(dy_g) + 5 * g.estimates["centroid_y_mm"].stderr
    assert abs(d.estimates["centroid_x_mm"].value - d.reference_mm[0]) < 1e-5


@pytest.mark.slow
def test_small_fresnel_number_uses_huygens_and_still_gives_the_airy_pattern():
    # an f/50 aberration-free singlet: Fresnel number NA^2 R / lambda ~ 10 < 20, so auto picks the direct
    # Huygens sum over the reference sphere; on the focal plane it is still the Airy pattern
    from lensrt.analysis.psf.map import psf_at
    semi = 0.5
    s = (Surface(thickness_mm=5.0, material=ConstantIndex(N_GLASS), semi_diameter_mm=semi, is_stop=True),
         Surface(curvature_per_mm=-1.0 / ((N_GLASS - 1.0) * F_MM), conic=-N_GLASS**2, thickness_mm=F_MM,
                 semi_diameter_mm=semi * 1.2))
    lens = Lens(s, aperture=Aperture("float_by_stop", 0.0), fields=Fields("angle", (0.0, math.radians(1.0))),
                wavelengths=Wavelengths((WL,)))
    r = psf_at(make_setup(lens, focus="paraxial", device="cpu", method="auto", pixels=48, pupil_samples=64),
               AXIS, 0, "cpu")
    assert r.kind == "diffraction-huygens" and "Fresnel" in r.metadata["method_reason"]
    assert r.metadata["fresnel_number"] < 20
    n_w = 0.5 * math.hypot(semi, F_MM) / semi  # 1 / (2 sin u') of the marginal ray (sag of 5 um neglected)
    x, y = r.grid.mesh_mm()
    ref = mtf.airy_psf(np.hypot(x - r.reference_mm[0], y - r.reference_mm[1]), WL, n_w)
    assert np.max(np.abs(r.psf - ref)) < 0.01 * ref.max()


def test_through_focus_spots_follow_a_pure_defocus():
    """The stigmatic plano-hyperbolic lens on axis: a ray of slope t lands dz t from the focus, so the RMS
    radius about the centroid is |dz| times the RMS slope of the pupil's rays -- linear, zero at focus."""
    from pathlib import Path
    from lensrt.analysis.fields import FieldSpec
    from lensrt.analysis.psf.focus_spots import through_focus_spots
    from lensrt.loading import load_lens
    lens = load_lens(Path(__file__).resolve().parents[2] / "data" / "plano_hyperbolic_f5.toml")
    setup = make_setup(lens, focus="paraxial", device="cpu")
    sp = through_focus_spots(setup, FieldSpec(0.0, 0.0, "axis"), [-0.2, -0.1, 0.0, 0.1, 0.2], device="cpu")
    assert sp.rms_radius_mm[2] < 1e-9
    assert sp.rms_radius_mm[1] == pytest.approx(0.5 * sp.rms_radius_mm[0], rel=1e-6)
    assert sp.rms_radius_mm[3] == pytest.approx(sp.rms_radius_mm[1], rel=1e-6)
    assert np.allclose(sp.centroid_mm, 0.0, atol=1e-12)
