"""VESC USB/UART backend end to end against the simulated VESC on a pseudo-terminal, in a
process of its own as a real VESC's firmware is."""

from __future__ import annotations

import time

import pytest

pytest.importorskip("serial")

from rotorbench_tests_expected_protocol import wait_for

from drivers.backends.serial_link import open_port
from drivers.backends.vesc_uart import (
    VescUartEsc,
    VescUartLink,
    VescUartSettings,
    VescUartTelemetry,
)
from drivers.contracts import Esc, Sensor
from drivers.errors import DeviceError
from drivers.wire_sim.vesc import LinearVescMotor, VescCommand
from drivers.wire_sim.vesc_uart import SimVescUart
from drivers.wire_sim.world_process import Remote, WorldProcess, one_device

MOTOR = LinearVescMotor(70_000.0, motor_current_per_duty_a=20.0, input_current_per_duty_a=10.0,
                        voltage_in_v=12.3, temp_fet_c=30.0, temp_motor_c=35.0)


@pytest.fixture
def vesc():
    """The simulated VESC in its process (a ``Remote``: ``sim.get("command")`` reads it
    there) and the host's link on its pty."""
    world = WorldProcess(one_device, SimVescUart, {"model": MOTOR, "controller_id": 5},
                         name="sim-vesc-uart")
    sim = world.remote("device")
    port = open_port(sim.get("path"), 115200)
    link = VescUartLink(port, "vesc", timeout_s=0.5)
    yield sim, link
    port.close()
    world.close()


def test_throttle_to_duty_and_telemetry(vesc):
    sim, link = vesc
    esc = VescUartEsc(link, VescUartSettings(keepalive_s=0.05))
    tel = VescUartTelemetry(link, pole_pairs=7, rate_hz=100.0)
    assert isinstance(esc, Esc) and isinstance(tel, Sensor)
    assert tel.describe().extra["controller_id"] == 5
    esc.arm()
    assert wait_for(lambda: sim.get("command") == VescCommand("current", 0.0))  # idle: no torque
    esc.set_pulse_us(1500)
    assert wait_for(lambda: sim.get("command") == VescCommand("duty", 0.5))
    time.sleep(0.1)
    b = tel.read_block()
    assert len(b) >= 5 and b.values["rpm"][-1] == pytest.approx(70_000 * 0.5 / 7)
    assert b.values["voltage_v"][-1] == pytest.approx(12.3)
    esc.close()
    tel.close()
    assert wait_for(lambda: sim.get("command") == VescCommand("current", 0.0))


def commanding(vesc, host_timeout_s: float) -> tuple[Remote, VescUartEsc]:
    """The VESC's own timeout at 0.2 s and the host armed at duty 0.8, kept alive every
    0.05 s until it has made no call for ``host_timeout_s``."""
    sim, link = vesc
    sim.set("timeout_s", 0.2)
    esc = VescUartEsc(link, VescUartSettings(keepalive_s=0.05, host_timeout_s=host_timeout_s))
    esc.arm()
    esc.set_pulse_us(1800)
    return sim, esc


def test_keepalive_holds_the_command_past_the_vesc_timeout(vesc):
    sim, esc = commanding(vesc, host_timeout_s=1.0)
    time.sleep(0.5)  # the host keeps commanding inside its own timeout: no release
    assert sim.get("timeouts") == 0 and sim.get("command").kind == "duty"
    esc.close()


def test_stalled_host_lets_the_vesc_release_the_motor(vesc):
    sim, esc = commanding(vesc, host_timeout_s=0.1)
    assert wait_for(lambda: esc.host_stalled, 1.0)  # the host went silent: one stop sent
    assert wait_for(lambda: sim.get("command") == VescCommand("current", 0.0))
    esc.close()


def test_silent_vesc_is_a_device_error(vesc):
    sim, link = vesc
    sim.port.disconnect()
    with pytest.raises(DeviceError, match="no GET_VALUES reply"):
        VescUartTelemetry(link, pole_pairs=7)
    with pytest.raises(DeviceError, match="keepalive_s must be below"):
        VescUartEsc(link, VescUartSettings(keepalive_s=1.0))
