"""Shared fixtures: the Warp device matrix and the reference data folder."""
from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "lens_prescriptions"


def _devices() -> list[str]:
    devices = ["cpu"]
    try:
        from lensrt.device import cuda_available
        if cuda_available():
            devices.append("cuda:0")
    except Exception:  # pragma: no cover - warp missing is reported by the kernel tests themselves
        pass
    return devices


@pytest.fixture(params=_devices())
def device(request: pytest.FixtureRequest) -> str:
    """Kernel tests run on "cpu" always and on "cuda:0" when Warp sees one."""
    return request.param


@pytest.fixture
def data_dir() -> Path:
    return DATA


@pytest.fixture
def library_dir() -> Path:
    return LIBRARY
