"""``rotorbench check --deep``: the bring-up report at rest, printed, as JSON, saved beside
the rig file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from bench.cli import main

RIGS = Path(__file__).resolve().parents[3] / "bench" / "data" / "rigs"


def _copy(tmp_path: Path, name: str) -> Path:
    shutil.copy(RIGS / "sim.thrust_map.csv", tmp_path)
    return Path(shutil.copy(RIGS / f"{name}.toml", tmp_path))


def test_deep_report_of_the_simulated_rig(tmp_path, capsys):
    rig = _copy(tmp_path, "sim")
    assert main(["check", "--deep", "--rig", str(rig), "--seconds", "1"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == f"saved {tmp_path / 'sim.bringup.json'}"
    report = json.loads((tmp_path / "sim.bringup.json").read_text())
    dev = {d["role"]: d for d in report["devices"]}
    assert list(dev) == ["esc", "load_cell", "power", "rpm"]
    assert dev["esc"]["limits"]["throttle_us"] == {"device": [1000.0, 2000.0], "rig": 2000.0}
    lc = dev["load_cell"]
    assert lc["rate_hz"] == pytest.approx(25_000, rel=0.02) and lc["dropped"] == 0
    assert lc["limits"]["thrust_n"]["rig"] == 7.0 and lc["limits"]["thrust_n"]["device"]
    # at rest: the noise floor is the sensor's own noise, not zero, and small
    assert 0 < lc["noise"]["thrust_n"]["rms"] < 0.1
    assert abs(dev["power"]["noise"]["current_a"]["mean"]) < 0.5  # current offset at rest
    assert dev["rpm"]["noise"]["rpm"] == {"mean": 0.0, "rms": 0.0}  # not spinning
    assert dev["load_cell"]["skew_s"] == 0.0


def test_deep_report_over_the_wire_as_json(tmp_path, capsys):
    rig = _copy(tmp_path, "sim-vesc-uart")
    save = tmp_path / "bringup" / "report.json"
    save.parent.mkdir()
    assert main(["check", "--deep", "--json", "--rig", str(rig), "--seconds", "1",
                 "--save", str(save)]) == 0
    lines = capsys.readouterr().out.splitlines()
    devices = [json.loads(x) for x in lines[:-1]]
    assert [d["role"] for d in devices] == ["esc", "load_cell", "power", "rpm"]
    assert devices[0]["identity"]["model"] == "VESC (USB/UART)"
    assert devices[0]["identity"]["dead_host_s"] == 1.0
    power = devices[2]
    assert power["identity"]["controller_id"] == 0 and power["stated_rate_hz"] == 100.0
    assert 50 < power["rate_hz"] < 110  # GET_VALUES polled at 100 Hz on a loaded host
    assert power["noise"]["voltage_v"]["mean"] == pytest.approx(11.1, abs=0.5)
    assert json.loads(save.read_text())["devices"] == devices


def test_deep_report_of_an_imu_bench_reads_the_controller(tmp_path, capsys):
    save = tmp_path / "imu.bringup.json"
    assert main(["check", "--deep", "--rig", str(RIGS / "sim-imu-tcp.toml"), "--seconds", "1",
                 "--save", str(save)]) == 0
    out = capsys.readouterr().out
    assert "controller {" in out
    dev = {d["role"]: d for d in json.loads(save.read_text())["devices"]}
    assert list(dev) == ["hexapod", "imu", "reference_imu"]
    hexapod = dev["hexapod"]
    assert hexapod["identity"]["model"].startswith("C-887")
    # the motion limits the controller reports against the rig file's, and its state
    # read before any motion (SVO?, FRF?, TMN?, TMX?)
    assert hexapod["limits"]["velocity_m_s"] == {"device": 0.6, "rig": 0.6}
    ctl = hexapod["controller"]
    assert all(ctl["servo"].values()) and all(ctl["referenced"].values())
    assert ctl["travel"]["X"] == pytest.approx([-0.25, 0.25])
    imu = dev["imu"]
    assert imu["rate_hz"] == pytest.approx(100, rel=0.1) and imu["dropped"] == 0
    lim = imu["limits"]["imu_gyro_x_rad_s"]
    assert lim["rig"] == pytest.approx(lim["device"][1])  # datasheet range = device range
    assert abs(imu["noise"]["imu_acc_z_m_s2"]["mean"] - 9.81) < 0.2  # at rest, level


def test_deep_refuses_bad_seconds(tmp_path, capsys):
    rig = _copy(tmp_path, "sim")
    assert main(["check", "--deep", "--rig", str(rig), "--seconds", "0"]) == 2
    assert "--seconds" in capsys.readouterr().err


def test_deep_save_creates_its_folder(tmp_path, capsys, monkeypatch):
    """The docs/devices.md line `check --deep ... --save out/deep/imu.json`
    with out/deep missing ended in a FileNotFoundError after listening."""
    monkeypatch.chdir(tmp_path)
    assert main(["check", "--deep", "--seconds", "1", "--rig", str(RIGS / "sim-imu-tcp.toml"),
                 "--save", "out/deep/imu.json"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "saved out/deep/imu.json"
    assert json.loads((tmp_path / "out" / "deep" / "imu.json").read_text())["devices"]


def test_deep_save_below_a_file_is_refused_before_listening(tmp_path, capsys):
    (tmp_path / "out").write_text("a file")
    rig = _copy(tmp_path, "sim")
    assert main(["check", "--deep", "--rig", str(rig), "--seconds", "1",
                 "--save", str(tmp_path / "out" / "deep" / "r.json")]) == 2
    err = capsys.readouterr().err
    assert "--save" in err and "is a file, not a folder" in err and len(err.splitlines()) == 1
