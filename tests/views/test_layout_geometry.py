"""Layout plots of folded and tilted systems: the drawn polylines against the geometry.

The figure's lines are captured before saving; the oracles are closed forms: the law of
reflection at a 45 deg fold mirror (the beam leaves along -y and the image line runs along z),
a rigid motion of the whole lens (tilt-shift: every drawn outline point moved by the same
rotation and shift), and the reflex lens's surfaces at their physical z.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from geometry_cases import folded_system

from lensrt import load_lens
from lensrt.prescription.tilt_shift import lens_frame, tilt_shift_lens
from lensrt.views.plots import layout


@pytest.fixture
def drawn(monkeypatch, tmp_path):
    """Draw a layout and return its axes' lines as (z, y, colour, linewidth) tuples."""
    def draw(lens):
        got = {}

        def keep(fig, path):
            got["fig"] = fig
            return path
        monkeypatch.setattr(layout, "save_figure", keep)
        layout.plot_layout(tmp_path / "layout.png", lens, device="cpu")
        ax = got["fig"].axes[0]
        return [(np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float), ln.get_color(),
                 ln.get_linewidth()) for ln in ax.get_lines()]
    return draw


def test_fold_mirror_turns_the_drawing(drawn) -> None:
    lens = folded_system()  # singlet at z = 0..4, a 45 deg mirror at z = 44, the image 55 mm along -y
    lines = drawn(lens)
    image = [ln for ln in lines if ln[2] == "k" and ln[3] == 1.2]
    assert len(image) == 1
    z, y, _, _ = image[0]
    assert np.allclose(y, -55.0, atol=1e-9)                    # the beam leaves the mirror along -y
    assert z.mean() == pytest.approx(44.0, abs=1e-9) and np.ptp(z) > 0
    rays = [ln for ln in lines if ln[3] == 0.7]
    reached = 0
    for z, y, _, _ in rays:
        if abs(y[-1] + 55.0) > 1e-6:
            continue
        reached += 1
        # the last point on the image line, the one before on the mirror (y = 44 - z), and the
        # segment after it the reflection of the one before: (dy, dz) -> (-dz, -dy) at a 45 deg mirror
        assert abs(z[-1] - 44.0) <= np.ptp(image[0][0]) / 2
        assert y[-2] == pytest.approx(44.0 - z[-2], abs=1e-9)
        d_in = np.array([y[-2] - y[-3], z[-2] - z[-3]])
        d_out = np.array([y[-1] - y[-2], z[-1] - z[-2]])
        d_in, d_out = d_in / np.linalg.norm(d_in), d_out / np.linalg.norm(d_out)
        assert np.allclose(d_out, [-d_in[1], -d_in[0]], atol=1e-9)
    assert reached >= 9


def test_tilted_lens_is_drawn_as_a_rigid_motion(drawn) -> None:
    lens = load_lens("cooke_triplet_50mm_f5")
    tilt, shift = math.radians(7.0), (0.0, 2.5)
    moved = tilt_shift_lens(lens, tilt, shift)
    origin, rot = lens_frame(tilt, shift, float(lens.vertex_z_mm()[lens.stop_index]))
    flat = layout.element_outlines(lens)
    tilted = layout.element_outlines(moved)
    assert len(flat) == len(tilted) > 0
    for a, b in zip(flat, tilted):
        pts = origin[:, None] + rot @ np.stack([np.zeros(len(a)), a[:, 1], a[:, 0]])
        assert np.allclose(b[:, 0], pts[2], atol=1e-9) and np.allclose(b[:, 1], pts[1], atol=1e-9)
    lines = drawn(moved)
    outlines = [ln for ln in lines if ln[2] == "#1b3a57" and ln[3] == 1.0]
    for b, (z, y, _, _) in zip(tilted, outlines):
        assert np.allclose(z, b[:, 0]) and np.allclose(y, b[:, 1])
    # the image line stays the camera's sensor: perpendicular to the camera axis at the lens's image z
    z, y, _, _ = next(ln for ln in lines if ln[2] == "k" and ln[3] == 1.2)
    assert np.allclose(z, lens.image_z_mm, atol=1e-9)


def test_reflex_lens_mirrors_at_their_physical_places(drawn) -> None:
    lens = load_lens("reflex_nikkor_500mm_f8")
    lines = drawn(lens)
    mirrors = [ln for ln in lines if ln[3] == 2.0]
    assert len(mirrors) == 2
    vz = lens.vertex_z_mm()
    primary, secondary = (i for i, s in enumerate(lens.surfaces) if s.mirror)
    for (z, y, _, _), i in zip(mirrors, (primary, secondary)):
        centre = np.argmin(np.abs(y))
        assert z[centre] == pytest.approx(vz[i], abs=1e-3)
    # the primary behind the front corrector, the secondary just behind it: the path folds twice
    assert vz[primary] > 100.0 and 10.0 < vz[secondary] < 20.0
    # the secondary's shadow is drawn: a dark bar of the obscuration's radius on its plane
    bars = [ln for ln in lines if ln[2] == "0.15"]
    a = lens.surfaces[2].apertures[0].a
    assert bars and max(np.abs(ln[1]).max() for ln in bars) == pytest.approx(a)
