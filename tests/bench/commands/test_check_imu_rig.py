"""``rotorbench check`` on IMU-bench rigs: every device answers through the IMU factory."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli import main
from bench.rig.rig import load_imu_rig
from drivers.check import hexapod_answer as _hexapod_answer
from drivers.contracts import Trajectory
from drivers.factory import open_rig
from drivers.hexapod_motions import gyro_sines

RIGS = Path(__file__).resolve().parents[3] / "bench" / "data" / "rigs"


@pytest.mark.parametrize("name", ["sim-imu", "sim-imu-tcp", "sim-imu-wire"])
def test_check_reports_every_device_of_the_imu_rigs(name: str) -> None:
    """As typed in a terminal of its own: the rates are the bench's, read in a process and
    session of its own (the wire rig at time scale 6 polls its MSP IMU 600 times a wall
    second; inside a test process, beside the suite's others, it read 36 of 100 Hz once)."""
    res = subprocess.run([sys.executable, "-m", "bench.cli", "check", "--rig",
                          str(RIGS / f"{name}.toml"), "--json", "--timeout", "5"],
                         capture_output=True, text=True, timeout=120, start_new_session=True)
    out = res.stdout
    assert res.returncode == 0, out + res.stderr
    lines = [json.loads(x) for x in out.splitlines()]
    assert [x["role"] for x in lines] == ["hexapod", "imu", "reference_imu"]
    assert all(x["ok"] for x in lines), out
    assert "at rest; stopped" in lines[0]["detail"]
    for x in lines[1:]:
        assert float(x["detail"].split(" samples/s")[0]) > 50  # 100 Hz IMUs


def test_check_exits_2_with_one_line_per_device_that_does_not_answer(tmp_path: Path,
                                                                      capsys) -> None:
    text = (RIGS / "sim-imu-wire.toml").read_text()
    text = text.replace('url = "tcp://sim"', 'url = "tcp://127.0.0.1:1"')
    text = text.replace("serial://sim/msp-imu", "serial:///dev/rotorbench-no-such-imu")
    text = text.replace("serial://sim/gx3", "serial:///dev/rotorbench-no-such-gx3")
    text = text.replace(", time_scale = 6.0", "")
    rig = tmp_path / "real-imu.toml"
    rig.write_text(text)
    assert main(["check", "--rig", str(rig), "--timeout", "1"]) == 2
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == ["hexapod", "imu", "reference_imu"]
    assert all(" FAIL " in ln for ln in lines)
    assert "127.0.0.1:1" in lines[0] and "no-such-imu" in lines[1] and "no-such-gx3" in lines[2]


def test_a_moving_hexapod_is_stopped_by_the_check() -> None:
    bench = open_rig(load_imu_rig(RIGS / "sim-imu.toml"))
    try:
        bench.hexapod.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
        bench.hexapod.start()
        bench.clock.sleep(1.0)
        assert bench.hexapod.is_moving()
        assert _hexapod_answer(bench.hexapod).endswith("was moving; stopped")
        assert not bench.hexapod.is_moving()
    finally:
        bench.close()
