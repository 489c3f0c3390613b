"""Line-printing load-cell backend end to end against a simulated board on a pty, in a
process of its own as the board's firmware is."""

from __future__ import annotations

import sys
import time

import pytest

pytest.importorskip("serial")

from drivers.backends.loadcell_serial import LineLoadCell
from drivers.backends.serial_link import open_port
from drivers.codecs.loadcell_lines import TESTSTAND_V2, LineLayout
from drivers.contracts import Sensor
from drivers.errors import DeviceError
from drivers.wire_sim.loadcell_board import SimLoadcellBoard, SteadyReadings
from drivers.wire_sim.world_process import Remote, WorldProcess, one_device

ep = sys.modules["rotorbench_tests_expected_protocol"]

HEADER = "Thrust(g),mSteps,Throttle(uS),Time(uS),mPRMs,Volts,Amps"  # protocols.md §8.2

MODEL = SteadyReadings({"thrust_n": 4.0, "steps": 0, "throttle_us": 1500, "rpm": 9000,
                        "voltage_v": 12.3, "current_a": 7.5}, clock="t_s")


@pytest.fixture
def board():
    """``board(layout, model, **settings)``: the simulated board in its process (a
    ``Remote``), stopped at the end of the test."""
    worlds: list[WorldProcess] = []

    def make(layout: LineLayout, model: SteadyReadings, **settings: str) -> Remote:
        worlds.append(WorldProcess(one_device, SimLoadcellBoard,
                                   {"layout": layout, "model": model, **settings},
                                   name="sim-loadcell"))
        return worlds[-1].remote("device")

    yield make
    for world in worlds:
        world.close()


def test_teststand_lines_to_si_blocks(board):
    sim = board(TESTSTAND_V2, MODEL, header=HEADER)
    port = open_port(sim.get("path"), 921_600)
    port.write(b"\n")  # any key: the firmware starts printing
    dev = LineLoadCell(port, TESTSTAND_V2, stale_s=0.3)
    assert isinstance(dev, Sensor)
    time.sleep(0.15)
    b = dev.read_block()
    assert len(b) > 5
    # printed in grams on the wire (the §8.2 format), back in newtons
    assert b.values["thrust_n"][-1] == pytest.approx(4.0)
    assert b.values["current_a"][-1] == pytest.approx(7.5)
    assert dev.decoder.stats.skipped_lines == 2  # greeting and header
    sim.port.disconnect()
    time.sleep(0.4)
    with pytest.raises(DeviceError, match="no data line"):
        ep.wait_for(lambda: dev.read_block() is None)  # until the reader finds it silent
    dev.close()
    port.close()


def test_custom_layout_from_config(board):
    layout = LineLayout.from_config({"separator": " ", "fields": [
        {"name": "t_board_s", "scale": 1e-3}, {"name": "thrust_n", "scale": 1e-3}]})
    sim = board(layout, SteadyReadings({"thrust_n": 1.234}, clock="t_board_s"))
    port = open_port(sim.get("path"), 115_200)
    port.write(b"x")
    dev = LineLoadCell(port, layout)
    time.sleep(0.1)
    b = dev.read_block()
    assert b.values["thrust_n"][-1] == pytest.approx(1.234)
    dev.close()
    port.close()
