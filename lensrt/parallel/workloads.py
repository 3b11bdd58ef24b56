"""Named workloads for the scaling benchmark: name -> factory of a :class:`~lensrt.parallel.work.Job`.

A workload factory has the signature ``factory(size: str, seed: int) -> Job``
where ``size`` is ``"tiny"`` (seconds on a CPU, for CI and smoke runs),
``"small"`` or ``"large"`` (a job that keeps several GPUs busy for seconds),
``"key=value,key=value"`` for explicit parameters the factory documents, or a
preset followed by such pairs (``"large,groups=36"``).

Factories are registered by ``"module:attribute"`` strings and imported only
when asked for, so the registry never imports a stage that is not needed (or
not installed). A stage adds itself with one line, e.g. in the benchmark or in
its own module::

    register_workload("psf-map", "lensrt.analysis.psf_parallel:psf_map_workload")
"""
from __future__ import annotations

from importlib import import_module
from typing import Callable

from ..errors import LensrtError
from .work import Job

__all__ = ["WorkloadFactory", "WORKLOADS", "register_workload", "get_workload", "parse_size"]

WorkloadFactory = Callable[[str, int], Job]

#: name -> "module:attribute" (or the factory itself)
WORKLOADS: dict[str, str | WorkloadFactory] = {
    "sweep": "lensrt.studies.sweep:sweep_workload",
    "psf-map": "lensrt.analysis.psf.map:psf_map_workload",
    "render": "lensrt.render.jobs:render_workload",
    "bokeh-map": "lensrt.analysis.bokeh.job:bokeh_map_workload",
}


def register_workload(name: str, factory: str | WorkloadFactory) -> None:
    """Add (or replace) a workload under ``name``."""
    WORKLOADS[name] = factory


def get_workload(name: str) -> WorkloadFactory:
    """The factory registered under ``name`` (imported now)."""
    try:
        entry = WORKLOADS[name]
    except KeyError:
        raise LensrtError(f"unknown workload {name!r}", hint=f"known: {', '.join(sorted(WORKLOADS))}") from None
    if callable(entry):
        return entry
    module, _, attr = entry.partition(":")
    try:
        return getattr(import_module(module), attr)
    except (ImportError, AttributeError) as err:
        raise LensrtError(f"workload {name!r} ({entry}) is not available in this installation: {err}") from None


def parse_size(size: str, presets: dict[str, dict]) -> dict:
    """Parameters for ``size``: a preset name, ``key=value`` pairs over the ``"tiny"`` preset, or a
    preset name followed by pairs over it (``"large,groups=36"``: the large PSF map in 36 work items).

    Values are converted to the type of the preset's value (int, float, str).
    """
    if size in presets:
        return dict(presets[size])
    parts = [p.strip() for p in size.split(",") if p.strip()]
    name = parts[0] if parts and "=" not in parts[0] else None
    if name is not None and name not in presets:
        raise LensrtError(f"unknown workload size {name!r}", hint=f"use one of {', '.join(presets)}, "
                                                                   "optionally followed by ,key=value pairs")
    base = dict(presets.get(name or "tiny", {}))
    for part in parts[1:] if name is not None else parts:
        key, eq, value = part.partition("=")
        if not eq or key not in base:
            raise LensrtError(f"bad workload size {part!r}",
                              hint=f"use one of {', '.join(presets)} or key=value with keys {', '.join(base)}")
        kind = type(base[key])
        try:
            base[key] = kind(float(value)) if kind is int else kind(value)
        except ValueError:
            raise LensrtError(f"workload parameter {key}={value!r} is not a {kind.__name__}") from None
    return base
