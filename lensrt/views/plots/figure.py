"""Matplotlib figures without pyplot (no global state, no display): one place for every plot module.

Drawing a figure (layout, text, Agg rasterising, PNG encoding) is Python work that holds the
GIL, often longer than the physics behind it, and so is writing a compressed EXR. Inside
:func:`deferred_figures` (the report uses it) that work leaves the calling process: worker
*processes* (:mod:`lensrt.views.plots.figure_worker`), started when the block begins, draw and
write while the caller goes on computing.

* A plot function decorated with :func:`drawn_by_workers` sends its *data* (its arguments,
  pickled at the call) and the worker runs the function itself: the caller builds no figure and
  need not import Matplotlib's figure code at all. :func:`defer` does the same for any
  module-level function whose first argument is the file it writes (EXR, PNG, JSON writers).
* Any other figure handed to :func:`save_figure` is pickled whole and drawn by a worker.

:meth:`FigureRenderer.wait` collects them. The files are those the same calls write in the
caller (the same code and the same Matplotlib draw them). A job that a worker cannot finish --
its process stopped, or the job raised there -- is run again in the caller, with one message
(:attr:`FigureRenderer.message`); only a job that fails there too comes back as an error.
Workers: ``LENSRT_FIGURE_WORKERS`` (0 = run everything in the caller), by default 2 where the
machine has at least 4 CPU cores and 0 below (on 2 cores the kernels already use both).
"""
from __future__ import annotations

import functools
import os
import pickle
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, TypeVar

from ...errors import LensrtError
from ...io.paths import output_file
from .figure_worker import execute, exr_threads, job_bytes, read_message, savefig, write_bytes

__all__ = ["new_figure", "save_figure", "defer", "drawn_by_workers", "deferred_figures", "figure_workers",
           "FigureRenderer"]

_active: "FigureRenderer | None" = None
#: the order in which queued jobs go to the workers: figures (only a worker may draw them) before files
#: (which the caller takes back at the end), then the end entries
_RANK, _RANK_END = {"figure": 0, "file": 1}, 2
_lock = threading.Lock()
_here = threading.local()  # .now is True while this thread runs a job itself (a worker's job run again)

F = TypeVar("F", bound=Callable[..., Any])


def new_figure(width_in: float, height_in: float, dpi: int = 120):
    """A constrained-layout Figure on an Agg canvas (thread-safe: no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width_in, height_in), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _renderer() -> "FigureRenderer | None":
    """The renderer that takes jobs from this thread now, if any."""
    if getattr(_here, "now", False):
        return None
    with _lock:
        return _active


def _handed_over(fn: Callable[..., Any], args: tuple, kwargs: dict, path: Path, kind: str) -> bool:
    """Give ``fn(*args, **kwargs)`` to the active renderer: False when there is none (or the call cannot be
    pickled: a function that is not module-level, an argument that pickle refuses), and the caller runs it."""
    renderer = _renderer()
    if renderer is None or "<locals>" in fn.__qualname__:
        return False
    try:
        job = job_bytes(fn, args, kwargs)
    except (pickle.PicklingError, TypeError, AttributeError):
        return False
    renderer.submit(job, path, kind)
    return True


def save_figure(fig, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix), creating the folder; inside
    :func:`deferred_figures` the file is written by a worker process (module docstring)."""
    p = output_file(path)
    if not _handed_over(savefig, (fig, str(p)), {}, p, "figure"):
        fig.savefig(p)
    return p


def defer(fn: Callable[..., Any], path: str | Path, *args: Any, **kwargs: Any) -> None:
    """Run ``fn(path, *args, **kwargs)``, a module-level function that writes the file ``path``:
    inside :func:`deferred_figures` in a worker process (the arguments are pickled now), else at once."""
    if not _handed_over(fn, (path, *args), kwargs, Path(path), "file"):
        fn(path, *args, **kwargs)


def drawn_by_workers(plot: F) -> F:
    """Decorate a module-level plot function ``plot(path, ...)`` (which draws and saves one figure) so
    that inside :func:`deferred_figures` its arguments go to a worker process, which calls it there.
    The decorated function returns the path, as before."""
    @functools.wraps(plot)
    def deferred_plot(path, *args, **kwargs):
        p = output_file(path)
        if not _handed_over(deferred_plot, (p, *args), kwargs, p, "figure"):
            return plot(p, *args, **kwargs)
        return p
    return deferred_plot  # type: ignore[return-value]


def default_figure_workers(cores: int) -> int:
    """Worker processes for a machine of ``cores`` CPU cores: 0 below 4 (on 2 cores the kernels already use
    both), 2 up to 11, 3 from 12 (a 16-core GPU host: the report's process, three workers and OpenEXR's
    threads), 4 from 32."""
    return 0 if cores < 4 else 2 if cores < 12 else 3 if cores < 32 else 4


def figure_workers() -> int:
    """Worker processes for deferred figures: ``LENSRT_FIGURE_WORKERS``, else
    :func:`default_figure_workers` of the machine's cores."""
    raw = os.environ.get("LENSRT_FIGURE_WORKERS")
    if raw is None:
        return default_figure_workers(os.cpu_count() or 1)
    try:
        n = int(raw)
    except ValueError:
        raise LensrtError(f"LENSRT_FIGURE_WORKERS={raw!r} is not a whole number",
                          hint="use 0 (draw figures in the calling process) or a number of worker processes") from None
    if n < 0:
        raise LensrtError(f"LENSRT_FIGURE_WORKERS={n} must be 0 or more")
    return n


@dataclass
class _Job:
    """One submitted job: who made it, the file it writes, its pickled call (dropped once done)."""
    owner: str
    path: Path
    data: bytes | None
    done: bool = False
    error: str | None = None
    kind: str = "figure"  # "figure" (needs Matplotlib) or "file" (a writer of data)
    seconds: float = 0.0
    where: str = "worker"  # where it ran: "worker", "caller", or "stolen" (by the caller, at the end)
    started: float = 0.0  # time.perf_counter() when a worker's feeding thread took it
    finished: float = 0.0  # time.perf_counter() when a worker finished it


class _Worker:
    """One worker process and the thread that feeds it jobs one at a time and reads its answers: the thread
    takes the next job from the renderer's shared queue only when its worker is free, so a job never waits
    behind a slow one while another worker idles."""

    def __init__(self, jobs: list[_Job], todo: "queue.PriorityQueue[tuple[int, int]]") -> None:
        import subprocess
        import sys
        import tempfile
        root = str(Path(__file__).resolve().parents[3])  # the lensrt this process runs, first on the path
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([root] + [v for v in [os.environ.get("PYTHONPATH")] if v]))
        self.stderr = tempfile.TemporaryFile()  # what the process says before it stops, for the message
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "lensrt.views.plots.figure_worker"], env=env,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.stderr)
        except BaseException:
            self.stderr.close()
            raise
        self.todo = todo
        self.jobs = jobs
        self.alive = True
        self.why = ""
        self.thread = threading.Thread(target=self._feed, name="lensrt-figures", daemon=True)
        self.thread.start()

    def _feed(self) -> None:
        while True:
            _, k = self.todo.get()
            if k < 0:  # the end: one such entry per worker, queued after every job
                return
            job = self.jobs[k]
            job.started = time.perf_counter()
            try:
                write_bytes(self.proc.stdin, job.data)
                error, seconds = read_message(self.proc.stdout)
            except Exception as err:  # noqa: BLE001 - a broken pipe, an end of file, a garbled answer
                # the process stopped: this job is run by the caller at the end, the queue's others by the
                # workers left (or by the caller, when none is)
                self.alive, self.why = False, f"{type(err).__name__}: {err}".rstrip(": ") + self._last_words()
                return
            job.seconds, job.finished = seconds, time.perf_counter()
            if error is None:
                job.done, job.data = True, None
            else:
                job.error = error

    def _last_words(self) -> str:
        """The last line the stopped process wrote on stderr (its exception, if Python raised one)."""
        import subprocess
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass
        self.stderr.seek(0)
        lines = self.stderr.read().decode("utf-8", "replace").strip().splitlines()
        return f"; it said: {lines[-1].strip()[:200]}" if lines else ""

    def close(self, kill: bool = False) -> None:
        """Stop the worker once its feeding thread has ended (after the queue's end entry, or at once with
        ``kill``); the process is reaped."""
        import subprocess
        if kill:
            self.proc.kill()
        self.thread.join()
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        try:
            self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()
        self.stderr.close()


class FigureRenderer:
    """Worker processes that run figure and file jobs; ``owner`` tags the jobs submitted from now on.

    Each worker is a fresh interpreter that imports Matplotlib and lensrt's plot modules (no copy of
    Warp's or CUDA's state, no re-run of the caller's main module). Jobs wait in one queue that the
    workers take from as each becomes free: figures first, in submission order, then files (the files
    still queued at the end the caller takes back and writes itself, while the workers draw). When no
    worker process is running (none could start, or all stopped) jobs run in the caller at once.
    """

    def __init__(self, workers: int) -> None:
        import queue
        self.jobs: list[_Job] = []
        self.todo: "queue.PriorityQueue[tuple[int, int]]" = queue.PriorityQueue()  # (rank, job index)
        self.owner = ""
        self.workers: list[_Worker] = []
        self._start_error = ""
        self._lock = threading.Lock()
        self.message: str | None = None  #: what went wrong with the workers, once per renderer (or None)
        self.wait_s = 0.0  #: seconds :meth:`wait` waited for the workers and ran left-over jobs
        self._outcomes: list[tuple[str, Path, BaseException | None]] | None = None
        self._wait_began = 0.0
        for _ in range(workers):
            try:
                self.workers.append(_Worker(self.jobs, self.todo))
            except OSError as err:
                self._start_error = f"{type(err).__name__}: {err}"
                break

    @property
    def pids(self) -> list[int]:
        """Process ids of the worker processes."""
        return [w.proc.pid for w in self.workers]

    def submit(self, job: bytes, path: Path, kind: str = "figure") -> None:
        """Queue a job made by :func:`~lensrt.views.plots.figure_worker.job_bytes` that writes ``path``
        (``kind``: ``"figure"``, or ``"file"`` for a writer that needs no Matplotlib)."""
        with self._lock:  # jobs may come from several threads
            k = len(self.jobs)
            self.jobs.append(_Job(self.owner, Path(path), job, kind=kind))
            if any(w.alive for w in self.workers):
                self.todo.put((_RANK[kind], k))
                return
        self._run_here(self.jobs[k])

    def _run_here(self, job: _Job, where: str = "caller") -> None:
        """Run a job in this process (no worker, a worker failed it, or taken from a busy worker's queue)."""
        _here.now = True
        try:
            job.seconds = execute(job.data)
            job.done, job.data, job.where = True, None, where
        except Exception as err:  # noqa: BLE001 - handed to the caller as the job's error
            job.error, job.where = f"{type(err).__name__}: {err}", where
        finally:
            _here.now = False

    def wait(self) -> list[tuple[str, Path, BaseException | None]]:
        """Wait for every job (the workers end), run again here whatever a worker could not finish;
        (owner, path, error or None) of each job, in submission order (a second call returns the same)."""
        if self._outcomes is not None:
            return self._outcomes
        t0 = self._wait_began = time.perf_counter()
        self._take_back_files()
        self._end_queue()
        for w in self.workers:
            w.close()
        stopped = [w.why for w in self.workers if not w.alive]
        redo = [j for j in self.jobs if not j.done and j.where == "worker"]
        failed_there = [j for j in redo if j.error is not None]
        for j in redo:
            self._run_here(j)
        ran_here = [j for j in self.jobs if j.where == "caller"]
        if self._start_error or stopped or failed_there:
            why = self._start_error and f"could not start a figure worker process ({self._start_error})"
            why = why or (stopped and f"a figure worker process stopped ({stopped[0]})")
            why = why or f"a figure worker process could not draw {failed_there[0].path.name} ({failed_there[0].error})"
            self.message = (f"{why}; {len(ran_here)} figure or file job{'s' * (len(ran_here) != 1)} ran in this "
                            "process instead (the same files, later)")
        self.wait_s = time.perf_counter() - t0
        self._outcomes = [(j.owner, j.path, None if j.done else RuntimeError(j.error)) for j in self.jobs]
        return self._outcomes

    def _steal_file(self) -> int | None:
        """The first file job still queued, taken off the queue (None when none is left; figure jobs stay: they
        would make this process import Matplotlib's figure code). While the caller writes it the workers finish
        the figures -- the caller would otherwise sit idle at the end -- and a worker that becomes free takes
        the next file itself: one file at a time."""
        import queue
        taken, back = None, []
        while taken is None:
            try:
                rank, k = self.todo.get_nowait()
            except queue.Empty:
                break
            if self.jobs[k].kind == "file":
                taken = k
            else:
                back.append((rank, k))
        for entry in back:
            self.todo.put(entry)
        return taken

    def _take_back_files(self) -> None:
        """Write the file jobs still queued here, one at a time (:meth:`_steal_file`); EXRs compressed with
        the threads a worker uses (:func:`~lensrt.views.plots.figure_worker.exr_threads`, restored after)."""
        previous = None
        try:
            while (k := self._steal_file()) is not None:
                if previous is None and self.jobs[k].path.suffix == ".exr":
                    previous = exr_threads()
                self._run_here(self.jobs[k], "stolen")
        finally:
            if previous is not None:
                import OpenEXR
                OpenEXR.set_global_thread_count(previous)

    def _end_queue(self) -> None:
        """One end entry per worker, after every job: each feeding thread ends on one."""
        for _ in self.workers:
            self.todo.put((_RANK_END, -1))

    def abort(self) -> None:
        """Stop the workers at once, jobs unfinished (the caller is failing anyway)."""
        self._end_queue()
        for w in self.workers:
            w.close(kill=True)

    def stats(self) -> dict[str, Any]:
        """Jobs, where they ran and their seconds (the five slowest by name), how long :meth:`wait` took and
        the jobs it waited for (finished by a worker after it began, or taken off the queue and run here then:
        ``stolen``) and, in ``waited_for_s``, how long after the wait began each of the former was finished
        (the last of them is what the end waited for)."""
        in_workers = [j for j in self.jobs if j.done and j.where == "worker"]
        here = [j for j in self.jobs if j.where in ("caller", "stolen")]
        late = [j.path.name for j in self.jobs if j.where == "stolen" or (j.done and j.where == "worker"
                                                                           and j.finished > self._wait_began > 0)]
        return {"workers": len(self.workers), "jobs": len(self.jobs), "jobs_in_workers": len(in_workers),
                "worker_s": sum(j.seconds for j in in_workers),
                "caller_s": sum(j.seconds for j in here), "stolen": sum(j.where == "stolen" for j in here),
                "wait_s": self.wait_s,
                "waited_for": late,
                "waited_for_s": [[j.path.name, j.finished - self._wait_began] for j in self.jobs
                                 if j.done and j.where == "worker" and j.finished > self._wait_began > 0],
                "slowest": [[j.path.name, j.where, j.seconds] for j in sorted(self.jobs, key=lambda j: -j.seconds)[:5]]}


@contextmanager
def deferred_figures(workers: int | None = None) -> Iterator[FigureRenderer | None]:
    """Within the block :func:`save_figure`, :func:`defer` and the :func:`drawn_by_workers` plot
    functions hand their work to ``workers`` processes (default :func:`figure_workers`; 0: no
    renderer, everything runs at once, None yielded), started now. Call :meth:`FigureRenderer.wait`
    (once) before using the files; leaving the block waits as well (or, on an exception, stops the
    workers without waiting)."""
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
    except BaseException:
        with _lock:
            _active = previous
        renderer.abort()
        raise
    with _lock:
        _active = previous
    renderer.wait()
