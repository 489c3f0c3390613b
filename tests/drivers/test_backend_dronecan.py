"""DroneCAN ESC backend end to end against a simulated ESC node on the virtual bus."""

from __future__ import annotations

import itertools
import time

import pytest

can = pytest.importorskip("can")

from rotorbench_tests_services import wait_until  # noqa: E402

from drivers.backends.can_link import CanLink  # noqa: E402
from drivers.backends.dronecan_esc import (  # noqa: E402
    DroneCanEsc,
    DroneCanEscSettings,
    DroneCanEscTelemetry,
)
from drivers.codecs import dronecan as dc  # noqa: E402
from drivers.contracts import Esc, Sensor  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402
from drivers.wire_sim.dronecan_esc import SimDroneCanEsc  # noqa: E402

_channels = itertools.count()


def model(_t, raw):
    return dc.EscStatus(0, 16.0, raw / 8191 * 20.0, 300.0, round(raw * 2), 0, 2)



@pytest.fixture
def rig():
    ch = f"dronecan-test-{next(_channels)}"
    buses = [can.Bus(interface="virtual", channel=ch) for _ in range(2)]
    host, dev = CanLink(buses[0], "host"), CanLink(buses[1], "esc-node")
    made = []

    def make(**kw):
        sim = SimDroneCanEsc(dev, node_id=21, esc_index=2, model=model, **kw).start()
        esc = DroneCanEsc(host, DroneCanEscSettings(esc_index=2, period_s=0.02,
                                                    host_timeout_s=0.15))
        tel = DroneCanEscTelemetry(host, 2, stale_s=0.2)
        made.extend([sim, esc, tel])
        return sim, esc, tel

    yield make
    for obj in reversed(made):
        (obj.stop if isinstance(obj, SimDroneCanEsc) else obj.close)()
    host.close()
    dev.close()
    for b in buses:
        b.shutdown()


def test_command_and_status(rig):
    sim, esc, tel = rig()
    assert isinstance(esc, Esc) and isinstance(tel, Sensor)
    esc.arm()
    esc.set_pulse_us(1500)
    assert wait_until(lambda: sim.raw == 4096)
    assert sim.commands_seen[-1] == (0, 0, 4096)  # other slots stay at 0 = stop
    time.sleep(0.1)
    b = tel.read_block()
    assert b.values["rpm"][-1] == 8192
    assert b.values["temp_esc_c"][-1] == pytest.approx(300.0 - 273.15)
    assert b.values["voltage_v"][-1] == 16.0
    assert wait_until(lambda: sim.host_node_status >= 1)


def test_stalled_host_and_disarm_stop_the_esc(rig):
    sim, esc, _ = rig(timeout_s=5.0)
    esc.arm()
    esc.set_pulse_us(2000)
    assert wait_until(lambda: sim.raw == 8191)
    assert wait_until(lambda: sim.raw == 0, timeout=0.5)  # host silent > 0.15 s
    assert esc.host_stalled
    esc.set_pulse_us(1250)
    assert wait_until(lambda: sim.raw == dc.raw_from_fraction(0.25))
    esc.disarm()
    assert wait_until(lambda: sim.raw == 0)


def test_lost_node_is_detected(rig):
    sim, _, tel = rig()
    assert wait_until(lambda: len(tel.read_block()) > 0)
    sim.disconnect()
    time.sleep(0.3)
    with pytest.raises(DeviceError, match=r"no esc\.Status"):
        tel.read_block()
