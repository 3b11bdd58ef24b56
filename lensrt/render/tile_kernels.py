"""One pass of a render tile summed on the device in one launch: spectral and moment sums, paths through the
lens and row-segment sums of Y.

One small Warp module (its own compile unit, so the integrator's kernels keep their cache). A tile
of :func:`lensrt.render.jobs.run_tile_item` renders all its passes without waiting for the device
between them: instead of copying each pass's hit counts and Y values to the host (a device
synchronisation per pass, and host work under the interpreter lock while the device idles), each
pass is folded into the tile's sums by :func:`tile_pass_sums`, one launch after the camera kernel,
whose thread ``j`` does up to three independent things:

* ``j`` < pixels * bands: adds spectral sum ``j`` of the pass to the tile's float64 sums (the
  one-device render's ``accumulate``);
* ``j`` < pixels: adds pixel ``j``'s XYZ and its square to the float64 moment sums (``accumulate_moments``);
* ``j`` < rows * segments: writes, into slot ``pass``, the pass's paths through the lens (int64: exact in
  any order) and its per-pixel Y sums added in float64, column by column, over one segment of one image
  row of the tile (a fixed order: the same bits on any number of devices).

Each element gets the same operations in the same order as in the four kernels this replaces
(``accumulate``, ``accumulate_moments``, per-block hit sums and per-segment Y sums), so the sums are
the same bits, in one launch per pass instead of four. The slots are copied to the host once, after
the tile's last pass; region sums are then sums of whole segments (:func:`lensrt.render.jobs.region_cuts`).
"""
# No ``from __future__ import annotations``: Warp reads the annotations as objects.

import warp as wp

__all__ = ["tile_pass_sums"]

wp.set_module_options({"enable_backward": False})


@wp.kernel
def tile_pass_sums(base: int, spec: wp.array(dtype=float), spec_sum: wp.array(dtype=wp.float64), n_spec: int,
                   xyz: wp.array(dtype=wp.vec3), s1: wp.array2d(dtype=wp.float64), s2: wp.array2d(dtype=wp.float64),
                   hits: wp.array(dtype=wp.int32), p0: int, p1: int, row0: int, cols: int,
                   cuts: wp.array(dtype=wp.int32), n_segs: int, n_cells: int, slot: int,
                   seg_y: wp.array3d(dtype=wp.float64), seg_hits: wp.array3d(dtype=wp.int64)):
    # thread j of a launch over max(n_spec, pixels, n_cells) threads from thread id ``base`` on (CPU slices);
    # spec/xyz/hits hold the pass's values of the tile's pixels [p0, p1)
    j = wp.tid() + base
    if j < n_spec:
        spec_sum[j] = spec_sum[j] + wp.float64(spec[j])
    if j < p1 - p0:
        for c in range(3):
            v = wp.float64(xyz[j][c])
            s1[j, c] = s1[j, c] + v
            s2[j, c] = s2[j, c] + v * v
    if j < n_cells:
        # image row row0 + r, columns [cuts[k], cuts[k + 1]), the part that lies in the tile
        r = j / n_segs
        k = j - r * n_segs
        row_base = (row0 + r) * cols
        a = wp.max(row_base + cuts[k], p0)
        b = wp.min(row_base + cuts[k + 1], p1)
        s = wp.float64(0.0)
        h = wp.int64(0)
        for i in range(a, b):
            s = s + wp.float64(xyz[i - p0][1])
            h = h + wp.int64(hits[i - p0])
        seg_y[slot, r, k] = s
        seg_hits[slot, r, k] = h
