"""Shared fixtures: the Warp device matrix, the reference data folder, and the oracles on the import path.

The tests mirror the package: ``tests/<stage>/test_*.py`` (``tests/analysis/psf/`` for ``lensrt/analysis/psf/``),
``tests/stability/`` for the extreme cases, ``tests/cli/`` for the command line, and ``tests/oracles/`` for the
reference code and published listings the tests compare against."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "lens_prescriptions"

# the oracles (reference tracers, listings, shared cases) are imported by name from every test folder
sys.path.insert(0, str(Path(__file__).resolve().parent / "oracles"))


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


def _register_hypothesis_profiles() -> None:
    """Hypothesis profiles: ``ci`` (default; the property suite stays well under a minute on 2 cores) and
    ``long`` (``HYPOTHESIS_PROFILE=long``: 150 random examples per property, about half an hour, for local runs)."""
    import os
    try:
        from hypothesis import HealthCheck, settings
    except ImportError:  # pragma: no cover - hypothesis is in the test extra
        return
    common = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                         HealthCheck.function_scoped_fixture],
                  print_blob=True)
    settings.register_profile("ci", max_examples=12, derandomize=True, **common)
    settings.register_profile("long", max_examples=150, **common)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


_register_hypothesis_profiles()
