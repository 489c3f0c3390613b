"""Fixtures for the driver tests: rig configs, the step-fit and codec-check helpers."""

from __future__ import annotations

import sys
from dataclasses import replace

import pytest
from rotorbench_tests_sitl import attach_logs, sitl  # noqa: F401  (tests/conftest.py loads it)

from bench.rig.rig import RigConfig, default_rig_path, load_rig


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:
    """A failed test that ran a SITL gets the firmware's log in its report."""
    outcome = yield
    attach_logs(item, outcome.get_result())  # type: ignore[attr-defined]


@pytest.fixture
def stepfit():
    """FOPDT fit and Paper C Step 1 runner (tests only)."""
    return sys.modules["rotorbench_tests_drivers_stepfit"]


@pytest.fixture
def default_rig() -> RigConfig:
    return load_rig(default_rig_path())


@pytest.fixture
def quiet_rig(default_rig: RigConfig) -> RigConfig:
    """The default rig without random noise or timestamp jitter."""
    return replace(default_rig, sim=replace(default_rig.sim, noise=False))
