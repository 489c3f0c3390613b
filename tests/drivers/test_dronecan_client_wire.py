"""Other people's CAN clients against the simulated CAN devices (python-can ``virtual``).

The simulated ESC runs in a process of its own, as a real ESC's firmware does, on a CAN
cable (a loopback socket) bridged to the virtual bus here, and so does the simulated VESC.

* The ``dronecan`` package's own node (PyPI 1.0.27, protocols.md §4.3) broadcasts
  ``uavcan.equipment.esc.RawCommand`` and listens for ``esc.Status``: the simulated ESC
  follows the command and its Status decodes in dronecan's own DSDL types. dronecan's
  ``PythonCAN.receive`` passes ``timeout * 1000`` to python-can (§4.3 known bug), so
  ``spin`` is given a thousandth of the wait wanted; and its writer thread calls
  ``bus.flush_tx_buffer()``, which python-can's ``virtual`` bus does not implement
  (``NotImplementedError``, python-can 4.6), so the test gives the virtual bus a no-op one.
* Plain python-can sends the VESC frames of protocols.md §3.2 (its computed examples) to
  the simulated VESC and reads its STATUS broadcasts.
"""

from __future__ import annotations

import itertools
import os
import time

import pytest

can = pytest.importorskip("can")
dronecan = pytest.importorskip("dronecan")

from drivers.backends.can_link import CanLink  # noqa: E402
from drivers.codecs import dronecan as dc  # noqa: E402
from drivers.wire_sim.can_socket import node_process  # noqa: E402
from drivers.wire_sim.dronecan_esc import LinearEscMotor, SimDroneCanEsc  # noqa: E402
from drivers.wire_sim.vesc import LinearVescMotor, SimVescDevice, VescCommand  # noqa: E402

_channels = itertools.count()


def _channel(kind: str) -> str:
    return f"client-{kind}-{os.getpid()}-{next(_channels)}"


# dronecan's python-can driver always passes python-can's deprecated 'bustype' (its source)
@pytest.mark.filterwarnings("ignore:The 'bustype' argument is deprecated:DeprecationWarning")
def test_the_dronecan_node_drives_the_simulated_esc(monkeypatch):
    from can.interfaces.virtual import VirtualBus

    monkeypatch.setattr(VirtualBus, "flush_tx_buffer", lambda self: None, raising=False)
    channel = _channel("dronecan")
    link = CanLink(can.Bus(channel, interface="virtual"), "sim side")
    motor = LinearEscMotor(dc.EscStatus(7, 12.5, 3.25, 300.0, 0, 0, 2), rpm_per_raw=1.0)
    esc, stop = node_process(link, SimDroneCanEsc, {
        "node_id": 21, "esc_index": 2, "model": motor, "status_period_s": 0.01},
        "sim-dronecan")
    node = dronecan.make_node(channel, node_id=100, bitrate=1_000_000, bustype="virtual")
    seen = []
    node.add_handler(dronecan.uavcan.equipment.esc.Status, lambda e: seen.append(e.message))
    try:
        end = time.monotonic() + 5.0  # the node's NodeStatus comes once a second
        while time.monotonic() < end and not (
                esc.get("raw") == 4096 and seen and esc.get("host_node_status")):
            node.broadcast(dronecan.uavcan.equipment.esc.RawCommand(cmd=[0, 0, 4096]))
            node.spin(0.02e-3)  # 20 ms (see module doc)
        assert esc.get("raw") == 4096  # the simulated ESC took dronecan's RawCommand
        assert esc.get("host_node_status") >= 1  # and heard the dronecan node's NodeStatus
        st = seen[-1]
        assert (st.esc_index, st.error_count, st.rpm) == (2, 7, 4096)
        assert st.voltage == pytest.approx(12.5) and st.temperature == pytest.approx(300.0)
    finally:
        node.close()
        stop()
        link.close()
        link.bus.shutdown()


def test_python_can_drives_the_simulated_vesc_with_the_reference_frames():
    channel = _channel("vesc")
    link = CanLink(can.Bus(channel, interface="virtual"), "sim side")
    # at duty 0.25: 12000 ERPM, 10.5 A, 3.1 A in; 24.3 V, 35.2 and 40.0 C, tachometer 123456
    motor = LinearVescMotor(48_000.0, motor_current_per_duty_a=42.0,
                            input_current_per_duty_a=12.4, voltage_in_v=24.3, temp_fet_c=35.2,
                            temp_motor_c=40.0, tachometer=123456)
    vesc, stop = node_process(link, SimVescDevice, {
        "controller_id": 1, "model": motor, "status_rate_hz": 100.0}, "sim-vesc")
    bus = can.Bus(channel, interface="virtual")
    try:
        # §3.2: SET_DUTY 0.25 to controller 1 = id 0x00000001, data 00 00 61 A8, sent
        # again while the statuses are read, as a host does (the VESC releases the motor
        # 1 s after the last command, and a loaded host may read for longer)
        duty = can.Message(arbitration_id=0x00000001, data=bytes.fromhex("000061A8"),
                           is_extended_id=True)
        bus.send(duty)
        end = time.monotonic() + 2.0
        while time.monotonic() < end and vesc.get("command") != VescCommand("duty", 0.25):
            time.sleep(0.005)
        assert vesc.get("command") == VescCommand("duty", 0.25)
        # statuses from before the command took effect (on the bus, or still on the cable
        # from the VESC's process) report duty 0; a tick's statuses go out 1, 4, 5 in
        # order, so the 4 and 5 after a STATUS with a duty are that tick's
        status = {}
        while time.monotonic() < end and len(status) < 3:
            bus.send(duty)
            msg = bus.recv(0.1)
            kind = None if msg is None else msg.arbitration_id >> 8
            if kind == 9:
                status = {9: bytes(msg.data)} if any(msg.data[6:8]) else {}
            elif status and kind in (16, 27):
                status[kind] = bytes(msg.data)
        # STATUS (12000 ERPM, 10.5 A, duty 0.25), STATUS_4 and STATUS_5 as in §3.2
        assert status[9] == bytes.fromhex("00002EE0006900FA")
        assert status[16] == bytes.fromhex("01600190001F0000")
        assert status[27] == bytes.fromhex("0001E24000F30000")
    finally:
        bus.shutdown()
        stop()
        link.close()
        link.bus.shutdown()
