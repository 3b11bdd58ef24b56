"""Bokeh physics against closed forms and independent traces: disc size, iris polygon, spherical
aberration, mechanical vignetting, axial colour, flux, colour and noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bokeh_cases import BK7, achromat, singlet

from lensrt import load_lens
from lensrt.analysis.bokeh.entry import bokeh_spot, focus_lens, gaussian_blur, spot_source
from lensrt.analysis.bokeh.measure import (disc_area_mm2, polygon_vertex_angle, ring_chromaticity_shift,
                                           ring_ratio)
from lensrt.prescription.materials import ConstantIndex

D_LINE = "587.5618"


def _spot(lens, focus_mm, source_mm, device, **kw):
    f = focus_lens(lens, focus_mm)
    src = spot_source(lens, f, source_mm, field_deg=kw.pop("field_deg", None))
    return bokeh_spot(lens, f, src, device=device, **kw), f


# ---- geometry --------------------------------------------------------------------------------

@pytest.mark.parametrize("focus_mm,source_mm", [(1000.0, 20000.0), (20000.0, 1000.0)])
def test_disc_diameter_matches_gaussian_optics(focus_mm, source_mm, device):
    # f/45 plano-hyperbolic singlet (no spherical aberration at infinity), stop 30 mm in front:
    # pupil magnification 1.48, which the formula must carry
    lens = load_lens(singlet(100.0, 45.0, -2.25, stop_gap_mm=30.0))
    img, f = _spot(lens, focus_mm, source_mm, device, light=D_LINE, rays=1 << 20, sampler="random",
                   batch_noise=False)
    g = gaussian_blur(lens, f, source_mm)
    assert abs(g.pupil_magnification - 1.48) < 0.01
    r = img.sources[0]
    # a uniform disc of diameter c has RMS radius c / (2 sqrt 2)
    d = 2.0 * math.sqrt(2.0) * r["rms_radius_mm"]
    se = 2.0 * math.sqrt(2.0) * r["rms_radius_stderr_mm"]
    assert 0 < se < 2e-3 * d
    assert abs(d - g.diameter_mm) < 3.5 * se
    no_mp = 2.0 * lens.surfaces[0].semi_diameter_mm * abs(g.defocus_mm) / (g.image_z_mm - g.exit_pupil_z_mm)
    assert abs(d - no_mp) > 100 * se  # the entrance pupil's diameter in place of the exit pupil's


@pytest.mark.parametrize("focus_mm,source_mm,expected_deg", [(20000.0, 1000.0, 10.0),  # foreground: upright
                                                             (1000.0, 20000.0, 190.0)])  # background: inverted
def test_seven_blade_iris_gives_a_heptagon_with_the_right_rotation(focus_mm, source_mm, expected_deg, device):
    lens = load_lens(singlet(50.0, 8.0, -2.25, stop_gap_mm=10.0, blades=7, rotation_deg=10.0))
    img, _ = _spot(lens, focus_mm, source_mm, device, light=D_LINE, rays=1 << 20, batch_noise=False)
    ang, amp = polygon_vertex_angle(img, 7)
    period = 360.0 / 7
    want = expected_deg % period
    err = (math.degrees(ang) - want + 0.5 * period) % period - 0.5 * period
    assert abs(err) < 0.5
    # the 7-fold harmonic of a regular heptagon's outline r(phi), relative to its mean
    phi = np.linspace(-math.pi, math.pi, 70000, endpoint=False)
    r = math.cos(math.pi / 7) / np.cos((phi + math.pi / 7) % (2 * math.pi / 7) - math.pi / 7)
    full = 2.0 * abs(np.mean(r * np.exp(7j * phi))) / r.mean()
    assert full == pytest.approx(0.0422, abs=1e-4)
    assert amp == pytest.approx(full, rel=0.1)


def test_rounded_blades_round_the_heptagon(device):
    from lensrt.prescription.model import Iris
    lens = load_lens(singlet(50.0, 8.0, -2.25, stop_gap_mm=10.0, blades=7))
    amps = []
    for roundness in (0.0, 0.5, 1.0):
        img, _ = _spot(lens, 1000.0, 20000.0, device, light=D_LINE, rays=1 << 19, batch_noise=False,
                       iris=Iris(7, 0.0, roundness))
        amps.append(polygon_vertex_angle(img, 7)[1])
    assert amps[0] > amps[1] > amps[2] and amps[2] < 0.1 * amps[0]


# ---- aberrations ------------------------------------------------------------------------------

@pytest.mark.parametrize("conic,kind", [(0.0, "under"), (-4.5, "over")])
def test_spherical_aberration_sets_bright_rim_or_bright_centre(conic, kind, device):
    # f/5.6 plano-convex singlet, flat side first: k = 0 is under-corrected (LSA -1.8 mm), k = -2 n^2
    # over-corrected (+1.8 mm); defocus ~5 mm on either side of focus
    lens = load_lens(singlet(50.0, 5.6, conic, stop_gap_mm=5.0))
    bg, _ = _spot(lens, 500.0, 20000.0, device, light=D_LINE, rays=1 << 19)  # s_p > s: background
    fg, _ = _spot(lens, 3000.0, 500.0, device, light=D_LINE, rays=1 << 19)  # s_p < s: foreground
    (r_bg, se_bg), (r_fg, se_fg) = ring_ratio(bg), ring_ratio(fg)
    assert se_bg > 0 and se_fg > 0
    bright_rim, soft_edge = (r_fg, se_fg), (r_bg, se_bg)
    if kind == "over":  # reversing the sign of the aberration swaps the two sides of focus
        bright_rim, soft_edge = soft_edge, bright_rim
    assert bright_rim[0] > 1.5 and bright_rim[0] - 1.0 > 10 * bright_rim[1]
    assert soft_edge[0] < 0.7 and 1.0 - soft_edge[0] > 10 * soft_edge[1]


# ---- vignetting ------------------------------------------------------------------------------

def _footprint_area_ratio(clip, free, src, f):
    """Independent oracle: a dense pupil grid traced in float64 through both lenses; the sensor area
    of the cells that pass every aperture (from each cell's Jacobian), vignetted over unvignetted,
    and the transmitted fraction of the grid."""
    from lensrt.analysis.bokeh.trace import pupil_boxes
    from lensrt.trace import RayBatch, trace
    from lensrt.trace.aiming import FieldPoint, ray_through_point
    obj = np.array([src["object_mm"]])
    b = pupil_boxes(free, obj, [float(D_LINE)], f.sensor_z_mm, device="cpu")[0][0]
    n = 241
    t = np.linspace(0.0, 1.0, n)
    A, B = np.meshgrid(b.a0 + t * (b.a1 - b.a0), b.b0 + t * (b.b1 - b.b0), indexing="ij")
    pts = np.asarray(b.centre) + A.ravel()[:, None] * np.asarray(b.e1) + B.ravel()[:, None] * np.asarray(b.e2)
    o, d = ray_through_point(FieldPoint(False, None, tuple(src["object_mm"])), pts)
    rays = RayBatch(o, d, float(D_LINE))
    rf = trace(free, rays, "float64", "cpu", plane_z_mm=f.sensor_z_mm)
    rc = trace(clip, rays, "float64", "cpu", plane_z_mm=f.sensor_z_mm)
    X, Y = rf.position_mm[:, 0].reshape(n, n), rf.position_mm[:, 1].reshape(n, n)
    jac = np.abs((X[1:, :-1] - X[:-1, :-1]) * (Y[:-1, 1:] - Y[:-1, :-1])
                 - (Y[1:, :-1] - Y[:-1, :-1]) * (X[:-1, 1:] - X[:-1, :-1]))

    def cells(ok):
        k = ok.reshape(n, n)
        return k[:-1, :-1] & k[1:, :-1] & k[:-1, 1:] & k[1:, 1:]
    return jac[cells(rc.ok)].sum() / jac[cells(rf.ok)].sum(), rc.ok.sum() / rf.ok.sum()


def test_off_axis_disc_shrinks_as_mechanical_vignetting_predicts(device):
    # f/16 singlet with an aperture 0.55 f behind it, 1.5x the axial beam: cat's eyes from 1 deg on
    clip = load_lens(singlet(50.0, 16.0, -2.25, stop_gap_mm=10.0, vignetting_aperture=1.5, fields_deg=(0.0, 4.0)))
    free = load_lens(singlet(50.0, 16.0, -2.25, stop_gap_mm=10.0, vignetting_aperture=10.0, fields_deg=(0.0, 4.0)))
    # the analysis stage's vignetting fraction (every aperture over the stop alone, object at infinity)
    from lensrt.analysis.compare.vignetting import vignetting
    vig = vignetting(clip, object_values=[math.radians(1.0), math.radians(2.0)], rays=1 << 15, exit_pupil=False,
                     device=device)
    ratios = []
    for k, field in enumerate((1.0, 2.0)):
        out = {}
        for name, lens in (("clip", clip), ("free", free)):
            img, f = _spot(lens, 300.0, 20000.0, device, field_deg=(0.0, field), light=D_LINE, rays=1 << 21,
                           pixel_um=5.0, batch_noise=False)
            out[name] = (img, f)
        rc, rf = out["clip"][0].sources[0], out["free"][0].sources[0]
        src = spot_source(free, out["free"][1], 20000.0, field_deg=(0.0, field))
        area_pred, frac_dense = _footprint_area_ratio(clip, free, src, out["free"][1])
        # the stream's transmitted pupil area against the dense count
        frac = rc["pupil_area_mm2"] / rf["pupil_area_mm2"]
        frac_se = frac * math.hypot(rc["pupil_area_stderr_mm2"] / rc["pupil_area_mm2"],
                                    rf["pupil_area_stderr_mm2"] / rf["pupil_area_mm2"])
        assert abs(frac - frac_dense) < 4 * frac_se + 2e-3
        v = vig.vignetting_fraction[k]
        assert abs(frac - v.value) < 4 * math.hypot(frac_se, v.stderr) + 0.01 * frac  # 20 m against infinity
        # the disc on the sensor against the footprint of the rays that pass every aperture
        area = disc_area_mm2(out["clip"][0]) / disc_area_mm2(out["free"][0])
        assert area == pytest.approx(area_pred, rel=0.02)
        # and, the lens being nearly linear, close to the transmitted fraction itself
        assert area == pytest.approx(frac, rel=0.06)
        ratios.append(area)
    assert 0.75 < ratios[0] < 0.95 and 0.3 < ratios[1] < 0.45


# ---- colour ----------------------------------------------------------------------------------

def test_axial_colour_gives_rims_of_different_hue_either_side_of_focus(device):
    n = float(BK7.index(587.5618))
    lens = load_lens(singlet(50.0, 5.6, -n * n, material=BK7, stop_gap_mm=5.0))
    bg, _ = _spot(lens, 500.0, 20000.0, device, rays=1 << 19)
    fg, _ = _spot(lens, 3000.0, 500.0, device, rays=1 << 19)
    (d_bg, se_bg), (d_fg, se_fg) = ring_chromaticity_shift(bg), ring_chromaticity_shift(fg)
    assert np.hypot(*d_bg) > 10 * np.hypot(*se_bg) and np.hypot(*d_fg) > 10 * np.hypot(*se_fg)
    # behind focus the rim turns blue (x falls), in front of it red-yellow (x rises): opposite hues
    assert d_bg[0] < 0 < d_fg[0]
    cos = np.dot(d_bg, d_fg) / (np.hypot(*d_bg) * np.hypot(*d_fg))
    assert cos < -0.5


def test_colour_corrected_lenses_show_no_coloured_rims(device):
    n = float(BK7.index(587.5618))
    singlet_bk7 = load_lens(singlet(50.0, 5.6, -n * n, material=BK7, stop_gap_mm=5.0))
    no_dispersion = load_lens(singlet(50.0, 5.6, -n * n, material=ConstantIndex(n), stop_gap_mm=5.0))
    doublet = load_lens(achromat(50.0, 5.6))
    for focus_mm, source_mm in ((500.0, 20000.0), (3000.0, 500.0)):
        d0, se0 = ring_chromaticity_shift(_spot(no_dispersion, focus_mm, source_mm, device, rays=1 << 19)[0])
        assert np.all(np.abs(d0) < 4 * se0)  # colour-free: nothing beyond the noise
        d1, _ = ring_chromaticity_shift(_spot(doublet, focus_mm, source_mm, device, rays=1 << 19)[0])
        d2, _ = ring_chromaticity_shift(_spot(singlet_bk7, focus_mm, source_mm, device, rays=1 << 19)[0])
        assert np.hypot(*d1) < 0.1 * np.hypot(*d2)  # the achromat: its secondary spectrum only


# ---- light, colour of the whole spot, noise ----------------------------------------------------

@pytest.mark.parametrize("light", [D_LINE, "D65"])
def test_spot_flux_is_intensity_times_solid_angle(light, device):
    # stop first: every ray through the stop reaches the sensor, so the spot's luminous flux is
    # I_v times the solid angle of the stop disc seen from the source
    lens = load_lens(singlet(50.0, 8.0, -2.25, material=BK7, stop_gap_mm=10.0))
    d = 20000.0
    img, _ = _spot(lens, 1000.0, d, device, light=light, rays=1 << 19, intensity_cd=3.0)
    r_stop = lens.surfaces[0].semi_diameter_mm
    omega = 2 * math.pi * (1.0 - d / math.hypot(d, r_stop))
    b = img.picture_batches()  # (B, rows, cols, 3), each an estimate of the whole image
    tot = b.reshape(len(b), -1, 3).sum(axis=1) * img.frame.pitch_mm ** 2 * 1e-6  # lm
    flux = tot[:, 1].mean()
    se = tot[:, 1].std(ddof=1) / math.sqrt(len(b))
    assert r_stop == pytest.approx(50.0 / 16.0)
    assert abs(flux - 3.0 * omega) < 4 * se + 1e-6 * flux
    assert img.sources[0]["luminous_flux_lm"] == pytest.approx(flux, rel=1e-4)  # batches kept in float32
    if light == "D65":  # the spot's colour is the source's: the D65 white point
        import colour
        xy = tot[:, :2].sum(axis=0) / tot.sum()
        white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
        xy_b = tot[:, :2] / tot.sum(axis=1, keepdims=True)
        se_xy = xy_b.std(axis=0, ddof=1) / math.sqrt(len(b))
        assert np.all(np.abs(xy - white) < 4 * se_xy + 2e-4)


def test_poisson_noise_estimate_matches_batch_means(device):
    lens = load_lens(singlet(50.0, 8.0, -2.25, material=BK7, stop_gap_mm=10.0))
    for light in ("D65", D_LINE):
        img, _ = _spot(lens, 1000.0, 20000.0, device, light=light, rays=1 << 19, sampler="random")
        r = img.sources[0]
        assert r["noise_method"].startswith("batch means")
        assert r["noise_batch"] == pytest.approx(r["noise_poisson"], rel=0.12)
        assert 0.02 < r["noise"] < 0.5 and r["disc_pixels"] > 1000
    # quasi-random samples beat plain Monte Carlo per pixel: the Poisson figure is then an upper bound
    img, _ = _spot(lens, 1000.0, 20000.0, device, light=D_LINE, rays=1 << 19, sampler="sobol")
    assert img.sources[0]["noise_batch"] < 0.9 * img.sources[0]["noise_poisson"]
    assert img.to_dict()["noise"]["rel_stderr_median"] == img.sources[0]["noise"]
