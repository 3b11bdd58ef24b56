"""Monte Carlo error against run time: estimates with standard errors, progressive runs, convergence.

Every Monte Carlo quantity lensrt reports is an :class:`Estimate`: its value,
standard error, sample count and seconds. Standard errors come from
independent *batches* (each batch a separate, differently seeded set of
samples):

* linear quantities (a mean, a histogram bin): **batch means** -- the standard
  deviation of the batch values over sqrt(B);
* non-linear functions of sums (an RMS radius = sqrt(sum r^2 / sum w - c^2), a
  centroid, an MTF value from an FFT of the histogram): the **jackknife over
  batches** -- recompute the function leaving one batch out,
  ``se^2 = (B-1)/B * sum_i (theta_i - theta_bar)^2`` (Efron & Stein 1981).

Both need B >= 2 and assume batches are i.i.d.; lensrt uses B = 16 to 64.
Randomised quasi-Monte Carlo (a low-discrepancy sequence with an independent
random shift per batch) fits the same scheme, which is how its smaller error is
measured honestly.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

__all__ = ["Estimate", "batch_means", "jackknife", "ProgressiveRun", "ConvergencePoint",
           "fit_loglog_slope", "StopRule"]


@dataclass(frozen=True)
class Estimate:
    """A Monte Carlo estimate with its standard error, sample count and run time.

    Attributes
    ----------
    value : float or ndarray
    stderr : float or ndarray
        One standard error (same shape as ``value``).
    samples : int
        Rays or samples that went into it (all batches together).
    seconds : float
        Wall-clock seconds spent producing it.
    method : str
        How ``stderr`` was computed (e.g. "jackknife over 32 batches").
    unit : str
    """

    value: Any
    stderr: Any
    samples: int
    seconds: float
    method: str = ""
    unit: str = ""

    @property
    def relative_stderr(self) -> Any:
        v = np.asarray(self.value, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.abs(np.asarray(self.stderr, dtype=np.float64) / v)
        return float(r) if r.ndim == 0 else r

    def to_dict(self) -> dict:
        def conv(x: Any) -> Any:
            a = np.asarray(x)
            return float(a) if a.ndim == 0 else a.tolist()
        return {"value": conv(self.value), "stderr": conv(self.stderr), "samples": int(self.samples),
                "seconds": float(self.seconds), "method": self.method, "unit": self.unit}

    def __str__(self) -> str:
        if np.ndim(self.value) == 0:
            return (f"{float(self.value):.6g} +- {float(self.stderr):.2g} {self.unit}".rstrip()
                    + f" ({self.samples:.3g} samples, {self.seconds:.3g} s)")
        return f"Estimate(shape={np.shape(self.value)}, samples={self.samples}, seconds={self.seconds:.3g})"


def batch_means(batch_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean over axis 0 of per-batch values and its standard error (std / sqrt(B))."""
    v = np.asarray(batch_values, dtype=np.float64)
    b = v.shape[0]
    if b < 2:
        raise ValueError("batch means need at least 2 batches")
    return v.mean(axis=0), v.std(axis=0, ddof=1) / math.sqrt(b)


def jackknife(batch_sums: Sequence[np.ndarray] | np.ndarray, statistic: Callable[..., Any]) -> tuple[Any, Any]:
    """Delete-one-batch jackknife of a statistic of summed batch data.

    Parameters
    ----------
    batch_sums : array (B, ...) or tuple of such arrays
        Per-batch sums (e.g. sum w, sum w x, sum w r^2, or a histogram per batch).
    statistic : callable
        Maps the all-batch sums (same structure, batch axis summed) to a value
        (scalar or array).

    Returns
    -------
    value, stderr
        ``statistic`` of all batches, and its jackknife standard error.
    """
    parts = batch_sums if isinstance(batch_sums, (tuple, list)) else (batch_sums,)
    parts = [np.asarray(p, dtype=np.float64) for p in parts]
    b = parts[0].shape[0]
    if b < 2:
        raise ValueError("the jackknife needs at least 2 batches")
    totals = [p.sum(axis=0) for p in parts]
    full = np.asarray(statistic(*totals), dtype=np.float64)
    loo = np.stack([np.asarray(statistic(*[t - p[i] for t, p in zip(totals, parts)]), dtype=np.float64)
                    for i in range(b)])
    mean = loo.mean(axis=0)
    se = np.sqrt((b - 1) / b * np.sum((loo - mean) ** 2, axis=0))
    if full.ndim == 0:
        return float(full), float(se)
    return full, se


@dataclass(frozen=True)
class StopRule:
    """When a progressive Monte Carlo run stops: whichever limit is reached first.

    ``target_error`` is compared with the run's current error measure (an
    absolute standard error, or relative if ``relative``); ``time_budget_s``
    with the elapsed seconds; ``max_samples`` with the samples so far.
    """

    max_samples: int | None = None
    target_error: float | None = None
    time_budget_s: float | None = None
    relative: bool = False
    min_batches: int = 4

    def __post_init__(self) -> None:
        if self.max_samples is None and self.target_error is None and self.time_budget_s is None:
            raise ValueError("a stop rule needs max_samples, target_error or time_budget_s")
        for name in ("max_samples", "target_error", "time_budget_s"):
            v = getattr(self, name)
            if v is not None and not (v > 0):
                raise ValueError(f"{name} must be positive, not {v!r}")

    def reason(self, samples: int, seconds: float, error: float | None, batches: int) -> str | None:
        """Why to stop now, or ``None`` to go on."""
        if self.max_samples is not None and samples >= self.max_samples:
            return "samples"
        if batches < self.min_batches:
            return None
        if self.target_error is not None and error is not None and error <= self.target_error:
            return "target_error"
        if self.time_budget_s is not None and seconds >= self.time_budget_s:
            return "time_budget"
        return None


@dataclass
class ConvergencePoint:
    """One point of an error-against-run-time curve."""

    samples: int
    seconds: float
    value: float
    stderr: float
    error: float | None = None  # |value - reference| when a reference is known

    def to_dict(self) -> dict:
        return {"samples": self.samples, "seconds": self.seconds, "value": self.value,
                "stderr": self.stderr, "error": self.error}


@dataclass
class ProgressiveRun:
    """Bookkeeping for a run that adds batches until a :class:`StopRule` fires.

    Call :meth:`add` after each batch with the batch's samples; read
    :attr:`elapsed_s`; :attr:`history` keeps one :class:`ConvergencePoint` per
    :meth:`record` call for convergence plots.
    """

    rule: StopRule
    samples: int = 0
    batches: int = 0
    started: float = field(default_factory=time.perf_counter)
    history: list[ConvergencePoint] = field(default_factory=list)
    stop_reason: str | None = None

    @property
    def elapsed_s(self) -> float:
        return time.perf_counter() - self.started

    def add(self, samples: int) -> None:
        self.samples += int(samples)
        self.batches += 1

    def record(self, value: float, stderr: float, reference: float | None = None) -> None:
        err = None if reference is None else abs(value - reference)
        self.history.append(ConvergencePoint(self.samples, self.elapsed_s, float(value), float(stderr), err))

    def should_stop(self, error: float | None) -> bool:
        self.stop_reason = self.rule.reason(self.samples, self.elapsed_s, error, self.batches)
        return self.stop_reason is not None


def fit_loglog_slope(x: Sequence[float], y: Sequence[float]) -> float:
    """Least-squares slope of log(y) against log(x) (e.g. error against seconds: -0.5 for plain MC)."""
    xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    ok = (xa > 0) & (ya > 0) & np.isfinite(xa) & np.isfinite(ya)
    if ok.sum() < 2:
        raise ValueError("need at least two positive points to fit a slope")
    return float(np.polyfit(np.log(xa[ok]), np.log(ya[ok]), 1)[0])
