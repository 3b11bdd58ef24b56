"""Dask worker plugins of :mod:`lensrt.parallel.cluster` (this module imports ``distributed``)."""
from __future__ import annotations

from typing import Any, Sequence

from distributed.diagnostics.plugin import WorkerPlugin

from .context import assign_worker_device, drop_context, store_context

__all__ = ["ContextPlugin", "DevicePlugin"]


class ContextPlugin(WorkerPlugin):
    """Carries a job context to every worker -- including workers that join or restart later -- once.

    The scheduler keeps registered plugins and hands them to each new worker,
    so a worker restarted after a crash gets the context before it runs a task.
    """

    idempotent = True

    def __init__(self, context_hash: str, context: Any) -> None:
        self.context_hash = context_hash
        self.context = context

    def setup(self, worker: Any) -> None:
        store_context(self.context_hash, self.context)

    def teardown(self, worker: Any) -> None:
        drop_context(self.context_hash)


class DevicePlugin(WorkerPlugin):
    """Assigns a device to each LocalCluster worker by its name (0, 1, ...), round-robin."""

    idempotent = True

    def __init__(self, devices: Sequence[str]) -> None:
        self.devices = list(devices)

    def setup(self, worker: Any) -> None:
        try:
            k = int(worker.name)
        except (TypeError, ValueError):
            k = 0
        assign_worker_device(self.devices[k % len(self.devices)])
