"""Fixtures for the bench tests: the fakes module and a fake rig."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_NAME = "rotorbench_tests_bench_fakes"
if _NAME not in sys.modules:
    _spec = importlib.util.spec_from_file_location(_NAME, Path(__file__).with_name("fakes.py"))
    assert _spec is not None and _spec.loader is not None
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules[_NAME] = _mod
    _spec.loader.exec_module(_mod)
fakes_module = sys.modules[_NAME]


@pytest.fixture
def fakes():
    return fakes_module


@pytest.fixture
def fake_rig():
    return fakes_module.FakeRig()


def _write_truth_map(rig_path: Path) -> None:
    """A static map for a copied sim rig from the plant's own steady state (no sweep)."""
    import numpy as np

    from bench.rig import load_rig, save_thrust_map
    from drivers.factory import open_rig

    rig = load_rig(rig_path)
    devices = open_rig(rig)
    try:
        truth = devices.truth()
        grid = np.arange(1100.0, 1951.0, 10.0)
        thrust = np.array([truth.steady_thrust_n(u) for u in grid])
    finally:
        devices.close()
    save_thrust_map(rig, grid.tolist(), thrust.tolist())


@pytest.fixture
def sim_rig_path(tmp_path: Path) -> Path:
    """A copy of the default sim rig in tmp_path, without a thrust map."""
    from bench.rig import default_rig_path

    target = tmp_path / "rig" / "sim.toml"
    target.parent.mkdir()
    target.write_text(default_rig_path().read_text(encoding="utf-8"), encoding="utf-8")
    (target.parent / "sim.thrust_map.csv").unlink(missing_ok=True)
    return target


@pytest.fixture
def sim_rig_mapped_path(sim_rig_path: Path) -> Path:
    """A copy of the default sim rig with a static map taken from the plant's truth."""
    _write_truth_map(sim_rig_path)
    return sim_rig_path
