"""Fixtures for the bench tests: the fakes module and a fake rig."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

fakes_module = sys.modules["rotorbench_tests_bench_fakes"]  # fakes.py, loaded by tests/conftest.py


def imported_run(tmp_path: Path) -> Path:
    """A small stand run imported from CSV (``rotorbench import``) under ``tmp_path``."""
    from bench.cli import main

    f = tmp_path / "stand.csv"
    rows = "\n".join(f"{i * 0.1:.1f},{1000 + 10 * i},{0.01 * i * i}" for i in range(40))
    f.write_text("t_s,throttle_us,thrust_n\n" + rows + "\n")
    run = tmp_path / "run"
    assert main(["import", str(f), "--format", "csv", "--out", str(run)]) == 0
    return run


def imu_log(path: Path) -> Path:
    """A half-second IMU log at rest (gravity on z) written to ``path``."""
    rows = "\n".join(f"{i * 0.01:.2f},0,0,0,0,0,9.81" for i in range(50))
    path.write_text("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,"
                    "acc_z_m_s2\n" + rows + "\n")
    return path


@pytest.fixture(scope="session")
def fakes():
    return fakes_module


@pytest.fixture
def fake_rig():
    return fakes_module.FakeRig()


@pytest.fixture
def sim_rig_path(tmp_path: Path) -> Path:
    """A copy of the default sim rig in tmp_path, without a thrust map."""
    from bench.rig.rig import default_rig_path

    target = tmp_path / "rig" / "sim.toml"
    target.parent.mkdir()
    target.write_text(default_rig_path().read_text(encoding="utf-8"), encoding="utf-8")
    (target.parent / "sim.thrust_map.csv").unlink(missing_ok=True)
    return target


@pytest.fixture
def sim_rig_mapped_path(sim_rig_path: Path) -> Path:
    """A copy of the default sim rig with a static map taken from the plant's truth."""
    fakes_module.write_truth_map(sim_rig_path)
    return sim_rig_path
