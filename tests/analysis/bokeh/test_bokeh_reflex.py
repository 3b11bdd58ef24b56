"""The ring bokeh of a catadioptric (reflex) lens: the library's Reflex-Nikkor 500 mm f/8.

Oracle: the obscuration ratio seen from the source point, found with real rays
(:func:`reflex_cases.edge_rays`: the edge rays grazing the secondary's shadow and the stop, traced
to the sensor); the Monte Carlo bokeh (float32 stream kernel, every ray through mirrors and
surface apertures) must give their ratio within 3 of its standard errors.
"""
from __future__ import annotations

import math

import pytest

from reflex_cases import D_LINE_NM, edge_rays

from lensrt import load_lens
from lensrt.analysis.bokeh.entry import bokeh_spot, focus_lens, spot_source
from lensrt.analysis.bokeh.measure import annulus_radii, polar

REFLEX = "reflex_nikkor_500mm_f8"


def test_reflex_lens_is_obscured_and_folded() -> None:
    lens = load_lens(REFLEX)
    assert lens.has_mirrors and sum(s.mirror for s in lens.surfaces) == 2
    obs = [a for s in lens.surfaces for a in s.apertures if a.obscuration]
    assert obs, "the secondary mirror's shadow is a surface obscuration"
    # the secondary's obscuration covers the beam it returns: no ray skips the secondary
    secondary = next(i for i, s in enumerate(lens.surfaces) if s.mirror and i > 5)
    assert lens.surfaces[2].apertures[0].a >= lens.surfaces[secondary].semi_diameter_mm


@pytest.mark.parametrize("source_mm", [5000.0])
def test_ring_ratio_equals_the_obscuration_ratio_seen_from_the_point(source_mm: float, device: str) -> None:
    lens = load_lens(REFLEX)
    focus = focus_lens(lens, math.inf)
    t_in, t_out, r_in, r_out = edge_rays(lens, source_mm)
    assert r_in > 0 and r_out > r_in
    # independent random batches: the jackknife error is then a plain Monte Carlo error (docs/guide/reflex.md
    # gives the estimator's own bias, ~2e-4 in the ratio, seen with 1e6 Sobol rays)
    img = bokeh_spot(lens, focus, spot_source(lens, focus, source_mm), light=f"lines:{D_LINE_NM}",
                     rays=200_000, sampler="random", device=device)
    (inner, outer, ratio), (se_in, se_out, se_ratio) = annulus_radii(img)
    assert 0 < se_ratio < 2e-3
    assert abs(ratio - r_in / r_out) < 3.0 * se_ratio, (ratio, se_ratio, r_in / r_out)
    assert abs(inner - r_in) < 3.0 * se_in and abs(outer - r_out) < 3.0 * se_out
    # the dark centre: (almost) no light inside the inner radius
    y = img.picture()[..., 1]
    r, _ = polar(img)
    assert y[r < 0.9 * r_in].sum() < 1e-3 * y.sum()
    # seen from the point in object space the ratio is tan(t_in) / tan(t_out); the lens maps
    # the pupil onto the defocused ring almost, not exactly, linearly (docs/guide/reflex.md)
    assert abs(math.tan(t_in) / math.tan(t_out) - ratio) < 0.005 * ratio
