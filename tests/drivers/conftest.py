"""Fixtures for the driver tests: rig configs and the step-fit helper module."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from bench.rig import RigConfig, default_rig_path, load_rig

_NAME = "rotorbench_tests_drivers_stepfit"
if _NAME not in sys.modules:
    _spec = importlib.util.spec_from_file_location(_NAME, Path(__file__).with_name("stepfit.py"))
    assert _spec is not None and _spec.loader is not None
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules[_NAME] = _mod
    _spec.loader.exec_module(_mod)


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
