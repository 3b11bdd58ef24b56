"""A trivial Warp kernel for the telemetry tests (its own module: compiled once, in a second)."""
import warp as wp


@wp.kernel
def count_threads(tid_base: int, slice_index: int, hits: wp.array(dtype=wp.int32), owner: wp.array(dtype=wp.int32)):
    t = wp.tid() + tid_base
    wp.atomic_add(hits, t, 1)
    owner[t] = slice_index
