"""Large item results from a worker process to the parent through shared memory instead of a pipe.

A result is pickled with protocol 5 and its large buffers (NumPy arrays) taken out of band
(:pep:`574`): when they add up to :data:`SHM_MIN_BYTES` or more, the worker copies them into one
``multiprocessing.shared_memory`` segment and sends only the pickle's small remainder, the segment's
name and the buffers' places in it (:func:`pack`). The parent copies each buffer out of the segment
into memory of its own (one ``memcpy`` per array, outside the interpreter lock), rebuilds the result
around them and unlinks the segment (:func:`unpack`). Results below the threshold, and results
where shared memory is not available, travel in the message itself (``pack`` returns them as they
are), so the message always says which way it came. A segment is made only while the
shared-memory file system keeps room to spare (a container's ``/dev/shm`` is often 64 MB): a write
that it cannot back would kill the worker rather than raise, so without room the result takes the pipe.

A worker process of :class:`~lensrt.parallel.process.ProcessExecutor` writes into a
:class:`SegmentPool`: two segments of its own, used in turn and kept from result to result (a new
segment's pages cost more to fault in than the copy itself), which the parent keeps attached
(:class:`Attached`). Two are enough: the parent copies a result out before it reads the next one,
and the worker writes a result only after the parent has read the one before it (it hands out the
next item then). A Dask task has no such hand-shake (a worker runs its queued tasks without
waiting), so there every result gets a segment of its own, unlinked by the reader.

A segment is registered with the resource tracker that a ``spawn``-ed worker shares with its parent:
when a worker dies after writing a segment and before the parent has read it, the tracker unlinks it
when the parent exits, so nothing is left in ``/dev/shm``.

**Results written in place** (:class:`SharedArrays`, :func:`attach_shared`): a job whose items fill
disjoint parts of large arrays (the tiles of a render) can skip the result copies altogether. The
parent makes the arrays once per run -- in one segment named by a token that the items carry, or in
plain memory when shared memory has no room -- and an item that finds them (:func:`attach_shared`:
the same process's arrays for a device thread, the segment by its name for a worker process on this
machine) writes its part into them and returns only small data; an item that does not (a worker on
another machine) returns its arrays as before, and the reduction places them. The parent then
neither copies a result out of a segment nor into its image: each byte is written once, by the
worker that made it, and the parent's serial work per item no longer grows with the item's size.
"""
from __future__ import annotations

import os
import pickle
import threading
from typing import Any, Dict, Tuple

import numpy as np

__all__ = ["SHM_MIN_BYTES", "Packed", "SegmentPool", "Attached", "pack", "unpack", "SharedArrays", "attach_shared",
           "Layout"]

#: results whose out-of-band buffers add up to less than this travel through the pipe (bytes)
SHM_MIN_BYTES = 1 << 20
#: where POSIX shared memory lives on Linux (checked for room before a segment is made)
SHM_DIR = "/dev/shm"


#: free room left in the shared-memory file system after a new segment (bytes)
SHM_HEADROOM_BYTES = 64 << 20


def _new_segment(size: int) -> Any:
    """A new segment of ``size`` bytes; OSError when the shared-memory file system (a container's
    /dev/shm is often 64 MB) would keep less than :data:`SHM_HEADROOM_BYTES` free: writing into a
    segment that the file system cannot back kills the process (SIGBUS) instead of raising."""
    import shutil
    from multiprocessing import shared_memory
    size = max(int(size), 1)
    if os.path.isdir(SHM_DIR) and shutil.disk_usage(SHM_DIR).free < size + SHM_HEADROOM_BYTES:
        raise OSError(f"{SHM_DIR} has no room for a {size}-byte result segment")
    return shared_memory.SharedMemory(create=True, size=size)


class Packed(tuple):
    """A result in shared memory: (segment name, pickle without its buffers, [(offset, bytes), ...],
    whether the reader unlinks the segment)."""

    __slots__ = ()


class SegmentPool:
    """The shared-memory segments of one worker process, used in turn and grown when a result needs it."""

    def __init__(self, n: int = 2) -> None:
        self._segs: list[Any] = [None] * int(n)
        self._next = 0

    def take(self, size: int) -> Any:
        """The next segment, at least ``size`` bytes (a larger one replaces it when it is too small);
        OSError when a new one is needed and there is no room for it."""
        k, self._next = self._next, (self._next + 1) % len(self._segs)
        seg = self._segs[k]
        if seg is None or seg.size < size:
            if seg is not None:
                self._segs[k] = None
                seg.close()
                seg.unlink()
            seg = self._segs[k] = _new_segment(size)
        return seg

    def close(self) -> None:
        """Unmap and unlink every segment (at the worker's end)."""
        for seg in self._segs:
            if seg is not None:
                seg.close()
                seg.unlink()
        self._segs = [None] * len(self._segs)


class Attached:
    """The parent's mappings of one worker's pooled segments (the most recent ``n`` names)."""

    def __init__(self, n: int = 2) -> None:
        self.n = int(n)
        self._segs: dict[str, Any] = {}

    def get(self, name: str) -> Any:
        from multiprocessing import shared_memory
        seg = self._segs.pop(name, None)
        if seg is None:
            seg = shared_memory.SharedMemory(name=name)
        self._segs[name] = seg               # most recent last
        while len(self._segs) > self.n:      # a segment the worker has replaced by a larger one
            old = self._segs.pop(next(iter(self._segs)))
            old.close()
        return seg

    def close(self, unlink: bool = False) -> None:
        """Unmap (and with ``unlink``, remove: the worker died and cannot) every segment."""
        for seg in self._segs.values():
            seg.close()
            if unlink:
                try:
                    seg.unlink()
                except FileNotFoundError:
                    pass
        self._segs = {}


def pack(obj: Any, min_bytes: int = SHM_MIN_BYTES, pool: SegmentPool | None = None) -> Any:
    """``obj`` itself when its NumPy buffers are small (or shared memory fails), else a :class:`Packed`:
    in the next segment of ``pool``, or in a new segment that the reader unlinks."""
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
        seg = pool.take(total) if pool is not None else _new_segment(total)
    except (ImportError, OSError):  # no shared memory here, or no room in it: the pipe
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
        if pool is None:
            seg.close()
    return Packed((seg.name, meta, spans, pool is None))


def unpack(obj: Any, attached: Attached | None = None) -> Any:
    """The result that :func:`pack` packed, its arrays in memory of this process (a one-off segment is
    unlinked; a pooled one is read through ``attached``); anything else as it is."""
    if not isinstance(obj, Packed):
        return obj
    from multiprocessing import shared_memory
    name, meta, spans, one_off = obj
    if not one_off and attached is None:
        raise ValueError("a result in a worker's pooled segment needs the reader's Attached mappings")
    seg = shared_memory.SharedMemory(name=name) if one_off else attached.get(name)
    try:
        view = np.frombuffer(seg.buf, dtype=np.uint8)
        own = []
        for off, n in spans:
            b = np.empty(n, dtype=np.uint8)
            b[:] = view[off:off + n]
            own.append(b)
        del view
    finally:
        if one_off:
            seg.close()
            seg.unlink()
    return pickle.loads(meta, buffers=own)


#: named arrays of :class:`SharedArrays`: name -> (shape, NumPy dtype string), laid out in this order
Layout = Dict[str, Tuple[Tuple[int, ...], str]]

#: the live :class:`SharedArrays` of this process, by token (what a device thread of the parent writes into)
_LOCAL: dict[str, Any] = {}
_LOCAL_LOCK = threading.Lock()


def _views(buf: Any, layout: Layout) -> dict[str, np.ndarray]:
    """The arrays of ``layout`` over ``buf``, each one 64-byte aligned, in layout order."""
    out, off = {}, 0
    for name, (shape, dtype) in layout.items():
        dt = np.dtype(dtype)
        count = int(np.prod(shape, dtype=np.int64))
        out[name] = np.frombuffer(buf, dtype=dt, count=count, offset=off).reshape(shape)
        off += -(-count * dt.itemsize // 64) * 64
    return out


def _layout_bytes(layout: Layout) -> int:
    return sum(-(-int(np.prod(shape, dtype=np.int64)) * np.dtype(dt).itemsize // 64) * 64
               for shape, dt in layout.values())


class SharedArrays:
    """Zeroed arrays that the items of one job run write in place, in one shared-memory segment named
    ``token`` (plain memory of this process when shared memory has no room: then only this process's
    device threads find them).

    Parameters
    ----------
    token : str
        The segment's name, which the job's items carry (a job's token; at most one run of a job at a time).
    layout : dict
        name -> (shape, NumPy dtype string).

    Notes
    -----
    Made in the parent (a reduction's ``start``); :meth:`release` unlinks the segment and forgets the
    token (when the run ends, or when the object is collected after a failed run); the arrays stay
    valid for as long as they are referenced. A worker process maps the segment per item
    (:func:`attach_shared`) and unmaps it when the item's views are gone.
    """

    def __init__(self, token: str, layout: Layout) -> None:
        import mmap
        import weakref
        self.token, self.layout = str(token), dict(layout)
        self.shared = False
        with _LOCAL_LOCK:
            ref = _LOCAL.get(self.token)
        old = ref() if ref is not None else None
        if old is not None:  # a run of the same job that failed and is not collected yet
            old.release()
        size = max(_layout_bytes(self.layout), 1)
        buf: Any = None
        try:
            seg = _new_named_segment(self.token, size)
        except (ImportError, OSError):
            seg = None
        if seg is not None:
            # our own mapping of the segment's file (the arrays keep it alive); the SharedMemory object is
            # kept only to unlink the name (and for the resource tracker, should this process die first)
            try:
                fd = os.open(os.path.join(SHM_DIR, self.token), os.O_RDWR)
                try:
                    buf = mmap.mmap(fd, size)
                finally:
                    os.close(fd)
                self.shared = True
            except OSError:
                buf = None
            seg.close()
            if buf is None:
                seg.unlink()
                seg = None
        if buf is None:
            buf = bytearray(size)  # zeroed; found by this process's threads only
        self._seg = seg
        self.arrays = _views(buf, self.layout)
        with _LOCAL_LOCK:
            _LOCAL[self.token] = weakref.ref(self)
        self._finalizer = weakref.finalize(self, _release, self.token, seg)

    def release(self) -> None:
        """Unlink the segment and forget the token (idempotent); the arrays stay valid."""
        self._finalizer()


def _release(token: str, seg: Any) -> None:
    with _LOCAL_LOCK:
        _LOCAL.pop(token, None)
    if seg is not None:
        try:
            seg.unlink()
        except FileNotFoundError:
            pass


def _new_named_segment(name: str, size: int) -> Any:
    """A new segment called ``name`` (a stale one of that name, left by a run that failed, is replaced);
    OSError when /dev/shm is missing or would keep less than :data:`SHM_HEADROOM_BYTES` free."""
    import shutil
    from multiprocessing import shared_memory
    if not os.path.isdir(SHM_DIR) or shutil.disk_usage(SHM_DIR).free < size + SHM_HEADROOM_BYTES:
        raise OSError(f"{SHM_DIR} has no room for {size} bytes of shared arrays")
    try:
        return shared_memory.SharedMemory(name=name, create=True, size=size)
    except FileExistsError:
        stale = shared_memory.SharedMemory(name=name)
        stale.close()
        stale.unlink()
        return shared_memory.SharedMemory(name=name, create=True, size=size)


def attach_shared(token: str | None, layout: Layout) -> dict[str, np.ndarray] | None:
    """The arrays of the :class:`SharedArrays` called ``token``: this process's own, else the segment of
    that name on this machine, mapped for as long as the returned views live; None when there is
    neither (a worker on another machine, a run that has ended) or its size does not fit ``layout``."""
    if not token:
        return None
    with _LOCAL_LOCK:
        ref = _LOCAL.get(token)
    mine = ref() if ref is not None else None
    if mine is not None:
        return mine.arrays if mine.layout == dict(layout) else None
    import mmap
    size = _layout_bytes(layout)
    try:
        fd = os.open(os.path.join(SHM_DIR, token), os.O_RDWR)
    except OSError:
        return None
    try:
        if os.fstat(fd).st_size < size:
            return None
        buf = mmap.mmap(fd, size)
    except (OSError, ValueError):
        return None
    finally:
        os.close(fd)
    return _views(buf, layout)
