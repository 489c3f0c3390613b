"""Fixtures for the analysis tests: the synthetic esc_test-family log writer (logfamily.py)."""

from __future__ import annotations

import sys

import pytest

_NAME = "rotorbench_tests_logfamily"  # logfamily.py, loaded by tests/conftest.py


@pytest.fixture(scope="session")
def logfamily():
    return sys.modules[_NAME]
