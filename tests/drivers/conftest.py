"""Fixtures for the driver tests: rig configs, the step-fit and codec-check helpers."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from bench.rig.rig import RigConfig, default_rig_path, load_rig

_NAME = "rotorbench_tests_drivers_stepfit"


def _load_helper(name: str, filename: str) -> None:
    """Load a helper module of this folder by path (tests use importlib mode)."""
    if name in sys.modules:
        return
    spec = importlib.util.spec_from_file_location(name, Path(__file__).parent / filename)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)


_load_helper(_NAME, "stepfit.py")
_load_helper("rotorbench_tests_codec_props", "codec_props.py")  # the codec fuzz tests' checks
_load_helper("rotorbench_tests_expected_protocol", "expected_protocol.py")  # transcript tests
_load_helper("rotorbench_tests_sitl", "../sitl.py")  # Betaflight SITL as a real peer

from rotorbench_tests_sitl import attach_logs, sitl  # noqa: E402, F401


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:
    """A failed test that ran a SITL gets the firmware's log in its report."""
    outcome = yield
    attach_logs(item, outcome.get_result())  # type: ignore[attr-defined]


@pytest.fixture
def stepfit():
    """FOPDT fit and Paper C Step 1 runner (tests only)."""
    return sys.modules[_NAME]


@pytest.fixture
def default_rig() -> RigConfig:
    return load_rig(default_rig_path())


@pytest.fixture
def quiet_rig(default_rig: RigConfig) -> RigConfig:
    """The default rig without random noise or timestamp jitter."""
    return replace(default_rig, sim=replace(default_rig.sim, noise=False))
