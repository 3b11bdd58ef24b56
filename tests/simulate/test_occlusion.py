"""Occlusion at a sharp depth edge against lensrt's own path tracer (benchmarks/acceptance_occlusion.py,
smaller): two uniform planes at 0.7 m and 5 m, the near one covering the left half of the view.

Bounds, in units of the step between the planes' levels on the sensor:

* sharp foreground (focus on it) over a blurred bright background: beyond the in-focus PSF's reach
  (2 px) the foreground is the foreground's own plateau in both images -- any blur from behind is a
  leak. Bound 1 % (measured at 96 x 72: 0.02 %).
* blurred foreground (focus on the background): the lens sees past the foreground's edge; with the
  background continued behind it (the disocclusion fill) the layered scheme matches the render up to
  the render's noise. Bound: 2 % (the issue's per-pixel accuracy) + 3 sigma of the render's profile
  noise (measured at 96 x 72: 2.3 % with sigma 1.1 %; 53 % before the fill), and the 10-90 % edge
  width within 1 px of the render's (6.90 against 6.91 px at 96 x 72).
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))


@pytest.mark.slow
def test_occluding_edge_leak_and_halo_against_the_path_tracer(tmp_path):
    import acceptance_occlusion as occ
    res = {r["case"]: r for r in occ.run(occ.parser().parse_args(
        ["--pixels", "64x48", "--sensor", "8x6", "--spp", "128", "--rays", "8192", "--grid", "3x4", "--bands", "2",
         "--out", str(tmp_path)]))}
    sharp, blurred = res["sharp-front"], res["blurred-front"]
    assert sharp["leak_sharp_side"] < 0.01, sharp
    assert blurred["leak_max"] < 0.02 + 3 * blurred["render_noise_of_profile_max"], blurred
    widths = blurred["halo_width_10_90_px"]
    assert widths["render"] > 3  # a real blur at the edge
    assert abs(widths["simulate"] - widths["render"]) < 1.0, widths
