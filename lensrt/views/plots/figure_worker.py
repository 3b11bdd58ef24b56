"""A figure-drawing worker process (``python -m lensrt.views.plots.figure_worker``), fed by
:class:`lensrt.views.plots.figure.FigureRenderer`.

Protocol on stdin/stdout, one message after another, each an 8-byte little-endian length and a
body. The parent sends *jobs*: the bytes of a pickled ``(module, function name, args, kwargs)``
(:func:`job_bytes`) -- a plot function and the data it draws, a file writer and the arrays it
writes, or :func:`savefig` and a pickled Matplotlib figure. The worker runs it (:func:`execute`)
and answers a pickled ``(error text or None, seconds)``. End of input ends the worker. Before
the first job arrives the worker imports Matplotlib and draws a small figure with text
(:func:`warm_up`), so fonts and the Agg canvas are loaded while the parent computes.
"""
from __future__ import annotations

import pickle
import struct
import sys
import time
from functools import reduce
from importlib import import_module
from typing import Any, BinaryIO, Callable

__all__ = ["read_message", "write_message", "read_bytes", "write_bytes", "job_bytes", "execute", "savefig",
           "exr_threads", "warm_up", "serve"]


def read_bytes(stream: BinaryIO) -> bytes:
    """The body of the next message of ``stream``; EOFError at its end."""
    head = stream.read(8)
    if len(head) < 8:
        raise EOFError
    (n,) = struct.unpack("<Q", head)
    body = stream.read(n)
    if len(body) < n:
        raise EOFError
    return body


def write_bytes(stream: BinaryIO, data: bytes) -> None:
    """Send ``data`` as one message on ``stream``."""
    stream.write(struct.pack("<Q", len(data)))
    stream.write(data)
    stream.flush()


def read_message(stream: BinaryIO) -> Any:
    """The next message of ``stream``, unpickled; EOFError at its end."""
    return pickle.loads(read_bytes(stream))


def write_message(stream: BinaryIO, obj: Any) -> None:
    """Send ``obj`` pickled on ``stream``."""
    write_bytes(stream, pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))


def job_bytes(fn: Callable, args: tuple, kwargs: dict) -> bytes:
    """A job for :func:`execute`: ``fn`` (a module-level function, found again by its module and name)
    and its arguments, pickled now -- later changes to the arguments do not reach the job."""
    return pickle.dumps((fn.__module__, fn.__qualname__, args, kwargs), protocol=pickle.HIGHEST_PROTOCOL)


def execute(job: bytes) -> float:
    """Run a job made by :func:`job_bytes`; returns its seconds (exceptions pass through)."""
    t0 = time.perf_counter()
    module, name, args, kwargs = pickle.loads(job)
    fn = reduce(getattr, name.split("."), import_module(module))
    fn(*args, **kwargs)
    return time.perf_counter() - t0


def savefig(fig, path: str) -> None:
    """Draw a (pickled and sent) Matplotlib figure into ``path``."""
    fig.savefig(path)


def exr_threads() -> int:
    """OpenEXR compresses with 4 threads where the machine has 16 or more cores (the same bytes: each block
    of scan lines is compressed on its own and written in order); returns the count it had before."""
    import os

    import OpenEXR
    before = OpenEXR.global_thread_count()
    if (os.cpu_count() or 1) >= 16:
        OpenEXR.set_global_thread_count(4)
    return before


def warm_up() -> None:
    """Import Matplotlib's figure and Agg canvas and draw a small figure with text into memory: the
    font files, the glyph cache and the text layout code are loaded before the first real figure.
    OpenEXR threads: :func:`exr_threads`."""
    import io

    exr_threads()

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(1.0, 1.0), dpi=50, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="x")
    ax.imshow([[0.0, 1.0]], extent=(0, 1, 0, 1))
    ax.set_title("warm-up 0.5 um", fontsize=7)
    ax.legend(fontsize=6)
    fig.savefig(io.BytesIO(), format="png")


def serve(inp: BinaryIO, out: BinaryIO) -> None:
    """Run every job that arrives on ``inp``; answer each on ``out``."""
    try:
        warm_up()
    except Exception:  # noqa: BLE001 - a failed warm-up costs time at the first figure, nothing else
        pass
    while True:
        try:
            job = read_bytes(inp)
        except EOFError:
            return
        try:
            answer: tuple[str | None, float] = (None, execute(job))
        except Exception as err:  # noqa: BLE001 - sent back to the parent, which names the figure
            answer = (f"{type(err).__name__}: {err}", 0.0)
        try:
            write_message(out, answer)
        except OSError:  # the parent is gone: nothing is waiting for the answer
            return


if __name__ == "__main__":
    import os
    reply = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but answers on the answer channel
    serve(sys.stdin.buffer, reply)
    sys.stderr.flush()
    os._exit(0)  # every file is written and every answer flushed: no interpreter teardown for the parent to wait on
