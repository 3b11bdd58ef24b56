"""Error against run time: a Monte Carlo quantity at growing sample counts, measured against a reference.

:func:`converge` runs a :class:`Quantity` (an RMS spot radius, an MTF value, a relative
illumination, a bokeh or render pixel region; see :mod:`.convergence_quantities` and
:mod:`lensrt.studies.convergence.render`) at sample counts N_1 < N_2 < ... with each sampler and
precision, ``repeats`` times with independent seeds per point, and measures

* the **RMS error** over the repeats against a reference value,
  ``sqrt(mean_k (v_k - ref)^2)`` -- one run's |error| is too noisy to fit a slope to;
* beside it the **RMS reported standard error** ``sqrt(mean_k se_k^2)`` (batch means or the
  jackknife, whatever the quantity reports) and the **expected RMS error**
  ``sqrt(rms_se^2 + se_ref^2)``: a high-sample reference has an error of its own, common to all
  repeats. Their ratio should be about 1 (with R repeats it lies within
  ``sqrt(chi2_R(0.025) / R)`` .. ``sqrt(chi2_R(0.975) / R)`` 95 % of the time; pooled over the
  points of a sampler, ``pooled_error_ratio``, with P x R runs, it is much steadier);
* the Monte Carlo **seconds** (the kernel's or the passes' wall-clock time, without fixed set-up;
  a discarded warm-up run per sampler and precision keeps kernel loading out of the clock).

The reference is a **closed form** where the quantity has one for this lens (the quantity says
which, and why not otherwise), else a **high-sample run** (Sobol' or the quantity's best sampler,
float64 where it has a choice, ``reference`` samples, its own seed). Points whose expected error
is dominated by the reference's (``se_ref > rms_se / 3``) are flagged ``reference_limited`` and
left out of the error slopes.

Slopes are least-squares fits of log(RMS error) against log(seconds) and log(samples)
(:func:`lensrt.stats.fit_loglog_slope`): about -0.5 for plain Monte Carlo. **Gains** compare each
sampler with plain random sampling of the same precision at the largest count: the variance
ratio (how many times more random samples the same error would need) and the efficiency ratio
(variance x seconds: the same, for run time), from the measured RMS errors (with R repeats each
is uncertain by about sqrt(2 / R) in the error, twice that in a variance ratio), and the variance
ratio of the RMS reported standard errors (averaged over the repeats and the batches: steadier,
and as good as the reported errors, which the ``error_ratio`` column checks).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Protocol, Sequence

import numpy as np

from ...errors import LensrtError
from ...stats import Estimate, fit_loglog_slope

__all__ = ["Reference", "Quantity", "converge", "repeat_seed", "default_counts", "default_ray_counts",
           "REFERENCE_LIMIT"]

#: a point is reference-limited when the reference's standard error exceeds this fraction of its own
REFERENCE_LIMIT = 1.0 / 3.0


@dataclass(frozen=True)
class Reference:
    """The value errors are measured against: a closed form (stderr 0) or a high-sample run."""

    value: float
    stderr: float
    samples: int
    seconds: float
    kind: str  # "closed form" or "high-sample run"
    description: str

    def to_dict(self) -> dict:
        return {"value": float(self.value), "stderr": float(self.stderr), "samples": int(self.samples),
                "seconds": float(self.seconds), "kind": self.kind, "description": self.description}


class Quantity(Protocol):
    """A scalar Monte Carlo quantity that :func:`converge` can study.

    Attributes: ``name`` (e.g. "psf-rms"), ``label`` (what and where, for titles), ``unit`` of
    the values, ``display_unit`` and ``display_scale`` (values x scale for tables and plots),
    ``sample_unit`` ("rays", "paths per pixel"), the ``samplers`` and ``precisions`` it supports,
    ``min_samples`` (smallest usable count) and ``reference_sampler`` / ``reference_precision``.
    """

    name: str
    label: str
    unit: str
    display_unit: str
    display_scale: float
    sample_unit: str
    samplers: tuple[str, ...]
    precisions: tuple[str, ...]
    min_samples: int
    reference_sampler: str
    reference_precision: str

    def run(self, samples: int, sampler: str, precision: str, seed: int) -> Estimate:
        """One run: a scalar Estimate whose ``seconds`` are the Monte Carlo work only."""

    def closed_form(self) -> tuple[Reference | None, str]:
        """The exact value where this lens and quantity have one, else (None, why not)."""


def repeat_seed(seed: int, *keys: int) -> int:
    """An independent 31-bit seed for (seed, keys...) (point index, repeat, ...)."""
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, *[int(k) for k in keys]])
               .generate_state(1, np.uint32)[0]) & 0x7FFFFFFF


def default_counts(max_samples: int, min_samples: int, n_points: int = 6) -> list[int]:
    """At most ``n_points`` powers of two spread evenly (in log) from ``min_samples`` up to ``max_samples``."""
    hi = max(int(max_samples), int(min_samples))
    k_hi = int(math.floor(math.log2(hi)))
    k_lo = int(math.ceil(math.log2(max(int(min_samples), 1))))
    if k_lo >= k_hi:
        return [1 << k_hi]
    ks = np.unique(np.round(np.linspace(k_lo, k_hi, max(2, int(n_points)))).astype(int))
    return [1 << int(k) for k in ks]


def default_ray_counts(max_rays: int, batches: int, n_points: int = 7) -> list[int]:
    """Powers of two from about max_rays / 2^(n_points - 1) to max_rays (at least 64 rays per batch)."""
    top = max(int(max_rays), batches * 64)
    k_hi = int(math.floor(math.log2(top)))
    k_lo = max(int(math.ceil(math.log2(batches * 64))), k_hi - n_points + 1)
    return [1 << k for k in range(k_lo, k_hi + 1)]


def _resolve_reference(q: Quantity, reference: Any, counts: Sequence[int], seed: int) -> Reference:
    """``reference``: None/"auto" (closed form if any, else a run with 16 x the largest count),
    "closed" (closed form or an error), or a sample count."""
    if reference in (None, "auto", "closed"):
        ref, why = q.closed_form()
        if ref is not None:
            return ref
        if reference == "closed":
            raise LensrtError(f"{q.name}: no closed form here ({why})", hint="give --reference N (samples)")
        n_ref = 16 * max(counts)
    else:
        n_ref = int(reference)
        if n_ref < max(counts):
            raise LensrtError(f"the reference ({n_ref} {q.sample_unit}) must have at least the largest count "
                              f"({max(counts)})", hint="a reference should have 8-16 x the largest count")
    e = q.run(n_ref, q.reference_sampler, q.reference_precision, repeat_seed(seed, 999_983))
    if float(e.value) == 0.0 and float(e.stderr) == 0.0:  # e.g. a field where every ray is vignetted
        raise LensrtError(f"{q.label}: the reference run ({e.samples} {q.sample_unit}) is exactly 0 with no spread, "
                          "so there is no Monte Carlo error to study",
                          hint="choose a field, region or window that light reaches")
    return Reference(float(e.value), float(e.stderr), int(e.samples), float(e.seconds), "high-sample run",
                     f"{e.samples} {q.sample_unit}, {q.reference_sampler}, {q.reference_precision}, {e.method}")


def _point(vals: np.ndarray, ses: np.ndarray, secs: np.ndarray, samples: int, ref: Reference) -> dict:
    err = vals - ref.value
    rms_err = float(np.sqrt(np.mean(err ** 2)))
    rms_se = float(np.sqrt(np.mean(ses ** 2)))
    expected = math.hypot(rms_se, ref.stderr)
    r = len(vals)
    return {"samples": int(samples), "seconds": float(np.mean(secs)), "repeats": r,
            "value_mean": float(np.mean(vals)),
            "bias": float(np.mean(err)), "bias_stderr": float(np.std(err, ddof=1) / math.sqrt(r)) if r > 1 else None,
            "rms_error": rms_err, "rms_stderr": rms_se, "expected_rms_error": expected,
            "error_ratio": rms_err / expected if expected > 0 else None,
            "reference_limited": bool(ref.stderr > REFERENCE_LIMIT * rms_se),
            "values": [float(v) for v in vals], "stderrs": [float(v) for v in ses]}


def _slope(x: Sequence[float], y: Sequence[float]) -> float | None:
    try:
        return fit_loglog_slope(x, y)
    except ValueError:
        return None


def converge(q: Quantity, counts: Sequence[int], samplers: Sequence[str] | None = None,
             precisions: Sequence[str] | None = None, repeats: int = 8, seed: int = 0, reference: Any = None,
             progress: Callable[[int, int], None] | None = None) -> dict:
    """The convergence study of the module docstring; a JSON-ready dict.

    Keys: ``quantity``, ``label``, ``unit``, ``display_unit``, ``display_scale``, ``sample_unit``,
    ``reference`` (:class:`Reference` as a dict), ``counts``, ``repeats``, ``seed``, ``runs`` (one
    row per sampler, precision and count: samples, mean seconds, RMS error, RMS reported standard
    error, expected RMS error, their ratio, bias, the repeats' values and standard errors),
    ``slopes`` (per sampler and precision: RMS error and RMS standard error against seconds and
    samples), ``gains`` (against random sampling of the same precision) and ``seconds``.
    """
    t0 = time.perf_counter()
    samplers = list(samplers or q.samplers)
    precisions = list(precisions or q.precisions)
    bad = [s for s in samplers if s not in q.samplers] + [p for p in precisions if p not in q.precisions]
    if bad:
        raise LensrtError(f"{q.name} cannot run {', '.join(bad)}",
                          hint=f"samplers: {', '.join(q.samplers)}; precisions: {', '.join(q.precisions)}")
    counts = sorted({int(n) for n in counts})
    if not counts or counts[0] < q.min_samples:
        raise LensrtError(f"{q.name}: sample counts must be at least {q.min_samples} {q.sample_unit}")
    if repeats < 1:
        raise LensrtError("repeats must be at least 1")
    ref = _resolve_reference(q, reference, counts, seed)
    runs, slopes = [], []
    total = len(samplers) * len(precisions) * len(counts) * repeats
    done = 0
    for prec in precisions:
        for samp in samplers:
            q.run(counts[0], samp, prec, repeat_seed(seed, 999_979))  # warm-up: kernel loads stay out of the clock
            pts = []
            for i, n in enumerate(counts):
                es = []
                for k in range(repeats):
                    es.append(q.run(n, samp, prec, repeat_seed(seed, i, k)))
                    done += 1
                    if progress is not None:
                        progress(done, total)
                p = _point(np.array([float(e.value) for e in es]), np.array([float(e.stderr) for e in es]),
                           np.array([e.seconds for e in es]), es[0].samples, ref)
                p.update({"sampler": samp, "precision": prec, "stderr_method": es[0].method})
                pts.append(p)
            runs.extend(pts)
            fit = [p for p in pts if not p["reference_limited"]]
            pooled = (math.sqrt(sum((p["rms_error"] / p["expected_rms_error"]) ** 2 for p in fit) / len(fit))
                      if fit and all(p["expected_rms_error"] > 0 for p in fit) else None)
            slopes.append({"sampler": samp, "precision": prec, "points": len(fit),
                           "pooled_error_ratio": pooled, "pooled_runs": len(fit) * repeats,
                           "error_vs_seconds": _slope([p["seconds"] for p in fit], [p["rms_error"] for p in fit]),
                           "error_vs_samples": _slope([p["samples"] for p in fit], [p["rms_error"] for p in fit]),
                           "stderr_vs_seconds": _slope([p["seconds"] for p in pts], [p["rms_stderr"] for p in pts]),
                           "stderr_vs_samples": _slope([p["samples"] for p in pts], [p["rms_stderr"] for p in pts])})
    gains = []
    for prec in precisions:
        rnd = [x for x in runs if x["sampler"] == "random" and x["precision"] == prec]
        base = rnd[-1] if rnd else None
        for samp in samplers:
            last = [x for x in runs if x["sampler"] == samp and x["precision"] == prec][-1]
            g = {"sampler": samp, "precision": prec, "samples": last["samples"], "variance_ratio": None,
                 "efficiency_ratio": None, "variance_ratio_reported": None}
            if base is not None and last["rms_error"] > 0:
                g["variance_ratio"] = (base["rms_error"] / last["rms_error"]) ** 2
                g["efficiency_ratio"] = g["variance_ratio"] * base["seconds"] / max(last["seconds"], 1e-12)
            if base is not None and last["rms_stderr"] > 0:
                g["variance_ratio_reported"] = (base["rms_stderr"] / last["rms_stderr"]) ** 2
            gains.append(g)
    return {"quantity": q.name, "label": q.label, "unit": q.unit, "display_unit": q.display_unit,
            "display_scale": q.display_scale, "sample_unit": q.sample_unit, "reference": ref.to_dict(),
            "counts": counts, "repeats": int(repeats), "seed": int(seed), "samplers": samplers,
            "precisions": precisions, "runs": runs, "slopes": slopes, "gains": gains,
            "seconds": time.perf_counter() - t0}

