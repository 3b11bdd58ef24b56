"""Large item results from a worker process to the parent through shared memory instead of a pipe.

A result is pickled with protocol 5 and its large buffers (NumPy arrays) taken out of band
(:pep:`574`): when they add up to :data:`SHM_MIN_BYTES` or more, the worker copies them into one
``multiprocessing.shared_memory`` segment and sends only the pickle's small remainder, the segment's
name and the buffers' places in it (:func:`pack`). The parent copies each buffer out of the segment
into memory of its own (one ``memcpy`` per array, outside the interpreter lock), rebuilds the result
around them and unlinks the segment (:func:`unpack`). Results below the threshold, and results
where shared memory is not available, travel in the message itself (``pack`` returns them as they
are), so the message always says which way it came.

A segment is registered with the resource tracker that a ``spawn``-ed worker shares with its parent:
when a worker dies after writing a segment and before the parent has read it, the tracker unlinks it
when the parent exits, so nothing is left in ``/dev/shm``.
"""
from __future__ import annotations

import pickle
from typing import Any

import numpy as np

__all__ = ["SHM_MIN_BYTES", "Packed", "pack", "unpack"]

#: results whose out-of-band buffers add up to less than this travel through the pipe (bytes)
SHM_MIN_BYTES = 1 << 20


class Packed(tuple):
    """A result in shared memory: (segment name, pickle without its buffers, [(offset, bytes), ...])."""

    __slots__ = ()


def pack(obj: Any, min_bytes: int = SHM_MIN_BYTES) -> Any:
    """``obj`` itself when its NumPy buffers are small (or shared memory fails), else a :class:`Packed`."""
    buffers: list[pickle.PickleBuffer] = []
    try:
        meta = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    except Exception:  # noqa: BLE001 - not picklable this way: let the pipe's pickler say why
        return obj
    raws = [b.raw() for b in buffers]
    total = sum(r.nbytes for r in raws)
    if total < min_bytes:
        return obj
    try:
        from multiprocessing import shared_memory
        seg = shared_memory.SharedMemory(create=True, size=max(total, 1))
    except (ImportError, OSError):
        return obj
    spans, off = [], 0
    try:
        view = np.frombuffer(seg.buf, dtype=np.uint8)
        for r in raws:
            view[off:off + r.nbytes] = np.frombuffer(r, dtype=np.uint8)
            spans.append((off, r.nbytes))
            off += r.nbytes
        del view
    finally:
        seg.close()
    return Packed((seg.name, meta, spans))


def unpack(obj: Any) -> Any:
    """The result that :func:`pack` packed (its arrays in memory of this process; the segment unlinked);
    anything else as it is."""
    if not isinstance(obj, Packed):
        return obj
    from multiprocessing import shared_memory
    name, meta, spans = obj
    seg = shared_memory.SharedMemory(name=name)
    try:
        view = np.frombuffer(seg.buf, dtype=np.uint8)
        own = []
        for off, n in spans:
            b = np.empty(n, dtype=np.uint8)
            b[:] = view[off:off + n]
            own.append(b)
        del view
    finally:
        seg.close()
        seg.unlink()
    return pickle.loads(meta, buffers=own)
