"""VESC CAN codec and candump logs: protocols.md §3.2 examples, transcripts, fuzzing."""

from __future__ import annotations

import io
import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import vesc_can as v
from drivers.codecs.can_log import CanFrame, CanLogError, format_line, parse_line, read_lines

T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts" / "vesc"
# ROTORBENCH_FUZZ_EXAMPLES=5000 for a deeper run than the default 300 per property
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)

# protocols.md §3.2 "CAN examples (computed)", controller id 1
SPEC = [
    (v.SetDuty(1, 0.25), 0x00000001, "00 00 61 A8"),
    (v.SetCurrent(1, 10.0), 0x00000101, "00 00 27 10"),
    (v.SetCurrentBrake(1, 5.0), 0x00000201, "00 00 13 88"),
    (v.SetRpm(1, 12000), 0x00000301, "00 00 2E E0"),
    (v.Status1(1, 12000, 10.5, 0.25), 0x00000901, "00 00 2E E0 00 69 00 FA"),
    (v.Status4(1, 35.2, 40.0, 3.1, 0.0), 0x00001001, "01 60 01 90 00 1F 00 00"),
    (v.Status5(1, 123456, 24.3), 0x00001B01, "00 01 E2 40 00 F3 00 00"),
]


@pytest.mark.parametrize(("msg", "ident", "hexstr"), SPEC)
def test_spec_frames(msg, ident, hexstr):
    frame = v.encode(msg)
    assert (frame.arbitration_id, frame.data) == (ident, bytes.fromhex(hexstr))
    assert frame.is_extended_id
    back = v.decode(frame)
    assert type(back) is type(msg)
    for name in msg.__dataclass_fields__:
        assert getattr(back, name) == pytest.approx(getattr(msg, name))


def test_id_layout_and_scalings():
    assert v.can_id(v.STATUS_5, 0x42) == 27 << 8 | 0x42
    assert v.split_id(0x00001B42) == (27, 0x42)
    assert v.mech_rpm(14000, 7) == 2000
    f = v.encode(v.SetCurrent(3, -2.5, off_delay_s=0.25))
    assert f.data == bytes.fromhex("FFFFF63C00FA")
    assert v.decode(f) == v.SetCurrent(3, -2.5, 0.25)
    with pytest.raises(ValueError):
        v.encode(v.SetDuty(1, 30000.0))  # 3e9 does not fit int32


def test_transcripts_and_python_can_agree():
    text = (T / "examples.log").read_text()
    frames = list(read_lines(text.splitlines(), source="examples.log"))
    dec = v.VescDecoder()
    got = [m for f in frames for m in dec.feed(f)]
    assert [type(m) for m in got] == [type(m) for m, _, _ in SPEC]
    assert dec.stats.messages == 7 and dec.stats.malformed == 0
    screen = list(read_lines((T / "screen.log").read_text().splitlines()))
    assert [(f.arbitration_id, f.data) for f in screen] == \
        [(f.arbitration_id, f.data) for f in frames[4:]]
    # python-can's own candump reader (the format's reference implementation) agrees.
    can = pytest.importorskip("can")
    theirs = list(can.io.CanutilsLogReader(io.StringIO(text)))
    assert [(m.arbitration_id, bytes(m.data), m.is_extended_id, m.timestamp) for m in theirs] == \
        [(f.arbitration_id, f.data, f.is_extended_id, f.timestamp) for f in frames]


def test_format_line_is_read_back_by_python_can():
    can = pytest.importorskip("can")
    frames = [CanFrame(0x901, b"\x00\x01", timestamp=1.5), CanFrame(0x123, b"", False, 2.0)]
    text = "\n".join(format_line(f) for f in frames) + "\n"
    theirs = list(can.io.CanutilsLogReader(io.StringIO(text)))
    assert [(m.arbitration_id, bytes(m.data), m.is_extended_id) for m in theirs] == \
        [(f.arbitration_id, f.data, f.is_extended_id) for f in frames]


@pytest.mark.parametrize("line", [
    "(1.0) can0 00000901#0000",  # fine, for contrast
])
def test_good_line(line):
    assert parse_line(line) == CanFrame(0x901, b"\x00\x00", True, 1.0, "can0")


@pytest.mark.parametrize("line", [
    "(1.0) can0 123#R",  # remote frame
    "(1.0) can0 00000901#R2",
    "(1.0) can0 123##1001122",  # CAN FD
    "(1.0) can0 20000080#0000000000000000",  # error frame
    "# a comment",
    "   ",
])
def test_lines_without_classic_payload_are_skipped(line):
    assert parse_line(line) is None


@pytest.mark.parametrize(("line", "why"), [
    ("(1.0) can0 00000901#000", "odd number"),
    ("(1.0) can0 00000901#000000000000000000", "classic CAN"),
    ("can0 00000901 [3] 00 11", "announced"),
    ("hello world", "not a candump line"),
])
def test_bad_lines_name_the_line(line, why):
    with pytest.raises(CanLogError, match=why) as err:
        list(read_lines(["", line], source="x.log"))
    assert "x.log:2" in str(err.value)
    assert err.value.exit_code == 2


def test_wrong_lengths_and_foreign_frames_are_counted():
    dec = v.VescDecoder(controller_ids={1})
    frames = [CanFrame(v.can_id(v.STATUS_1, 1), b"\x00" * 7),  # STATUS needs 8 bytes
              CanFrame(v.can_id(v.STATUS_1, 2), b"\x00" * 8),  # other controller
              CanFrame(0x123, b"", is_extended_id=False),  # standard id
              CanFrame(v.can_id(v.STATUS_1, 1), b"\x00" * 8)]
    got = [m for f in frames for m in dec.feed(f)]
    assert got == [v.Status1(1, 0.0, 0.0, 0.0)]
    assert (dec.stats.malformed, dec.stats.foreign, dec.stats.frames_in) == (1, 2, 4)


# ---------------------------------------------------------------------------- properties

ctrl = st.integers(0, 255)
i32, i16 = st.integers(-(2**31), 2**31 - 1), st.integers(-(2**15), 2**15 - 1)
# Messages built from wire integers, so the round trip is exact up to float rounding.
messages = st.one_of(
    st.builds(lambda c, d: v.SetDuty(c, d / 1e5), ctrl, i32),
    st.builds(lambda c, a: v.SetCurrent(c, a / 1e3), ctrl, i32),
    st.builds(lambda c, a, d: v.SetCurrent(c, a / 1e3, d / 1e3), ctrl, i32, i16),
    st.builds(lambda c, a: v.SetCurrentBrake(c, a / 1e3), ctrl, i32),
    st.builds(lambda c, r: v.SetRpm(c, float(r)), ctrl, i32),
    st.builds(lambda c, r, i, d: v.Status1(c, float(r), i / 10, d / 1000), ctrl, i32, i16, i16),
    st.builds(lambda c, a, b: v.Status2(c, a / 1e4, b / 1e4), ctrl, i32, i32),
    st.builds(lambda c, a, b: v.Status3(c, a / 1e4, b / 1e4), ctrl, i32, i32),
    st.builds(lambda c, a, b, d, e: v.Status4(c, a / 10, b / 10, d / 10, e / 50),
              ctrl, i16, i16, i16, i16),
    st.builds(lambda c, t, u: v.Status5(c, t, u / 10), ctrl, i32, i16),
    st.builds(lambda c, a, b, d, e: v.Status6(c, a / 1e3, b / 1e3, d / 1e3, e / 1e3),
              ctrl, i16, i16, i16, i16),
)


@FUZZ
@given(messages)
def test_round_trip(msg):
    frame = v.encode(msg)
    assert v.decode(frame) == msg
    assert v.encode(v.decode(frame)) == frame
    assert parse_line(format_line(frame)) == CanFrame(frame.arbitration_id, frame.data,
                                                      timestamp=0.0, channel="can0")


known_ids = st.builds(lambda p, c: p << 8 | c,
                      st.sampled_from([0, 1, 2, 3, 9, 14, 15, 16, 27, 58, 17]), ctrl)


@FUZZ
@given(st.one_of(known_ids, st.integers(0, 0x1FFFFFFF)), st.binary(max_size=8), st.booleans())
def test_fuzz_any_frame_never_raises(ident, data, ext):
    frame = CanFrame(ident if ext else ident & 0x7FF, data, ext)
    dec = v.VescDecoder()
    out = dec.feed(frame)
    assert len(out) + dec.stats.malformed + dec.stats.foreign == 1
    for m in out:  # what decodes re-encodes to the same bytes (reserved/extra bytes aside)
        again = v.encode(m).data
        n = 6 if isinstance(m, v.Status5) else len(again)
        assert again[:n] == data[:n]
        assert v.encode(m).arbitration_id == ident


@FUZZ
@given(st.text(max_size=80))
def test_fuzz_log_lines_raise_only_can_log_error(line):
    try:
        parse_line(line)
    except CanLogError:
        pass
