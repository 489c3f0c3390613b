"""PI hexapod backend end to end against the simulated GCS controller on loopback TCP, in a
process of its own as the controller's firmware is."""

from __future__ import annotations

import math
import socket
import time

import pytest

from drivers.backends.pi_hexapod import PiHexapod, from_wire, open_tcp, to_wire
from drivers.codecs import gcs
from drivers.errors import DeviceError
from drivers.wire_sim.pi_hexapod import SimPiController
from drivers.wire_sim.world_process import Remote, WorldProcess, one_device


def controller(**settings) -> tuple[WorldProcess, Remote]:
    """The simulated controller in its process, and the handle that reads and sets it."""
    world = WorldProcess(one_device, SimPiController, settings, name="sim-pi")
    return world, world.remote("device")


@pytest.fixture
def hexapod():
    world, sim = controller(velocity=100.0)
    dev = PiHexapod(open_tcp(*sim.get("address")), url="tcp://sim", timeout_s=0.5)
    yield sim, dev
    dev.close()
    world.close()


def test_identify_and_units_at_the_boundary(hexapod):
    _, dev = hexapod
    assert dev.identification.model == "C-887"
    assert to_wire({"X": 0.001, "U": math.radians(2.0)}) == pytest.approx({"X": 1.0, "U": 2.0})
    assert from_wire({"Z": 5.0, "W": 90.0}) == pytest.approx({"Z": 0.005, "W": math.pi / 2})
    assert dev.describe().channels[0].name == "hex_x_m"  # the Hexapod contract's log channels


def test_move_wait_and_position(hexapod):
    sim, dev = hexapod
    dev.move_to({"X": 0.002, "W": math.radians(5.0)})
    dev.wait_on_target(timeout_s=1.0)
    pos = dev.position()
    assert pos["X"] == pytest.approx(0.002) and pos["W"] == pytest.approx(math.radians(5.0))
    commands = sim.get("commands")
    names = [c.name for c in commands if c.name != "ERR?"]
    # the state is read at open and again before the move (limits, reference, servo)
    assert names[:5] == ["*IDN?", "SVO?", "FRF?", "TMN?", "TMX?"]
    assert names[names.index("MOV") - 4:names.index("MOV")] == ["SVO?", "FRF?", "TMN?", "TMX?"]
    mov = next(c for c in commands if c.name == "MOV")
    assert mov.args == ("X", "2", "W", "5")  # mm and degrees on the wire


def test_limits_and_reference_are_read_from_the_controller_before_motion():
    world, sim = controller(travel={"Z": (-10.0, 20.0)}, referenced=False)
    dev = PiHexapod(open_tcp(*sim.get("address")), url="tcp://sim", timeout_s=0.5)
    try:
        assert dev.state.travel["Z"] == pytest.approx((-0.010, 0.020))
        assert dev.describe().extra["controller"]["referenced"]["X"] is False
        with pytest.raises(DeviceError, match=r"not referenced \(FRF\? X=0\): reference it"):
            dev.move_to({"X": 0.001})
        sim.set("referenced", True)
        with pytest.raises(DeviceError, match=r"MOV Z = 0.021 outside the controller's "
                                              r"TMN\?..TMX\? -0.01..0.02"):
            dev.move_to({"Z": 0.021})
        sim.servo.update({"V": False})
        with pytest.raises(DeviceError, match=r"servo off \(SVO\? V=0\)"):
            dev.move_to({"Z": 0.001})
        assert not any(c.name == "MOV" for c in sim.get("commands"))  # nothing moved
    finally:
        dev.close()
        world.close()


def test_refused_commands_raise_with_the_gcs_error(hexapod):
    _, dev = hexapod
    with pytest.raises(DeviceError, match="GCS error 7"):
        dev.command(gcs.mov({"Z": 1000.0}))  # 1000 mm: out of limits (the backend's own
        # move_to refuses it before sending: see the TMN?/TMX? test)
    with pytest.raises(DeviceError, match="GCS error 2"):
        dev.command(gcs.command("NOPE"))
    dev.move_to({"Z": 0.001})  # the error was cleared by ERR?


def test_stop_halts_motion_and_clears_error_10(hexapod):
    sim, dev = hexapod
    sim.set("velocity", 1.0)  # slow: 1 mm/s
    dev.move_to({"Y": 0.010})
    time.sleep(0.05)
    dev.stop()
    y = sim.pose_at()["Y"]
    time.sleep(0.05)
    assert sim.pose_at()["Y"] == y < 10.0
    assert sim.get("error") == 0  # error 10 of the stop was read and cleared
    dev.move_to({"Y": 0.0})  # no error pending after the stop


def test_pivot_and_wave_generator_commands_reach_the_controller(hexapod):
    sim, dev = hexapod
    dev.set_pivot({"R": 0.0, "S": 0.0, "T": 0.05})
    assert sim.get("pivot")["T"] == pytest.approx(50.0)
    for line in (gcs.wav_sin_p(1, 1000, 2.0, 0.0, 1000, 0, 500), gcs.wsl(1, 1), gcs.wgc(1, 10),
                 gcs.wtr(1, 10, 0), gcs.wgo(1, 1), gcs.wgo(1, 0)):
        dev.command(line)
    assert [c.name for c in sim.get("commands") if c.name.startswith("W")] == \
        ["WAV", "WSL", "WGC", "WTR", "WGO", "WGO"]


def test_silent_controller_times_out_and_close_never_raises(hexapod):
    sim, dev = hexapod
    sim.disconnect()
    t0 = time.monotonic()
    with pytest.raises(DeviceError, match="no reply"):
        dev.position()
    assert time.monotonic() - t0 < 1.0
    dev.close()


def test_connection_refused_is_a_device_error():
    world, sim = controller()
    host, port = sim.get("address")
    world.close()
    with pytest.raises(DeviceError, match="cannot connect"):
        open_tcp(host, port, timeout_s=0.5)


def test_a_controller_that_never_answers_is_refused_and_its_socket_closed():
    """The socket is the backend's from construction: refused at open, it is closed, not
    left for the garbage collector to warn about in whatever runs next."""
    server = socket.create_server(("127.0.0.1", 0))
    try:
        sock = open_tcp(*server.getsockname())
        with pytest.raises(DeviceError, match=r"no reply within 0\.1 s"):
            PiHexapod(sock, url="tcp://mute", timeout_s=0.1)
        assert sock.fileno() == -1
    finally:
        server.close()
