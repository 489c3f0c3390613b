"""DroneCAN ESC backend end to end against a simulated ESC node, in a process of its own
as a real ESC's firmware is, on a CAN cable (a loopback socket) to python-can's virtual bus
here."""

from __future__ import annotations

import time

import pytest

can = pytest.importorskip("can")

from rotorbench_tests_expected_protocol import wait_for  # noqa: E402

from drivers.backends.dronecan_esc import (  # noqa: E402
    DroneCanEsc,
    DroneCanEscSettings,
    DroneCanEscTelemetry,
)
from drivers.codecs import dronecan as dc  # noqa: E402
from drivers.contracts import Esc, Sensor  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402
from drivers.wire_sim.dronecan_esc import LinearEscMotor, SimDroneCanEsc  # noqa: E402

MOTOR = LinearEscMotor(dc.EscStatus(0, 16.0, 0.0, 300.0, 0, 0, 2), rpm_per_raw=2.0,
                       current_at_max_a=20.0)


@pytest.fixture
def rig(can_bench):
    """``make(...)``: the simulated ESC in its process (a ``Remote``: ``sim.get("raw")``
    reads it there), the ESC backend and the telemetry on the host's bus."""

    def make(**kw):
        sim = can_bench.node(SimDroneCanEsc, {"node_id": 21, "esc_index": 2,
                                                   "model": MOTOR, **kw}, "sim-dronecan")
        esc = DroneCanEsc(can_bench.host, DroneCanEscSettings(esc_index=2, period_s=0.02,
                                                              host_timeout_s=0.15))
        tel = DroneCanEscTelemetry(can_bench.host, 2, stale_s=0.2)
        can_bench.on_close(esc.close, tel.close)
        return sim, esc, tel

    return make


def test_command_and_status(rig):
    sim, esc, tel = rig()
    assert isinstance(esc, Esc) and isinstance(tel, Sensor)
    esc.arm()
    esc.set_pulse_us(1500)
    assert wait_for(lambda: sim.get("raw") == 4096)
    assert sim.get("commands_seen")[-1] == (0, 0, 4096)  # other slots stay at 0 = stop
    time.sleep(0.1)
    b = tel.read_block()
    assert b.values["rpm"][-1] == 8192
    assert b.values["temp_esc_c"][-1] == pytest.approx(300.0 - 273.15)
    assert b.values["voltage_v"][-1] == 16.0
    assert wait_for(lambda: sim.get("host_node_status") >= 1)


def test_stalled_host_and_disarm_stop_the_esc(rig):
    sim, esc, _ = rig(timeout_s=5.0)
    esc.arm()
    esc.set_pulse_us(2000)
    assert wait_for(lambda: sim.get("raw") == 8191)
    assert wait_for(lambda: sim.get("raw") == 0, timeout_s=0.5)  # host silent > 0.15 s
    assert esc.host_stalled
    esc.set_pulse_us(1250)
    assert wait_for(lambda: sim.get("raw") == dc.raw_from_fraction(0.25))
    esc.disarm()
    assert wait_for(lambda: sim.get("raw") == 0)


def test_lost_node_is_detected(rig):
    sim, _, tel = rig()
    assert wait_for(lambda: len(tel.read_block()) > 0)
    sim.disconnect()
    time.sleep(0.3)
    with pytest.raises(DeviceError, match=r"no esc\.Status"):
        tel.read_block()
