"""Per-pass counts of a render tile, kept on the device: paths through the lens and row-segment sums of Y.

One small Warp module (its own compile unit, so the integrator's kernels keep their cache). A tile
of :func:`lensrt.render.jobs.run_tile_item` renders all its passes without waiting for the device
between them: instead of copying each pass's hit counts and Y values to the host (a device
synchronisation per pass, and host work under the interpreter lock while the device idles), each
pass writes

* ``block_hits``: the paths through the lens summed over consecutive blocks of pixels (int64, one
  thread per block: integer sums, exact in any order);
* ``row_segment_sums``: the pass's per-pixel Y sums added in float64, column by column, over each
  segment of each image row of the tile (one thread per (row, segment), a fixed order: the same bits
  on any number of devices).

into slot ``pass`` of an array that the tile copies to the host once, after its last pass. Region
sums are then sums of whole segments (:func:`lensrt.render.jobs.region_cuts`).
"""
# No ``from __future__ import annotations``: Warp reads the annotations as objects.

import warp as wp

__all__ = ["block_hits", "row_segment_sums", "HITS_BLOCK"]

#: pixels per thread of :func:`block_hits`
HITS_BLOCK = 256

wp.set_module_options({"enable_backward": False})


@wp.kernel
def block_hits(hits: wp.array(dtype=wp.int32), n: int, block: int, slot: int, out: wp.array2d(dtype=wp.int64)):
    # paths through the lens of pixels [b * block, (b + 1) * block) of the tile, into out[slot, b]
    b = wp.tid()
    i0 = b * block
    i1 = wp.min(i0 + block, n)
    s = wp.int64(0)
    for i in range(i0, i1):
        s = s + wp.int64(hits[i])
    out[slot, b] = s


@wp.kernel
def row_segment_sums(xyz: wp.array(dtype=wp.vec3), p0: int, p1: int, row0: int, cols: int,
                     cuts: wp.array(dtype=wp.int32), slot: int, out: wp.array3d(dtype=wp.float64)):
    # Y of the pixels of image row row0 + r, columns [cuts[k], cuts[k + 1]), that lie in the tile [p0, p1):
    # summed in float64 in column order into out[slot, r, k] (xyz holds the tile's pixels from p0 on)
    r, k = wp.tid()
    base = (row0 + r) * cols
    a = wp.max(base + cuts[k], p0)
    b = wp.min(base + cuts[k + 1], p1)
    s = wp.float64(0.0)
    for i in range(a, b):
        s = s + wp.float64(xyz[i - p0][1])
    out[slot, r, k] = s
