"""Rig files a propulsion command cannot use: garbage bytes, an IMU-bench rig."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import RIGS, run_bad


def test_rig_file_or_thrust_map_with_garbage_bytes(tmp_path: Path, capsys,
                                                   fixtures_dir: Path) -> None:
    """Bytes that are not UTF-8 ended in a UnicodeDecodeError traceback."""
    garbage = b"\xac\x00\xff\xfe garbage"
    rig = tmp_path / "rig.toml"
    rig.write_bytes(garbage)
    for argv in (["step", "--dry-run"], ["check"]):
        err = run_bad(capsys, *argv, "--rig", str(rig))
        assert f"{rig}: not valid TOML: 'utf-8' codec can't decode" in err
    text = (RIGS / "sim.toml").read_text()
    rig.write_text(text)
    (tmp_path / "sim.thrust_map.csv").write_bytes(garbage)
    err = run_bad(capsys, "step", "--dry-run", "--rig", str(rig))
    assert "sim.thrust_map.csv: cannot read thrust map" in err


@pytest.mark.parametrize("command", ["step", "sweep"])
def test_imu_rig_given_to_a_propulsion_command(capsys, fixtures_dir: Path,
                                               command: str) -> None:
    """It said 'hexapod: unknown key; expected one of rig, devices, ...'. (``check``
    checks IMU-bench rigs: tests/bench/commands/test_check_imu_rig.py.)"""
    rig = RIGS / "sim-imu.toml"
    err = run_bad(capsys, command, "--rig", str(rig), "--dry-run")
    assert 'kind = "imu": an IMU-bench rig' in err and "rotorbench calibrate" in err
