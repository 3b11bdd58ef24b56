"""A figure-drawing worker process (``python -m lensrt.views.plots.figure_worker``), fed by
:class:`lensrt.views.plots.figure.FigureRenderer`.

Protocol on stdin/stdout, one message after another, each an 8-byte little-endian length and a
pickle: the parent sends ``(figure pickle bytes, path)``; the worker draws the figure, writes it
(``savefig``) and answers ``None``, or the error as a string. End of input ends the worker.
"""
from __future__ import annotations

import pickle
import struct
import sys
from typing import Any, BinaryIO

__all__ = ["read_message", "write_message", "serve"]


def read_message(stream: BinaryIO) -> Any:
    """The next message of ``stream``; EOFError at its end."""
    head = stream.read(8)
    if len(head) < 8:
        raise EOFError
    (n,) = struct.unpack("<Q", head)
    body = stream.read(n)
    if len(body) < n:
        raise EOFError
    return pickle.loads(body)


def write_message(stream: BinaryIO, obj: Any) -> None:
    """Send ``obj`` on ``stream``."""
    data = pickle.dumps(obj)
    stream.write(struct.pack("<Q", len(data)) + data)
    stream.flush()


def serve(inp: BinaryIO, out: BinaryIO) -> None:
    """Draw every figure that arrives on ``inp``; answer each on ``out``."""
    import matplotlib.backends.backend_agg  # noqa: F401 - loaded before the first figure arrives
    import matplotlib.figure  # noqa: F401
    while True:
        try:
            data, path = read_message(inp)
        except EOFError:
            return
        try:
            pickle.loads(data).savefig(path)
            write_message(out, None)
        except Exception as err:  # noqa: BLE001 - sent back to the parent, which names the figure
            write_message(out, f"{type(err).__name__}: {err}")


if __name__ == "__main__":
    reply = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but answers on the answer channel
    serve(sys.stdin.buffer, reply)
