"""Frames lost on a device's link are counted, per backend.

Time stamps show samples that never came; a decoder's counters show frames that came
damaged (bad checksums, truncated, malformed) and a DroneCAN transfer-id sequence shows
transfers that never came. ``link_errors()`` reports them; the run records them."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from drivers.backends.dronecan_esc import DroneCanEscTelemetry
from drivers.codecs import dronecan as dc
from drivers.codecs.stream import DecoderStats, link_losses

pytest.importorskip("serial")

from drivers.backends.kiss_telemetry import KissTelemetry
from drivers.codecs.transcript import parse_hex_dump

T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts" / "kiss"


def test_link_losses_are_the_loss_counters_only():
    st = DecoderStats(bytes_in=100, messages=3, garbage_bytes=12, bad_checksums=2, truncated=1,
                      resyncs=2)
    assert link_losses(st) == {"bad_checksums": 2, "truncated": 1}
    assert link_losses(DecoderStats()) == {}


def test_a_damaged_kiss_frame_is_a_link_error():
    ep = sys.modules["rotorbench_tests_expected_protocol"]
    frames = parse_hex_dump((T / "noisy.hex").read_text())
    port = ep.ScriptedPort([(b"", frames)])
    dev = KissTelemetry(port, pole_pairs=7, stale_s=0.5)
    assert ep.wait_for(lambda: dev.decoder.stats.bytes_in == len(frames))
    dev.read_block()
    dev.close()
    # frame 2 fails its CRC once and is cut short once (noisy.hex)
    assert dev.link_errors() == {"bad_checksums": 1, "truncated": 1}


class _Bus:
    """The CanLink surface the telemetry uses: subscribe / unsubscribe."""

    def __init__(self) -> None:
        self.listeners: list = []

    def subscribe(self, fn) -> None:
        self.listeners.append(fn)

    def unsubscribe(self, fn) -> None:
        self.listeners.remove(fn)

    def send(self, msg, node: int, tid: int) -> None:
        for frame in dc.encode(msg, node, tid, dc.DEFAULT_PRIORITY):
            for fn in list(self.listeners):
                fn(frame)


def _status(index: int) -> dc.EscStatus:
    return dc.EscStatus(0, 12.0, 1.5, 300.0, 5000, 10, index)


def test_dronecan_transfer_id_gaps_count_lost_status_transfers():
    bus = _Bus()
    dev = DroneCanEscTelemetry(bus, esc_index=0)
    # node 20 numbers its esc.Status transfers over all its ESCs: 0 (esc 0), 1 (esc 1),
    # 2 is lost, 3 (esc 0), 3 again (a repeated transfer), 4 .. 31, 0 (wrap), 2 (1 lost)
    for tid, index in [(0, 0), (1, 1), (3, 0), (3, 0), *[(t, 0) for t in range(4, 32)],
                       (0, 0), (2, 0)]:
        bus.send(_status(index), 20, tid)
    bus.send(_status(0), 21, 7)  # another node: its own sequence
    assert dev.transfer_id_gaps == 2
    assert dev.link_errors() == {"transfer_id_gaps": 2}
    assert len(dev.read_block()) == 34  # esc 0's rows: the repeat is kept as a row
    dev.close()
