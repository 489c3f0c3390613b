"""The device factory's URL and option checks: errors name the rig file, device and field."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

from bench.cli import main
from bench.rig.rig import load_rig
from drivers.device_options import parse_device
from drivers.errors import DeviceError
from drivers.factory import open_rig

rigs = sys.modules["rotorbench_tests_factory_rigs"]  # factory_rigs.py, by conftest

SIM_SERIAL = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs" / "sim-serial.toml"


class Dev:
    def __init__(self, url, options=None, channel="", calibration=None):
        self.url, self.options, self.channel = url, options or {}, channel
        self.calibration = calibration or {}


def test_query_and_options_merge_and_must_agree():
    spec = parse_device("rig.toml", "esc", Dev("serial:///dev/ttyUSB0?baud=115200&protocol=msp",
                                               {"motor": 2}))
    assert (spec.scheme, spec.host, spec.path) == ("serial", "", "/dev/ttyUSB0")
    assert spec.integer("baud") == 115200 and spec.text("protocol") == "msp"
    assert spec.integer("motor") == 2
    with pytest.raises(DeviceError, match=r"rig.toml: \[devices.esc\] options.baud: 9600 "
                                          r"disagrees with the URL's baud=115200"):
        parse_device("rig.toml", "esc", Dev("serial:///dev/x?baud=115200", {"baud": 9600}))
    spec = parse_device("rig.toml", "esc", Dev("serial://COM3"))
    assert spec.host + spec.path == "com3"  # Windows port names are case-insensitive


def _open(tmp_path, devices, base=None):
    return open_rig(load_rig(rigs.write(tmp_path, devices, base)))


@pytest.mark.parametrize(("body", "match"), [
    ('url = "serial://sim/msp"\noptions = { motr = 1, propellers_off = true }',
     r"\[devices.esc\] options.motr: unknown option for this device \(known: .*motor"),
    ('url = "serial://sim/msp"\noptions = { motor = 9 }', r"options.motor: 9 outside 0..7"),
    ('url = "serial://sim/msp"\noptions = { control = "motor_test" }',
     r"\[devices.esc\] .*propellers-on run: Betaflight and INAV"),
    ('url = "serial://sim/msp"',  # propellers on: the RC path, which this FC cannot serve
     r"\[devices.esc\] .*refused MSP_FAILSAFE_CONFIG: the RC control path needs Betaflight"),
    ('url = "serial://sim/msp"\noptions = { control = "pwm" }',
     r"options.control: .*rc, motor_test"),
    ('url = "serial://sim/msp"\noptions = { propellers_off = "yes" }',
     r"options.propellers_off: expected true or false"),
    ('url = "serial://sim/msp"\noptions = { protocol = "loadcell" }',
     r"options.protocol: 'loadcell' cannot drive an ESC"),
    ('url = "can://sim/bench"\noptions = { protocol = "vesc" }',
     r"\[devices.esc\] options.controller_id: missing"),
    ('url = "can://sim/bench"\noptions = { protocol = "canopen" }',
     r"options.protocol: 'canopen': expected one of vesc, dronecan"),
    ('url = "can://socketcan"\noptions = { protocol = "vesc", controller_id = 1 }',
     r"expected can://<interface>/<channel>"),
    ('url = "tcp://localhost:50000"', r"\[devices.esc\] .*PI GCS hexapod"),
    ('url = "serial:///dev/rotorbench-no-such-port"',
     r"\[devices.esc\] 'serial:///dev/rotorbench-no-such-port': .*cannot open"),
])
def test_bad_device_tables_name_file_device_and_field(tmp_path, body, match):
    devices = {"esc": body}
    for role in ("load_cell", "power", "rpm"):
        devices[role] = 'url = "serial://sim/loadcell"'
    with pytest.raises(DeviceError, match=match) as err:
        _open(tmp_path, devices)
    assert str(err.value).startswith(str(tmp_path / "rig.toml"))


def test_roles_sharing_a_board_must_agree_and_one_port_serves_one_protocol(tmp_path):
    board = 'url = "serial://sim/loadcell"\noptions = {{ stale_s = {} }}'
    devices = {"esc": 'url = "serial://sim/msp"\noptions = { propellers_off = true }',
               "load_cell": board.format(0.3),
               "power": board.format(0.3), "rpm": board.format(0.5)}
    with pytest.raises(DeviceError, match=r"\[devices.rpm\] options.stale_s: roles sharing"):
        _open(tmp_path, devices)
    devices["rpm"] = ('url = "serial://sim/loadcell"\n'
                      'options = { stale_s = 0.3, columns = ["rpm", "volts"] }')
    with pytest.raises(DeviceError, match=r"rpm: .* has no column 'volts'"):
        _open(tmp_path, devices)


def test_sim_devices_do_not_mix_with_hardware(tmp_path):
    with pytest.raises(DeviceError, match=r"\[devices.esc\] url 'sim://esc': .* cannot be mixed"):
        _open(tmp_path, {"load_cell": 'url = "serial://sim/loadcell"'})


def test_a_missing_library_is_a_clear_error(tmp_path, monkeypatch):
    real = importlib.import_module

    def no_can(name, *a, **k):
        if name == "drivers.backends.can_link":
            raise ModuleNotFoundError("No module named 'can'")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", no_can)
    body = 'url = "can://socketcan/can0"\noptions = { protocol = "vesc", controller_id = 1 }'
    with pytest.raises(DeviceError, match=r"\[devices.esc\] url 'can://socketcan/can0': the "
                                          r"can:// backend needs the Python package python-can"):
        _open(tmp_path, {"esc": body, **dict.fromkeys(("load_cell", "power", "rpm"),
                                                       'url = "serial://sim/loadcell"')})


def test_cli_prints_one_line_and_exits_2(tmp_path, capsys):
    text = SIM_SERIAL.read_text().replace("motor = 0", "motor = 0, bogus = 1")
    rig = tmp_path / "rig.toml"
    rig.write_text(text.replace('file = "sim.thrust_map.csv"', 'file = "none.csv"'))
    code = main(["step", "--rig", str(rig), "--sequence", "step1", "--repeats", "1",
                 "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.startswith("rotorbench: error:")]
    assert len(lines) == 1 and "options.bogus: unknown option" in lines[0]
    assert "Traceback" not in err


@pytest.mark.skipif(sys.platform != "linux", reason="pty paths")
def test_check_names_the_failing_device(tmp_path, capsys):
    text = SIM_SERIAL.read_text().replace("motor = 0", "motor = 0, bogus = 1")
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    assert main(["check", "--rig", str(rig), "--timeout", "0.5"]) == 2
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("esc") and "FAIL" in out[0] and "options.bogus" in out[0]


def test_open_hexapod_over_tcp_and_bad_urls():
    from drivers.factory import open_hexapod
    from drivers.wire_sim.pi_hexapod import SimPiController
    from drivers.wire_sim.world_process import WorldProcess, one_device

    with pytest.raises(DeviceError, match=r"hexapod: 'serial://x': expected tcp://<host>"):
        open_hexapod("serial://x")
    world = WorldProcess(one_device, SimPiController, {}, name="sim-pi")
    try:
        host, port = world.remote("device").get("address")
        hexapod = open_hexapod(f"tcp://{host}:{port}")
        try:
            assert "C-887" in str(hexapod.identification)
        finally:
            hexapod.close()
    finally:
        world.close()
