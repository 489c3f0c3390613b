"""DroneCAN codec: protocols.md §4.2 frames, transcripts, bit packing, reassembly fuzzing."""

from __future__ import annotations

import math
import os
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import dronecan as d
from drivers.codecs.can_log import CanFrame, read_lines
from drivers.codecs.checksums import crc16_ccitt_false

T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts" / "dronecan"
# ROTORBENCH_FUZZ_EXAMPLES=5000 for a deeper run than the default 300 per property
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)
H = bytes.fromhex

STATUS = d.EscStatus(5, 16.0, 12.5, 300.0, 12000, 42, 2)


def test_spec_raw_command_frame():
    msg = d.RawCommand((0, 4096, 8191, -8192))
    assert msg.to_payload() == H("00 00 01 0F F7 C0 20")  # §4.2
    (frame,) = d.encode(msg, source_node_id=100, transfer_id=0)
    assert (frame.arbitration_id, frame.data) == (0x10040664, H("00 00 01 0F F7 C0 20 C0"))
    (rx,) = d.DroneCanDecoder().feed(frame)
    assert (rx.message, rx.source_node_id, rx.priority, rx.transfer_id) == (msg, 100, 16, 0)


def test_spec_status_three_frames():
    frames = d.encode(STATUS, source_node_id=21, transfer_id=3)
    assert [f.arbitration_id for f in frames] == [0x10040A15] * 3
    assert [f.data for f in frames] == [H("2D 13 05 00 00 00 00 83"),
                                        H("4C 40 4A B0 5C E0 2E 23"), H("15 08 43")]
    dec = d.DroneCanDecoder()
    out = [r for f in frames for r in dec.feed(f)]
    assert [r.message for r in out] == [STATUS]


def test_crc_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1  # CRC-16/CCITT-FALSE check value


def test_transcripts():
    frames = list(read_lines((T / "examples.log").read_text().splitlines()))
    dec = d.DroneCanDecoder()
    out = [r.message for f in frames for r in dec.feed(f)]
    assert out == [d.RawCommand((0, 4096, 8191, -8192)), STATUS]
    dec = d.DroneCanDecoder()
    frames = list(read_lines((T / "noisy.log").read_text().splitlines()))
    out = [r.message for f in frames for r in dec.feed(f)] + dec.flush()
    assert out == [d.RawCommand((0, 4096, 8191, -8192)), STATUS]
    s = dec.stats
    assert (s.frames_in, s.orphan_frames, s.truncated, s.bad_crc, s.foreign) == (11, 2, 1, 1, 1)


def test_node_status_and_unknown_single_frame():
    ns = d.NodeStatus(1234, 1, 2, 3, 0xBEEF)
    (f,) = d.encode(ns, source_node_id=7, transfer_id=1)
    assert len(f.data) == 8
    assert d.DroneCanDecoder().feed(f)[0].message == ns
    unk = CanFrame(d.MessageId(16, 999, 7).to_int(), b"\x01\x02\xC0")
    assert d.DroneCanDecoder().feed(unk)[0].message == d.Unknown(999, "0102")


def test_service_frames_and_nan_fields():
    dec = d.DroneCanDecoder()
    assert dec.feed(CanFrame(0x10040664 | 0x80, b"\xC0")) == []  # service bit set
    assert dec.stats.foreign == 1
    msg = d.EscStatus(0, math.nan, 1.0, math.nan, -5, 0, 31)
    out = [r for f in d.encode(msg, 1, 0) for r in dec.feed(f)]
    assert math.isnan(out[0].message.voltage_v) and out[0].message.rpm == -5


def test_raw_from_fraction():
    assert [d.raw_from_fraction(x) for x in (-1.0, 0.0, 0.5, 1.0, 2.0)] == \
        [-8192, 0, 4096, 8191, 8191]


# ---------------------------------------------------------------------------- properties


@FUZZ
@given(st.lists(st.tuples(st.integers(1, 40), st.booleans()), max_size=12), st.data())
def test_bit_packing_round_trip(fields, data):
    w = d.BitWriter()
    values = []
    for nbits, signed in fields:
        lo, hi = (-(1 << (nbits - 1)), (1 << (nbits - 1)) - 1) if signed else (0, (1 << nbits) - 1)
        x = data.draw(st.integers(lo, hi))
        values.append(x)
        w.write(x, nbits, signed=signed)
    r = d.BitReader(w.to_bytes())
    assert [r.read(n, signed=s) for n, s in fields] == values
    assert r.remaining < 8


raw_cmd = st.builds(d.RawCommand, st.lists(st.integers(-8192, 8191), max_size=20).map(tuple))
f16 = st.floats(-65504, 65504, width=16)
status = st.builds(d.EscStatus, st.integers(0, 2**32 - 1), f16, f16, f16,
                   st.integers(-(2**17), 2**17 - 1), st.integers(0, 127), st.integers(0, 31))
messages = st.one_of(raw_cmd, status)


@FUZZ
@given(messages, st.integers(0, 127), st.integers(0, 31), st.integers(0, 31))
def test_round_trip(msg, node, tid, prio):
    frames = d.encode(msg, node, tid, prio)
    assert all(len(f.data) <= 8 for f in frames)
    out = [r for f in frames for r in d.DroneCanDecoder().feed(f)] if len(frames) == 1 else \
        _feed_all(d.DroneCanDecoder(), frames)
    assert [(r.message, r.source_node_id, r.transfer_id, r.priority) for r in out] == \
        [(msg, node, tid, prio)]


def _feed_all(dec, frames):
    return [r for f in frames for r in dec.feed(f)]


def _not_ours(ident: int) -> bool:
    """Noise must not name a (node, type) of the test traffic: that would be real traffic."""
    mid = d.MessageId.from_int(ident)
    return mid is None or not (1 <= mid.source_node_id <= 5
                               and mid.data_type_id in (d.RAW_COMMAND_DTID, d.STATUS_DTID))


@st.composite
def traffic(draw):
    """Transfers from several nodes, interleaved, with damaged and lost frames."""
    transfers = draw(st.lists(st.tuples(messages, st.integers(1, 5)), min_size=1, max_size=6))
    tids: dict[int, int] = {}
    queues = []
    for msg, node in transfers:
        tid = tids.get(node, 0)
        tids[node] = tid + 1
        queues.append((node, msg, d.encode(msg, node, tid)))
    stream, intact = [], []
    # Transfers of one node are sent in order (as on a real bus); nodes interleave.
    by_node: dict[int, list] = {}
    for node, msg, frames in queues:
        by_node.setdefault(node, []).append((msg, frames))
    cursors = {n: [list(fr) for _, fr in q] for n, q in by_node.items()}
    damaged_nodes: set[int] = set()
    while any(cursors.values()):
        node = draw(st.sampled_from(sorted(n for n, q in cursors.items() if q)))
        cur = cursors[node][0]
        frame = cur.pop(0)
        fate = draw(st.integers(0, 9))
        if fate == 0:  # lost
            damaged_nodes.add(node)
        elif fate == 1 and frame.data:  # a flipped data byte
            k = draw(st.integers(0, len(frame.data) - 1))
            bad = bytearray(frame.data)
            bad[k] ^= draw(st.integers(1, 255))
            stream.append(CanFrame(frame.arbitration_id, bytes(bad)))
            damaged_nodes.add(node)
        else:
            stream.append(frame)
            if draw(st.integers(0, 15)) == 0:
                stream.append(frame)  # a repeated frame (bus retransmission)
        if not cur:
            cursors[node].pop(0)
    for n, q in by_node.items():
        if n not in damaged_nodes:
            intact += [(n, m) for m, _ in q]
    noise = draw(st.lists(st.builds(CanFrame, st.integers(0, 0x1FFFFFFF).filter(_not_ours),
                                    st.binary(max_size=8)), max_size=4))
    for f in noise:
        stream.insert(draw(st.integers(0, len(stream))), f)
    return stream, intact


@FUZZ
@given(traffic())
def test_fuzz_reassembly_never_raises_and_keeps_clean_transfers(case):
    stream, intact = case
    dec = d.DroneCanDecoder()
    out = _feed_all(dec, stream) + dec.flush()
    s = dec.stats
    assert s.frames_in == len(stream)
    assert s.messages == len(out)
    got = [(r.source_node_id, r.message) for r in out]
    # Every transfer of a node whose frames all arrived intact comes back; lost, damaged,
    # repeated and foreign frames never raise and never spoil another node's transfers.
    for item in intact:
        assert item in got
