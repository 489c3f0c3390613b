"""PI GCS codec: command syntax (protocols.md §6.1-§6.3), reply termination, parsers, fuzzing."""

from __future__ import annotations

import itertools
import os
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import gcs

props = sys.modules["rotorbench_tests_codec_props"]  # codec_props.py, loaded by conftest.py
T = props.FIXTURES / "gcs"
# ROTORBENCH_FUZZ_EXAMPLES=5000 for a deeper run than the default 300 per property
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)


def test_spec_command_syntax():
    # §6.1: pipython joins "CMD axis value ...", floats as '.12g', LF-terminated.
    assert gcs.mov({"X": 1, "Y": 0.5, "Z": 0, "U": 0, "V": 0, "W": 0}) == \
        b"MOV X 1 Y 0.5 Z 0 U 0 V 0 W 0\n"
    assert gcs.mov({"X": 1 / 3}) == b"MOV X 0.333333333333\n"
    # §6.3 examples
    assert gcs.wsl(1, 1) == b"WSL 1 1\n"
    assert gcs.wgc(1, 10) == b"WGC 1 10\n"
    assert gcs.wtr(1, 10, 0) == b"WTR 1 10 0\n"
    assert gcs.wgo(1, 1) == b"WGO 1 1\n"
    assert gcs.frf() == b"FRF X\n"
    assert gcs.svo({"X": True}) == b"SVO X 1\n"
    assert gcs.vls(5) == b"VLS 5\n"
    assert gcs.wav_sin_p(1, 1000, 2.0, 0.0, 1000, 0, 500) == \
        b"WAV 1 X SIN_P 1000 2 0 1000 0 500\n"
    assert gcs.drc(1, "X", gcs.RECORD_ACTUAL_POSITION) == b"DRC 1 X 2\n"
    assert gcs.drr_query(1, 100, [1, 2]) == b"DRR? 1 100 1 2\n"
    assert gcs.pos_query() == b"POS?\n" and gcs.pos_query("XY") == b"POS? X Y\n"
    assert gcs.spi({"R": 0, "S": 0, "T": 12.5}) == b"SPI R 0 S 0 T 12.5\n"
    assert gcs.STOP_ALL == b"\x18" and gcs.PORT == 50000
    with pytest.raises(ValueError):
        gcs.command("MOV", "X\n1")
    with pytest.raises(ValueError):
        gcs.wav_sin_p(1, 10, 1.0, 0.0, 10, 0, 5, append="?")


def test_reply_termination_rule():
    # §6.1: complete at LF not preceded by a space; non-final lines end with " \n".
    dec = gcs.GcsReplyDecoder()
    assert dec.feed(b"X=1.000000 \nY=0.5 \n") == []
    assert dec.buffered > 0
    (r,) = dec.feed(b"W=0\n")
    assert r.lines == ("X=1.000000", "Y=0.5", "W=0")
    assert gcs.parse_axis_values(r) == {"X": 1.0, "Y": 0.5, "W": 0.0}
    assert gcs.encode_axis_values({"X": 1.0, "Y": 0.5, "W": 0.0}) == b"X=1 \nY=0.5 \nW=0\n"


def test_reply_parsers():
    idn = gcs.GcsReply(("(c)2015 Physik Instrumente (PI) GmbH & Co. KG, C-887, 123, 1.2.3.4",))
    assert gcs.parse_idn(idn).model == "C-887"
    assert gcs.parse_error_code(gcs.GcsReply(("10",))) == gcs.STOPPED_BY_COMMAND
    for bad in (("1", "2"), ("x",)):
        with pytest.raises(gcs.GcsReplyError) as e:
            gcs.parse_error_code(gcs.GcsReply(bad))
        assert e.value.exit_code == 2
    with pytest.raises(gcs.GcsReplyError, match="AXIS=number"):
        gcs.parse_axis_values(gcs.GcsReply(("X=abc",)))
    arr = gcs.parse_data_array(gcs.GcsReply(("# NAME0 = X", "# SAMPLE_TIME = 0.0001",
                                             "# END_HEADER", "1 2", "3 4")))
    assert arr.header == {"NAME0": "X", "SAMPLE_TIME": "0.0001"}
    np.testing.assert_array_equal(arr.data, [[1, 2], [3, 4]])
    with pytest.raises(gcs.GcsReplyError, match="different lengths"):
        gcs.parse_data_array(gcs.GcsReply(("# END_HEADER", "1 2", "3")))


def test_transcripts():
    dec = gcs.GcsReplyDecoder()
    replies = dec.feed((T / "replies.txt").read_bytes()) + dec.flush()
    assert [gcs.reply_kind(r) for r in replies] == ["text", "axis_values", "integer", "integer",
                                                   "data_array"]
    assert gcs.parse_axis_values(replies[1]) == {"X": 1.0, "Y": 0.5, "Z": 0.0, "U": 0.0,
                                                 "V": 0.0, "W": 0.0}
    assert gcs.parse_data_array(replies[4]).data.shape == (2, 2)
    assert dec.stats.garbage_bytes == 0 and dec.stats.messages == 5
    cdec = gcs.GcsCommandDecoder()
    cmds = cdec.feed((T / "commands.txt").read_bytes()) + cdec.flush()
    assert [c.name for c in cmds] == ["CSV?", "*IDN?", "MOV", "ERR?", "POS?", "WSL", "WGC", "WTR",
                                      "WGO", "WGO", "STP", "ERR?", "#5", "#24"]
    assert cmds[2].args == ("X", "1", "Y", "0.5", "Z", "0", "U", "0", "V", "0", "W", "0")


def test_command_decoder_reads_what_the_encoders_write():
    stream = gcs.mov({"X": 1.5}) + gcs.READY + gcs.err_query() + gcs.STOP_ALL
    got = gcs.GcsCommandDecoder().feed(stream)
    assert got == [gcs.GcsCommand("MOV", ("X", "1.5")), gcs.GcsCommand("#7"),
                   gcs.GcsCommand("ERR?"), gcs.GcsCommand("#24")]


def test_over_long_reply_is_dropped_and_decoder_recovers():
    dec = gcs.GcsReplyDecoder(max_bytes=64)
    out = dec.feed(b"A" * 200 + b"\n0\n")
    assert out == [gcs.GcsReply(("0",))]
    assert dec.stats.malformed == 1 and dec.stats.garbage_bytes == 201


# ---------------------------------------------------------------------------- properties

axis = st.sampled_from(gcs.HEXAPOD_AXES)
value = st.floats(-1e6, 1e6, allow_nan=False)
axis_replies = st.dictionaries(axis, value, min_size=1)
text_line = st.text(st.characters(codec="cp1252", exclude_categories=("Cc",)), min_size=1,
                    max_size=30).filter(lambda s: s.strip() and not s.endswith(" "))


@st.composite
def reply_streams(draw):
    pieces = []
    for _ in range(draw(st.integers(1, 6))):
        if draw(st.booleans()):
            vals = draw(axis_replies)
            raw = gcs.encode_axis_values(vals)
            lines = [f"{k}={format(v, '.12g')}" for k, v in vals.items()]
        else:
            lines = draw(st.lists(text_line, min_size=1, max_size=3))
            raw = gcs.encode_reply(lines)
        msg = gcs.GcsReply(tuple(lines))
        if draw(st.integers(0, 4)) == 0:  # noise bytes the protocol never uses
            pieces.append(props.Piece(draw(st.binary(max_size=5).map(
                lambda b: bytes(x for x in b if x in gcs._BAD)))))
        pieces.append(props.Piece(raw, msg, intact=True))
    data, intact = props.assemble(pieces)
    return data, intact, draw(st.lists(st.integers(0, len(data)), max_size=6))


@FUZZ
@given(reply_streams())
def test_fuzz_replies_round_trip_through_noise_and_chunking(stream):
    data, intact, cuts = stream
    _, located = props.check_stream(gcs.GcsReplyDecoder, data, intact, cuts)
    assert [x.message for x in located] == [m for _, _, m in intact]


@FUZZ
@given(axis_replies)
def test_axis_values_round_trip(vals):
    (r,) = gcs.GcsReplyDecoder().feed(gcs.encode_axis_values(vals))
    back = gcs.parse_axis_values(r)
    assert back.keys() == vals.keys()
    for k in vals:
        assert back[k] == pytest.approx(vals[k], rel=1e-11, abs=1e-300)


@FUZZ
@given(st.binary(max_size=300), st.lists(st.integers(0, 300), max_size=6))
def test_fuzz_noise_never_raises(noise, cuts):
    for make in (gcs.GcsReplyDecoder, gcs.GcsCommandDecoder):
        dec = make()
        props.feed_chunked(dec, noise, cuts)
        s = dec.stats
        assert dec.buffered == 0 and s.bytes_in == s.frame_bytes + s.garbage_bytes
        for r in [x.message for x in props.feed_chunked(make(), noise, [])]:
            if isinstance(r, gcs.GcsReply):
                gcs.reply_kind(r)  # the classifier accepts any reply


def test_strict_decoder_takes_only_what_a_controller_can_send():
    real = (T / "replies.txt").read_bytes()
    for data in (real, real.replace(b"\n", b"\r\n"), gcs.encode_reply([gcs.READY_CHAR])):
        lenient, strict = gcs.GcsReplyDecoder(), gcs.GcsReplyDecoder(strict=True)
        assert strict.feed(data) == lenient.feed(data) != []
    dec = gcs.GcsReplyDecoder(strict=True)
    # a control byte inside a line, a byte above ASCII, then a good reply
    assert dec.feed(b"X=1\x02.5\n\xe9t\xe9\nY=2\n") == [gcs.GcsReply(("Y=2",))]
    s = dec.stats
    assert s.messages == 1 and s.garbage_bytes == 11 and s.bytes_in == s.frame_bytes + 11
    assert gcs.GcsReplyDecoder().feed(b"X=1\x02.5\n") == [gcs.GcsReply(("X=1.5",))]  # lenient


@FUZZ
@given(st.binary(min_size=1, max_size=600))
def test_fuzz_strict_replies_are_reply_text(noise):
    dec = gcs.GcsReplyDecoder(strict=True)
    for r in dec.feed(noise) + dec.flush():
        assert gcs.is_reply_text(" \n".join(r.lines) + "\n")
    s = dec.stats
    assert dec.buffered == 0 and s.bytes_in == s.frame_bytes + s.garbage_bytes


# the bytes a reply stream is made of: text with line ends and continuation spaces, weighted
# so lines end, continue and overflow; half the streams also carry bytes to drop (control
# bytes, cp1252 holes), which send a chunk the byte-wise way
_TEXT = [*b"0123456789 =.-AXYZ#\t\r\xe9", *b"\n\n\n", *b"  "]
_REPLY_BYTES = st.one_of(
    st.lists(st.sampled_from(_TEXT), max_size=300),
    st.lists(st.sampled_from([*_TEXT, 0x00, 0x02, 0x7F, 0x81]), max_size=300)).map(bytes)


@settings(max_examples=1000, deadline=None, database=None)
@given(stream=_REPLY_BYTES, cuts=st.lists(st.integers(0, 300), max_size=40),
       max_bytes=st.sampled_from([4, 8, 24, gcs.DEFAULT_MAX_REPLY]))
def test_reply_decoder_line_by_line_is_the_byte_by_byte_decoder(stream, cuts, max_bytes):
    """The reply decoder takes clean text a line at a time (a data recorder's reply is
    megabytes); messages, their offsets and lengths, and every counter are the byte-wise
    decoder's, in any chunking, with garbage and over-long lines mixed in."""
    fast, slow = gcs.GcsReplyDecoder(max_bytes), gcs.GcsReplyDecoder(max_bytes)
    bounds = sorted({0, len(stream), *(c for c in cuts if c < len(stream))})
    got, want = [], []
    for a, b in itertools.pairwise(bounds):
        got += fast.feed_located(stream[a:b])
        want += gcs._TextDecoder.feed_located(slow, stream[a:b])
    assert got == want
    assert fast.stats.as_dict() == slow.stats.as_dict()
    assert fast.buffered == slow.buffered
    assert fast.flush_located() == slow.flush_located()
    assert fast.stats.as_dict() == slow.stats.as_dict()


def test_a_long_clean_data_recorder_reply_is_one_message_at_its_offset():
    rows = "".join(f"{i * 0.001:.6f} {i:d} {-i * 0.5:.3f} \n" for i in range(20_000))
    array = "# REC_RATE = 1000 \n# END_HEADER \n" + rows[:-2] + "\n"  # its last line ends it
    dec = gcs.GcsReplyDecoder()
    first, data = dec.feed_located(b"0 1\n" + array.encode())
    assert first.message == gcs.GcsReply(("0 1",)) and (first.offset, first.length) == (0, 4)
    assert (data.offset, data.length) == (4, len(array))
    assert len(data.message.lines) == 20_002 and dec.stats.garbage_bytes == 0
