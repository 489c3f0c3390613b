"""Rigs of wire-level simulated devices: real backends against peers driven by the sim plant."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bench.rig.rig import load_rig
from drivers.contracts import Esc, Sensor
from drivers.factory import open_rig

pytest.importorskip("serial")
pytest.importorskip("can")

rigs = sys.modules["rotorbench_tests_factory_rigs"]  # factory_rigs.py, by conftest

RIGS = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs"


def _spin(r, pulse_us: float, seconds: float) -> dict:
    """Command ``pulse_us`` every 20 ms for ``seconds``; the blocks read meanwhile."""
    got: dict[str, list] = {role: [] for role in r.sensors}
    r.esc.arm()
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        r.esc.set_pulse_us(pulse_us)
        r.clock.sleep(0.02)
        for role, s in r.sensors.items():
            got[role].append(s.read_block())
    return got


def _last(blocks, name):
    vals = np.concatenate([b.values[name] for b in blocks if len(b)])
    return float(np.mean(vals[-5:]))


@pytest.mark.parametrize("name", ["sim-serial", "sim-can"])
def test_wire_rig_commands_reach_the_plant_and_sensors_report_it(name):
    with open_rig(load_rig(RIGS / f"{name}.toml")) as r:
        assert isinstance(r.esc, Esc)
        assert all(isinstance(s, Sensor) for s in r.sensors.values())
        assert [c.name for c in r.sensors["power"].describe().channels] == ["current_a",
                                                                           "voltage_v"]
        got = _spin(r, 1500.0, 1.0)
        truth = r.truth()
        assert truth.steady_thrust_n(1500.0) == pytest.approx(truth.thrust_n, rel=0.02)
        # the load cell shows the plant's thrust (plus the bridge's zero offset, ~0.12 N)
        assert _last(got["load_cell"], "thrust_n") == pytest.approx(truth.thrust_n, abs=0.2)
        assert _last(got["rpm"], "rpm") == pytest.approx(truth.rpm, rel=0.02)
        assert _last(got["power"], "current_a") == pytest.approx(truth.current_bus_a, abs=0.25)
        assert _last(got["power"], "voltage_v") == pytest.approx(truth.voltage_bus_v, abs=0.1)
        t = np.concatenate([b.t_s for b in got["load_cell"]])
        assert np.all(np.diff(t) >= 0) and t.size > 150  # 250 lines/s from the board


def test_dronecan_esc_on_the_virtual_bus(tmp_path):
    esc = 'url = "can://sim/bus"\noptions = { protocol = "dronecan", esc_index = 2 }'
    tel = 'url = "can://sim/bus"\noptions = { protocol = "dronecan", esc_index = 2 }'
    board = 'url = "serial://sim/loadcell"'
    path = rigs.write(tmp_path, {"esc": esc, "power": tel, "rpm": tel, "load_cell": board},
                      RIGS / "sim-can.toml")
    with open_rig(load_rig(path)) as r:
        assert r.esc.describe().extra["esc_index"] == 2
        got = _spin(r, 1600.0, 0.8)
        truth = r.truth()
        assert truth.steady_thrust_n(1600.0) == pytest.approx(truth.thrust_n, rel=0.02)
        assert _last(got["rpm"], "rpm") == pytest.approx(truth.rpm, abs=2)  # whole rpm
    assert r.wire is not None and not r.wire.peers  # peers stopped on close


def test_close_leaves_the_esc_idle_and_stops_every_peer():
    r = open_rig(load_rig(RIGS / "sim-serial.toml"))
    _spin(r, 1400.0, 0.3)
    plant = r.wire.plant
    r.close()
    assert plant.pulse_us == 1000.0 and plant.idle_since() is not None
    assert not r.wire.peers
    r.close()  # twice is fine
