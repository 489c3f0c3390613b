"""A dead host stops the motor: each ESC backend, host killed with kill -9 mid-step.

The host (the real backend) runs in a child process, the simulated device in another
(``drivers.wire_sim.world_process``, as its firmware runs on its own processor), which
reports when its motor is released. CAN frames cross from the host through a loopback TCP
socket standing in for the CAN adapter onto a python-can ``virtual`` bus here, and on to
the device's process by its CAN cable (``can_socket.node_process``): when the host dies,
its frames stop, as they would on a real bus. Serial devices share a pseudo-terminal, as a
USB cable would.

Bounds: VESC, its command timeout (1 s firmware default, protocols.md §3.2); DroneCAN,
the ESC's own command timeout (firmware specific; the simulated one is 0.5 s). MSP motor
test: Betaflight and INAV keep the last SET_MOTOR value (docs/protocols.md), and so does
the simulated flight controller; the test shows it, and the backend refuses to drive it
for a propellers-on run.
"""

from __future__ import annotations

import itertools
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

can = pytest.importorskip("can")

from drivers.backends.can_link import CanLink  # noqa: E402
from drivers.codecs import dronecan as dc  # noqa: E402
from drivers.wire_sim.can_socket import node_process  # noqa: E402
from drivers.wire_sim.dronecan_esc import LinearEscMotor, SimDroneCanEsc  # noqa: E402
from drivers.wire_sim.vesc import LinearVescMotor, SimVescDevice  # noqa: E402
from drivers.wire_sim.world_process import Constant, WorldProcess, one_device  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
_channels = itertools.count()

# The child: the real backend over a "CAN adapter" that writes each frame as a line
# "<id hex> <data hex>" to a loopback socket; commands like a step's loop (every 10 ms).
CHILD = r"""
import socket, sys, time
from drivers.codecs.can_log import CanFrame

class SocketLink:
    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port))
    def send(self, frame: CanFrame) -> None:
        self.sock.sendall(f"{frame.arbitration_id:x} {frame.data.hex()}\n".encode())
    def subscribe(self, cb): pass
    def unsubscribe(self, cb): pass

link = SocketLink(int(sys.argv[2]))
if sys.argv[1] == "vesc":
    from drivers.backends.vesc import VescEsc, VescEscSettings
    esc = VescEsc(link, VescEscSettings(controller_id=1))
else:
    from drivers.backends.dronecan_esc import DroneCanEsc, DroneCanEscSettings
    esc = DroneCanEsc(link, DroneCanEscSettings(esc_index=0))
esc.arm()
while True:
    esc.set_pulse_us(1500.0)
    time.sleep(0.01)
"""


class Bridge:
    """Receives the child's frames and puts them on this process's virtual bus."""

    def __init__(self, channel: str) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.bus = can.Bus(channel, interface="virtual")
        self.last_rx = 0.0
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        conn, _ = self.server.accept()
        with conn, conn.makefile("r") as lines:
            for line in lines:
                ident, data = line.split()
                self.bus.send(can.Message(arbitration_id=int(ident, 16),
                                          data=bytes.fromhex(data), is_extended_id=True))
                self.last_rx = time.monotonic()

    def close(self) -> None:
        self.server.close()
        self._thread.join(timeout=2)
        self.bus.shutdown()


def _kill_mid_step(kind: str, bridge: Bridge, running, released, bound_s: float) -> float:
    """Start the host, wait until the motor runs, kill -9, return kill -> release (s)."""
    script_env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", CHILD, kind, str(bridge.port)],
                             env=script_env, cwd=REPO)
    try:
        deadline = time.monotonic() + 30.0
        while not running():
            assert child.poll() is None, "the host ended before it could be killed"
            assert time.monotonic() < deadline, "the motor never ran"
            time.sleep(0.01)
        time.sleep(0.3)  # mid-step, the motor running on the host's commands
        assert running()
        child.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    while not released():
        assert time.monotonic() - killed < bound_s + 2.0, "the motor never stopped"
        time.sleep(0.002)
    return time.monotonic() - killed


VESC_MOTOR = LinearVescMotor(70_000.0, motor_current_per_duty_a=0.0,
                             input_current_per_duty_a=0.0, voltage_in_v=12.0,
                             temp_fet_c=25.0, temp_motor_c=25.0)


@pytest.mark.slow
def test_kill_9_of_the_host_releases_the_vesc_within_its_timeout():
    channel = f"dead-vesc-{next(_channels)}-{os.getpid()}"
    bridge = Bridge(channel)
    link = CanLink(can.Bus(channel, interface="virtual"), "device side")
    vesc, stop = node_process(link, SimVescDevice, {
        "controller_id": 1, "model": VESC_MOTOR, "status_rate_hz": 200.0}, "sim-vesc")
    try:
        took = _kill_mid_step(
            "vesc", bridge,
            running=lambda: (c := vesc.get("command")).kind == "duty" and c.value > 0.4,
            released=lambda: vesc.get("command").kind == "release", bound_s=1.0)
        timeouts = vesc.get("timeouts")
    finally:
        stop()
        link.close()
        link.bus.shutdown()
        bridge.close()
    assert timeouts == 1  # released by its own command timeout, nothing else
    assert took <= 1.0 + 0.05, f"VESC released {took:.3f} s after the kill (bound 1 s)"
    print(f"VESC (CAN): motor released {took:.3f} s after kill -9 (bound 1.0 s + 5 ms tick)")


@pytest.mark.slow
def test_kill_9_of_the_host_stops_the_dronecan_esc_within_its_timeout():
    channel = f"dead-dronecan-{next(_channels)}-{os.getpid()}"
    bridge = Bridge(channel)
    link = CanLink(can.Bus(channel, interface="virtual"), "device side")
    model = LinearEscMotor(dc.EscStatus(0, 12.0, 0.0, 300.0, 0, 0, 0), rpm_per_raw=1.0)
    esc, stop = node_process(link, SimDroneCanEsc, {
        "node_id": 21, "esc_index": 0, "model": model, "status_period_s": 0.005,
        "timeout_s": 0.5}, "sim-dronecan")
    try:
        took = _kill_mid_step("dronecan", bridge, running=lambda: esc.get("raw") > 4000,
                              released=lambda: esc.get("raw") == 0, bound_s=0.5)
        timeouts = esc.get("timeouts")
    finally:
        stop()
        link.close()
        link.bus.shutdown()
        bridge.close()
    assert timeouts == 1
    assert took <= 0.5 + 0.05, f"DroneCAN ESC stopped {took:.3f} s after the kill (bound 0.5 s)"
    print(f"DroneCAN: ESC stopped {took:.3f} s after kill -9 (bound 0.5 s + 5 ms tick)")



MSP_CHILD = r"""
import sys, time
from drivers.backends.msp_fc import MspClient, MspMotorEsc
from drivers.backends.serial_link import open_port

client = MspClient(open_port(sys.argv[1], 115200), "fc", timeout_s=0.5)
esc = MspMotorEsc(client, 0, propellers_off=True)
esc.arm()
while True:
    esc.set_pulse_us(1500.0)
    time.sleep(0.01)
"""


@pytest.mark.slow
def test_kill_9_of_the_host_leaves_the_msp_motor_test_running_as_betaflight_does():
    """Why the MSP backend is refused for propellers-on runs: nothing stops the motor."""
    pytest.importorskip("serial")
    from drivers.wire_sim.msp_fc import SimFlightController

    world = WorldProcess(one_device, SimFlightController, {
        "imu": Constant(((0.0, 0.0, 9.8), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))}, name="sim-fc")
    fc = world.remote("device")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", MSP_CHILD, fc.get("path")], env=env,
                             cwd=REPO)
    try:
        deadline = time.monotonic() + 30.0
        while fc.motors()[0] != 1500:
            assert child.poll() is None and time.monotonic() < deadline
            time.sleep(0.01)
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
        time.sleep(1.5)  # longer than every other backend's bound
        assert fc.motors()[0] == 1500  # still spinning: the FC holds the last value
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
        world.close()


VESC_UART_CHILD = r"""
import sys, time
from drivers.backends.serial_link import open_port
from drivers.backends.vesc_uart import VescUartEsc, VescUartLink, VescUartSettings

esc = VescUartEsc(VescUartLink(open_port(sys.argv[1], 115200), "vesc"), VescUartSettings())
esc.arm()
while True:
    esc.set_pulse_us(1500.0)
    time.sleep(0.01)
"""


@pytest.mark.slow
def test_kill_9_of_the_host_releases_the_vesc_on_usb_within_its_timeout():
    pytest.importorskip("serial")
    from drivers.wire_sim.vesc_uart import SimVescUart

    world = WorldProcess(one_device, SimVescUart, {"model": VESC_MOTOR}, name="sim-vesc-uart")
    vesc = world.remote("device")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", VESC_UART_CHILD, vesc.get("path")],
                             env=env, cwd=REPO)
    try:
        deadline = time.monotonic() + 30.0
        while not ((c := vesc.get("command")).kind == "duty" and c.value > 0.4):
            assert child.poll() is None and time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(0.3)
        child.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        child.wait(timeout=10)
        while vesc.get("command").kind != "release":
            assert time.monotonic() - killed < 3.0, "the VESC never released the motor"
            time.sleep(0.002)
        took = time.monotonic() - killed
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
        timeouts = vesc.get("timeouts")
        world.close()
    assert timeouts == 1
    assert took <= 1.0 + 0.05, f"VESC released {took:.3f} s after the kill (bound 1 s)"
    print(f"VESC (USB/UART): motor released {took:.3f} s after kill -9 (bound 1.0 s)")
