"""Progress on the terminal: one bar format for every command.

* :func:`bar_line` -- the text of a bar, ``label [#####.....] 3/8, 12.1 s, ~20 s left``;
* :class:`ProgressBar` -- a ``(done, total)`` callback (what :meth:`lensrt.parallel` executors
  call after each work item) that redraws the bar in place on a terminal;
* :class:`StepProgress` -- a list of named steps (``lensrt report``): one line per finished
  step with its seconds and outcome, and a bar for the step running now.

Everything goes to stderr, so stdout stays clean for ``--json``. On a stream that is not a
terminal (a log file, CI) bars are not redrawn: a step prints one line when it starts and one
when it ends.
"""
from __future__ import annotations

import sys
import time
from typing import IO

__all__ = ["bar_line", "ProgressBar", "StepProgress"]

_WIDTH = 24


def bar_line(label: str, done: int, total: int, elapsed_s: float | None = None) -> str:
    """``label [#####.....] done/total, 12.1 s, ~20 s left`` (the estimate from the rate so far)."""
    frac = min(max(done / total, 0.0), 1.0) if total > 0 else 0.0
    n = int(round(_WIDTH * frac))
    text = f"{label} [{'#' * n}{'.' * (_WIDTH - n)}] {done}/{total}"
    if elapsed_s is not None:
        text += f", {elapsed_s:.1f} s"
        if 0 < done < total:
            text += f", ~{elapsed_s * (total - done) / done:.0f} s left"
    return text


def _is_tty(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class ProgressBar:
    """A ``(done, total)`` progress callback drawing :func:`bar_line` on ``stream`` (stderr).

    Redrawn in place on a terminal, ending the line when ``done`` reaches ``total`` (unless
    ``end_line`` is false: the caller writes the last line); elsewhere it draws nothing.
    """

    def __init__(self, label: str = "items", stream: IO[str] | None = None, end_line: bool = True) -> None:
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.tty = _is_tty(self.stream)
        self.end_line = end_line
        self.t0 = time.perf_counter()
        self.width = 0

    def redraw(self, text: str, newline: bool = False) -> None:
        """Overwrite the current terminal line with ``text``."""
        pad = " " * max(self.width - len(text), 0)
        self.width = 0 if newline else len(text)
        self.stream.write("\r" + text + pad + ("\n" if newline else ""))
        self.stream.flush()

    def __call__(self, done: int, total: int) -> None:
        if not self.tty:
            return
        text = bar_line(self.label, done, total, time.perf_counter() - self.t0)
        self.redraw(text, newline=self.end_line and done >= total)


class StepProgress:
    """Named steps of a long command, numbered ``[k/n]``, each ending in ``ok, 3.2 s`` or ``FAILED``.

    ``bar = steps.start("PSF map")`` begins a step and returns a :class:`ProgressBar` for its
    work items (pass it as an executor's ``progress``); ``steps.finish(ok)`` ends it.
    """

    def __init__(self, total_steps: int, stream: IO[str] | None = None, quiet: bool = False) -> None:
        self.total = int(total_steps)
        self.stream = sys.stderr if stream is None else stream
        self.quiet = quiet
        self.tty = _is_tty(self.stream) and not quiet
        self.k = 0
        self.bar = ProgressBar("", self.stream, end_line=False)
        self.bar.tty = self.tty

    def start(self, name: str) -> ProgressBar:
        """Begin the next step; returns the ``(done, total)`` callback for its work items."""
        self.k += 1
        self.bar.label = f"[{self.k}/{self.total}] {name}"
        self.bar.t0 = time.perf_counter()
        if self.tty:
            self.bar.redraw(self.bar.label + " ...")
        elif not self.quiet:
            self.stream.write(self.bar.label + " ...\n")
            self.stream.flush()
        return self.bar

    def finish(self, ok: bool = True, note: str = "") -> float:
        """End the current step with one line; returns its seconds."""
        dt = time.perf_counter() - self.bar.t0
        line = f"{self.bar.label}: " + (f"ok, {dt:.1f} s" if ok else f"FAILED after {dt:.1f} s") \
            + (f" ({note})" if note else "")
        if self.tty:
            self.bar.redraw(line, newline=True)
        elif not self.quiet:
            self.stream.write(line + "\n")
            self.stream.flush()
        return dt
