"""PI's own Python client (PIPython, GCS 2 over a socket) against the simulated controller.

The pure-Python path of protocols.md §6.4: ``PISocket`` -> ``GCSMessages`` ->
``GCSCommands`` (PI's ``samples/advanced/connect_socket.py``); PI's native library is not
needed. PIPython checks ``ERR?`` after every command and query, so a call that returns
is one the controller accepted. PIPython is proprietary (EULA: for use with PI hardware);
it is a test dependency only.
"""

from __future__ import annotations

import time

import pytest

pipython = pytest.importorskip("pipython")

from pipython.pidevice.gcscommands import GCSCommands  # noqa: E402
from pipython.pidevice.gcserror import GCSError  # noqa: E402
from pipython.pidevice.gcsmessages import GCSMessages  # noqa: E402
from pipython.pidevice.interfaces.pisocket import PISocket  # noqa: E402

from drivers.wire_sim.pi_hexapod import SimPiController  # noqa: E402
from drivers.wire_sim.world_process import WorldProcess, one_device  # noqa: E402

AXES = ["X", "Y", "Z", "U", "V", "W"]


@pytest.fixture
def pidev():
    world = WorldProcess(one_device, SimPiController, {
        "velocity": 50.0, "limit": 50.0, "travel": {"Z": (-25.0, 25.0), "W": (-30.0, 30.0)}},
        name="sim-pi")  # in a process of its own, as the controller's firmware is
    sim = world.remote("device")
    host, port = sim.get("address")
    # as context managers: PIPython registers each GCSCommands with every gateway (a class
    # attribute) until it is left, and a stale one would talk to a closed socket
    with PISocket(host=host, port=port) as gateway, \
            GCSCommands(GCSMessages(gateway)) as dev:
        yield sim, dev
    world.close()


def test_pipython_start_up_queries(pidev):
    _, dev = pidev
    assert "C-887" in dev.qIDN()
    assert dev.qSAI() == AXES
    assert dev.qSVO() == dict.fromkeys(AXES, True)
    assert dev.qFRF() == dict.fromkeys(AXES, True)
    assert dev.qTMN()["Z"] == -25.0 and dev.qTMX()["W"] == 30.0
    assert dev.qTMX(["X"]) == {"X": 50.0}
    assert dev.qERR() == 0


def test_pipython_moves_waits_and_stops(pidev):
    _, dev = pidev
    dev.MOV({"X": 1.0, "Z": -0.5})
    for _ in range(200):
        if all(dev.qONT().values()):
            break
        time.sleep(0.01)
    assert all(dev.qONT().values())
    pos = dev.qPOS()
    assert pos["X"] == pytest.approx(1.0) and pos["Z"] == pytest.approx(-0.5)
    dev.MOV("X", 40.0)
    dev.STP(noraise=True)  # PIPython's own handling of error 10 after a stop
    assert dev.qERR() == 0
    with pytest.raises(GCSError) as err:
        dev.MOV("Z", 30.0)  # beyond TMX? Z = 25
    assert err.value.val == 7  # position out of limits


def test_pipython_wave_generator_and_data_recorder(pidev):
    sim, dev = pidev
    dev.WAV_SIN_P(table=1, firstpoint=1, numpoints=1000, append="X", center=500,
                  amplitude=1.0, offset=0.0, seglength=1000)
    dev.WSL(1, 1)
    assert dev.qWSL(1) == {1: 1}
    dev.DRC(1, "X", 2)
    assert dev.qDRC(1) == {1: ["X", 2]}
    assert dev.qWGO(1) == {1: 0}
    dev.WGO(1, 1)
    dev.WGO(1, 0)
    assert dev.qWGO() == dict.fromkeys(range(1, 7), 0)
    wav = next(c for c in sim.get("commands") if c.name == "WAV")
    assert wav.args[:3] == ("1", "X", "SIN_P")  # PIPython's argument order (§6.3)


def test_an_unreferenced_controller_refuses_motion_as_pipython_sees_it():
    world = WorldProcess(one_device, SimPiController, {"referenced": False}, name="sim-pi")
    host, port = world.remote("device").get("address")
    try:
        with PISocket(host=host, port=port) as gateway, \
                GCSCommands(GCSMessages(gateway)) as dev:
            _unreferenced(dev)
    finally:
        world.close()


def _unreferenced(dev) -> None:
    assert dev.qFRF() == dict.fromkeys(AXES, False)
    with pytest.raises(GCSError) as err:
        dev.MOV("X", 1.0)
    assert err.value.val == 5  # move without reference or with servo off
    dev.FRF("X")
    assert dev.qFRF("X") == {"X": True}
    dev.MOV("X", 1.0)
