"""Matplotlib figures without pyplot (no global state, no display): one place for every plot module.

Drawing a figure (layout, text, Agg rasterising, PNG encoding) is Python work that holds the
GIL, often longer than the physics behind it. Inside :func:`deferred_figures` (the report uses it)
:func:`save_figure` pickles the finished figure and hands it to worker *processes*
(:mod:`lensrt.views.plots.figure_worker`), which draw and write it while the caller goes on
computing; :meth:`FigureRenderer.wait` collects them. The files are those a direct ``savefig``
writes (the same Matplotlib draws them). Workers:
``LENSRT_FIGURE_WORKERS`` (0 = draw in the caller), by default 2 where the machine has at least
4 CPU cores and 0 below (on 2 cores the kernels already use both).
"""
from __future__ import annotations

import os
import pickle
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ...errors import LensrtError
from ...io.paths import output_file

__all__ = ["new_figure", "save_figure", "deferred_figures", "figure_workers", "FigureRenderer"]

_active: "FigureRenderer | None" = None
_lock = threading.Lock()


def new_figure(width_in: float, height_in: float, dpi: int = 120):
    """A constrained-layout Figure on an Agg canvas (thread-safe: no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width_in, height_in), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix), creating the folder; inside
    :func:`deferred_figures` the file is written by a worker process (module docstring)."""
    p = output_file(path)
    with _lock:
        renderer = _active
    if renderer is not None:
        renderer.submit(fig, p)
    else:
        fig.savefig(p)
    return p


def figure_workers() -> int:
    """Worker processes for deferred figures: ``LENSRT_FIGURE_WORKERS``, else 2 on >= 4 cores, else 0."""
    raw = os.environ.get("LENSRT_FIGURE_WORKERS")
    if raw is None:
        return 2 if (os.cpu_count() or 1) >= 4 else 0
    try:
        n = int(raw)
    except ValueError:
        raise LensrtError(f"LENSRT_FIGURE_WORKERS={raw!r} is not a whole number",
                          hint="use 0 (draw figures in the calling process) or a number of worker processes") from None
    if n < 0:
        raise LensrtError(f"LENSRT_FIGURE_WORKERS={n} must be 0 or more")
    return n


class _Worker:
    """One worker process and the thread that feeds it figures one at a time and reads its answers."""

    def __init__(self, results: list) -> None:
        import queue
        import subprocess
        import sys
        root = str(Path(__file__).resolve().parents[3])  # the lensrt this process runs, first on the path
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([root] + [v for v in [os.environ.get("PYTHONPATH")] if v]))
        self.proc = subprocess.Popen([sys.executable, "-m", "lensrt.views.plots.figure_worker"], env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.todo: "queue.SimpleQueue" = queue.SimpleQueue()
        self.results = results
        self.thread = threading.Thread(target=self._feed, name="lensrt-figures", daemon=True)
        self.thread.start()

    def _feed(self) -> None:
        from .figure_worker import read_message, write_message
        while True:
            job = self.todo.get()
            if job is None:
                return
            k, data, path = job
            try:
                write_message(self.proc.stdin, (data, path))
                answer = read_message(self.proc.stdout)
                self.results[k] = None if answer is None else RuntimeError(answer)
            except (OSError, EOFError) as err:
                self.results[k] = RuntimeError(f"the figure worker process stopped ({type(err).__name__})")

    def close(self) -> None:
        self.todo.put(None)
        self.thread.join()
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        self.proc.wait()


class FigureRenderer:
    """Worker processes that draw pickled figures; ``owner`` tags the figures submitted from now on.

    Each worker is a fresh interpreter that imports only Matplotlib (no copy of Warp's or CUDA's state,
    no re-run of the caller's main module); figures go to the workers in turn.
    """

    def __init__(self, workers: int) -> None:
        self.results: list = []
        self.pending: list[tuple[int, str, Path]] = []
        self.workers = [_Worker(self.results) for _ in range(workers)]
        self.owner = ""
        self._lock = threading.Lock()

    def submit(self, fig, path: Path) -> None:
        data = pickle.dumps(fig)
        with self._lock:  # figures may come from several threads
            k = len(self.results)
            self.results.append(RuntimeError("not drawn"))
            self.pending.append((k, self.owner, path))
            # the worker with the fewest figures waiting
            w = min(self.workers, key=lambda w: w.todo.qsize())
            w.todo.put((k, data, str(path)))

    def wait(self) -> list[tuple[str, Path, BaseException | None]]:
        """Wait for every figure (the workers end): (owner, path, error or None) each, in submission order."""
        for w in self.workers:
            w.close()
        out = [(owner, path, self.results[k]) for k, owner, path in self.pending]
        self.pending = []
        return out


@contextmanager
def deferred_figures(workers: int | None = None) -> Iterator[FigureRenderer | None]:
    """Within the block :func:`save_figure` hands figures to ``workers`` processes (default
    :func:`figure_workers`; 0: no renderer, figures drawn at once, None yielded). Call
    :meth:`FigureRenderer.wait` (once) before using the files; leaving the block waits as well."""
    global _active
    n = figure_workers() if workers is None else int(workers)
    if n <= 0:
        yield None
        return
    renderer = FigureRenderer(n)
    with _lock:
        previous, _active = _active, renderer
    try:
        yield renderer
    finally:
        with _lock:
            _active = previous
        renderer.wait()
