"""The stream planner's histogram replicas on GPUs: the memory budget and its environment knob."""
from __future__ import annotations

import pytest

from lensrt.errors import LensrtError
from lensrt.trace.stream_launch import plan_slots, replica_budget_mb


def _plan(plane: int, layers: int, n_chan: int):
    return plan_slots(1, 2, 1 << 20, plane, layers, n_chan, True, batch_histograms=False, threads_per_batch=None,
                      replicas=None, cpu_workers=None, rays_per_launch=None)


def test_replicas_follow_the_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    bins = 1500 * 1000 * 3 * 3  # a 1500 x 1000 bokeh map, 3 depth layers, XYZ
    monkeypatch.delenv("LENSRT_REPLICA_MB", raising=False)
    assert replica_budget_mb() == 256
    assert _plan(1500 * 1000, 3, 3).replicas == max(1, (256 << 20) // (8 * bins))
    monkeypatch.setenv("LENSRT_REPLICA_MB", "2048")
    assert _plan(1500 * 1000, 3, 3).replicas == min(16, (2048 << 20) // (8 * bins))
    assert _plan(64 * 64, 1, 1).replicas == 16  # never more than 16


@pytest.mark.parametrize("value", ["lots", "0", "-5"])
def test_bad_replica_budget_is_one_clear_error(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv("LENSRT_REPLICA_MB", value)
    with pytest.raises(LensrtError, match="LENSRT_REPLICA_MB"):
        replica_budget_mb()
