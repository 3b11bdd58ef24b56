"""Point location and linear interpolation on the rays' triangulation (TriLinear, BucketLocator) against
matplotlib's LinearTriInterpolator and a brute-force search over every triangle."""
from __future__ import annotations

import numpy as np
import pytest
from matplotlib.tri import LinearTriInterpolator, Triangulation

from lensrt.analysis.wave.point_location import BucketLocator
from lensrt.analysis.wave.pupil_grid import TriLinear, pupil_coordinates


def ray_like_points(m: int = 48, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A regular m x m grid bent as a lens bends the pupil (distortion, shear), with cocircular points."""
    a, b = np.meshgrid(np.linspace(-1, 1, m), np.linspace(-1, 1, m))
    r2 = a * a + b * b
    x = 0.9 * a * (1 + 0.08 * r2) + 0.03 * b
    y = 0.9 * b * (1 - 0.05 * r2)
    keep = r2 <= 1.15
    return x[keep], y[keep]


def brute_force(x, y, triangles, qx, qy) -> np.ndarray:
    """Every triangle that holds each point (boundary included): (Q, T) bool."""
    xt, yt = x[triangles], y[triangles]
    inside = np.ones((qx.size, len(triangles)), dtype=bool)
    area = (xt[:, 1] - xt[:, 0]) * (yt[:, 2] - yt[:, 0]) - (xt[:, 2] - xt[:, 0]) * (yt[:, 1] - yt[:, 0])
    for a, c in ((0, 1), (1, 2), (2, 0)):
        e = (xt[None, :, c] - xt[None, :, a]) * (qy[:, None] - yt[None, :, a]) \
            - (yt[None, :, c] - yt[None, :, a]) * (qx[:, None] - xt[None, :, a])
        inside &= np.sign(area)[None, :] * e >= -1e-12 * np.abs(area)[None, :]
    return inside


def test_bucket_locator_finds_a_triangle_that_holds_each_point():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1, 1, 300), rng.uniform(-1, 1, 300)
    tri = Triangulation(x, y)
    qx, qy = rng.uniform(-1.2, 1.2, 2000), rng.uniform(-1.2, 1.2, 2000)
    found = BucketLocator(x, y, tri.triangles).find(qx, qy)
    holds = brute_force(x, y, tri.triangles, qx, qy)
    assert np.array_equal(found >= 0, holds.any(axis=1))  # inside the hull exactly where some triangle holds it
    hit = found >= 0
    assert holds[np.nonzero(hit)[0], found[hit]].all()
    assert hit.sum() > 1000 and (~hit).sum() > 100  # both cases exercised


def test_masked_triangles_are_left_out():
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-1, 1, 200), rng.uniform(-1, 1, 200)
    tri = Triangulation(x, y)
    mask = np.zeros(len(tri.triangles), dtype=bool)
    mask[::3] = True
    qx, qy = rng.uniform(-1, 1, 3000), rng.uniform(-1, 1, 3000)
    found = BucketLocator(x, y, tri.triangles, mask).find(qx, qy)
    assert not mask[found[found >= 0]].any()
    only_masked = ~brute_force(x, y, tri.triangles[~mask], qx, qy).any(axis=1)
    assert np.array_equal(found < 0, only_masked)


@pytest.mark.parametrize("n", [32, 128])
def test_trilinear_equals_matplotlib_linear_interpolation(n):
    x, y = ray_like_points()
    rng = np.random.default_rng(2)
    values = np.sin(3 * x) * np.cos(2 * y) + 0.1 * rng.standard_normal(x.size)
    lin = TriLinear(x, y)
    gx, gy = pupil_coordinates(n)
    qx = np.concatenate([gx.ravel(), rng.uniform(-1.1, 1.1, 5000)])
    qy = np.concatenate([gy.ravel(), rng.uniform(-1.1, 1.1, 5000)])
    ours = lin.interp(values, qx, qy, fill=-5.0)
    ref = np.ma.filled(LinearTriInterpolator(lin.tri, values)(qx, qy).astype(np.float64), -5.0)
    assert np.array_equal(ours == -5.0, ref == -5.0)
    inside = ref != -5.0
    assert inside.sum() > 0.5 * qx.size
    # the same plane coefficients and expression: equal, but for points on an edge two triangles share
    # (then the other triangle's plane, equal to rounding)
    assert np.max(np.abs(ours[inside] - ref[inside])) <= 1e-13
    assert np.mean(ours[inside] == ref[inside]) > 0.9


def test_trilinear_reproduces_a_plane_and_fills_outside():
    x, y = ray_like_points(m=24)
    lin = TriLinear(x, y)
    qx, qy = pupil_coordinates(64)
    v = lin.interp(0.3 * x - 1.7 * y + 2.0, qx, qy, fill=np.nan)
    inside = np.isfinite(v)
    assert np.allclose(v[inside], 0.3 * qx[inside] - 1.7 * qy[inside] + 2.0, rtol=0, atol=1e-12)
    assert v.shape == qx.shape and (~inside).any()
    assert np.all(np.hypot(qx[~inside], qy[~inside]) > 0.8)  # only beyond the rays' hull


def test_trilinear_of_reuses_the_triangulation_of_the_same_points():
    x, y = ray_like_points(m=20)
    a = TriLinear.of(x, y)
    assert TriLinear.of(x.copy(), y.copy()) is a  # by content, not by identity
    assert TriLinear.of(x[:-1], y[:-1]) is not a
    fresh = TriLinear(x, y)
    qx, qy = pupil_coordinates(48)
    v = np.cos(x) + y
    assert np.array_equal(a.interp(v, qx, qy), fresh.interp(v, qx, qy), equal_nan=True)
    for k in range(TriLinear.KEEP + 1):  # only the most recent are kept
        TriLinear.of(x + 1e-3 * (k + 1), y)
    assert TriLinear.of(x, y) is not a
