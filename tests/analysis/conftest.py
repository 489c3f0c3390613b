"""Fixtures for the analysis tests: the synthetic esc_test-family log writer (logfamily.py)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_NAME = "rotorbench_tests_logfamily"
if _NAME not in sys.modules:  # tests use importlib mode: load the helper by path
    _spec = importlib.util.spec_from_file_location(_NAME, Path(__file__).with_name("logfamily.py"))
    assert _spec is not None and _spec.loader is not None
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules[_NAME] = _mod
    _spec.loader.exec_module(_mod)


@pytest.fixture(scope="session")
def logfamily():
    return sys.modules[_NAME]
