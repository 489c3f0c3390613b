"""MSP codec: protocols.md §1.9 example frames, transcripts, round trips and fuzzing."""

from __future__ import annotations

import math
import os
import struct
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import msp
from drivers.codecs.checksums import crc8_dvb_s2
from drivers.codecs.transcript import parse_hex_dump

props = sys.modules["rotorbench_tests_codec_props"]  # codec_props.py, loaded by conftest.py
T = props.FIXTURES / "msp"
H = bytes.fromhex
# ROTORBENCH_FUZZ_EXAMPLES=5000 for a deeper run than the default 300 per property
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)

# protocols.md §1.9, message -> exact bytes
SPEC_FRAMES = [
    (msp.Request(101), "24 4D 3C 00 65 65"),
    (msp.Request(102), "24 4D 3C 00 66 66"),
    (msp.Request(104), "24 4D 3C 00 68 68"),
    (msp.Request(108), "24 4D 3C 00 6C 6C"),
    (msp.Request(1), "24 4D 3C 00 01 01"),
    (msp.RawImu((0, 0, 2048), (1, -2, 3), (0, 0, 0)),
     "24 4D 3E 12 66 00 00 00 00 00 08 01 00 FE FF 03 00 00 00 00 00 00 00 7F"),
    (msp.Motor((1000,) * 4 + (0,) * 4),
     "24 4D 3E 10 68 E8 03 E8 03 E8 03 E8 03 00 00 00 00 00 00 00 00 78"),
    (msp.SetMotor((1100,) * 4 + (1000,) * 4),
     "24 4D 3C 10 D6 4C 04 4C 04 4C 04 4C 04 E8 03 E8 03 E8 03 E8 03 C6"),
    (msp.Ack(214), "24 4D 3E 00 D6 D6"),
    (msp.ErrorReply(214), "24 4D 21 00 D6 D6"),
]


@pytest.mark.parametrize(("message", "hexstr"), SPEC_FRAMES)
def test_spec_frames_encode_and_decode(message, hexstr):
    assert msp.encode_message(message) == H(hexstr)
    dec = msp.MspDecoder(typed=True)
    assert dec.feed(H(hexstr)) == [message]
    assert dec.stats.garbage_bytes == 0


def test_spec_attitude_frame_in_radians():
    frame = H("24 4D 3E 06 6C 7D 00 CE FF 0E 01 29")  # §1.9: 12.5°, -5.0°, 270°
    (att,) = msp.MspDecoder(typed=True).feed(frame)
    assert math.degrees(att.roll_rad) == pytest.approx(12.5)
    assert math.degrees(att.pitch_rad) == pytest.approx(-5.0)
    assert math.degrees(att.yaw_rad) == pytest.approx(270.0)
    assert msp.encode_message(att) == frame


def test_spec_v2_requests_and_crc8_check_value():
    assert crc8_dvb_s2(b"123456789") == 0xBC  # §1.2 check value
    assert msp.request(102, version=2) == H("24 58 3C 00 66 00 00 00 05")
    assert msp.encode_v2(msp.REQUEST, 0x1001) == H("24 58 3C 00 01 10 00 00 5C")


def test_set_motor_pads_to_eight_and_refuses_out_of_range():
    assert msp.encode_message(msp.SetMotor((1100,) * 4)) == H(SPEC_FRAMES[7][1])
    for bad in ((999,), (2001,), (1000,) * 9):
        with pytest.raises(ValueError):
            msp.encode_message(msp.SetMotor(bad))


def test_imu_si_by_firmware():
    """Betaflight sends the gyro's counts (16.4 per deg/s, measured on its SITL), INAV
    whole deg/s."""
    m = msp.RawImu((0, 0, 2048), (1476, 0, -2952), (0, 0, 0))  # 90 and -180 deg/s x 16.4
    acc, gyro = msp.imu_si(m, "BTFL", acc_1g=2048)
    assert acc[2] == pytest.approx(9.80665)
    assert gyro == pytest.approx((math.pi / 2, 0, -math.pi))
    _, gyro = msp.imu_si(m, "BTFL", acc_1g=2048, gyro_lsb_per_dps=32.8)  # a +-1000 range
    assert gyro == pytest.approx((math.pi / 4, 0, -math.pi / 2))
    acc, gyro = msp.imu_si(msp.RawImu((0, 0, 512), (90, 0, -180), (0, 0, 0)), "INAV")
    assert acc[2] == pytest.approx(9.80665)
    assert gyro == pytest.approx((math.pi / 2, 0, -math.pi))
    with pytest.raises(ValueError, match="acc_1g"):
        msp.imu_si(m, "BTFL")
    with pytest.raises(ValueError, match="MWII"):
        msp.imu_si(m, "MWII")


def test_jumbo_and_v2_over_v1_frames():
    payload = bytes(range(256)) * 2
    jumbo = msp.encode_v1(msp.REPLY, 150, payload)
    assert jumbo[3] == 0xFF and jumbo[5:7] == (512).to_bytes(2, "little")
    tunnel = msp.encode_v2_over_v1(msp.REPLY, 0x1001, b"\x01\x02", flags=3)
    assert tunnel[4] == 255
    out = msp.MspDecoder().feed(jumbo + tunnel)
    assert out == [msp.MspFrame(1, ">", 150, payload), msp.MspFrame(2, ">", 0x1001, b"\x01\x02", 3)]


def test_payload_of_wrong_length_is_malformed_not_a_crash():
    bad = msp.encode_v1(msp.REPLY, msp.MSP_RAW_IMU, b"\x00" * 17)
    dec = msp.MspDecoder(typed=True)
    assert dec.feed(bad + msp.encode_message(msp.Ack(214))) == [msp.Ack(214)]
    assert dec.stats.malformed == 1


# ---------------------------------------------------------------------------- transcripts


def test_transcript_requests():
    data = parse_hex_dump((T / "requests.hex").read_text())
    dec = msp.MspDecoder(typed=True)
    got = dec.feed(data) + dec.flush()
    assert got == [m for m, _ in SPEC_FRAMES[:5]] + [SPEC_FRAMES[7][0], msp.Request(102),
                                                     msp.Request(0x1001)]
    assert dec.stats.garbage_bytes == 0


def test_transcript_replies():
    dec = msp.MspDecoder(typed=True)
    got = dec.feed(parse_hex_dump((T / "replies.hex").read_text()))
    assert [type(m).__name__ for m in got] == ["RawImu", "Attitude", "Motor", "Ack", "ErrorReply"]


def test_transcript_noisy_is_counted():
    dec = msp.MspDecoder(typed=True)
    got = dec.feed(parse_hex_dump((T / "noisy.hex").read_text())) + dec.flush()
    assert [type(m).__name__ for m in got] == ["Attitude", "Ack", "RawImu"]
    s = dec.stats
    assert (s.bad_checksums, s.truncated, s.malformed) == (1, 2, 0)
    assert s.bytes_in == s.frame_bytes + s.garbage_bytes
    assert s.frame_bytes == 12 + 6 + 24


# ---------------------------------------------------------------------------- properties

int16 = st.integers(-(2**15), 2**15 - 1)
vec3 = st.tuples(int16, int16, int16)
typed_messages = st.one_of(
    st.builds(msp.RawImu, vec3, vec3, vec3),
    st.builds(msp.Motor, st.lists(st.integers(0, 0xFFFF), max_size=8).map(tuple)),
    st.builds(msp.SetMotor, st.lists(st.integers(1000, 2000), min_size=8, max_size=8).map(tuple)),
    st.builds(msp.ApiVersion, st.integers(0, 255), st.integers(0, 255), st.integers(0, 255)),
    st.builds(msp.FcVariant, st.sampled_from(["BTFL", "INAV", "MWII"])),
    st.builds(msp.AttitudeQuaternion,
              *[st.integers(-0x7FFF, 0x7FFF).map(lambda v: v / 0x7FFF)] * 4),
    st.builds(msp.Request, st.sampled_from([1, 2, 101, 102, 104, 108])),
    st.builds(msp.Ack, st.just(214)),
    st.builds(msp.ErrorReply, st.integers(0, 254)),
)


@FUZZ
@given(typed_messages, st.sampled_from([1, 2]))
def test_typed_round_trip(message, version):
    dec = msp.MspDecoder(typed=True)
    assert dec.feed(msp.encode_message(message, version)) == [message]


@FUZZ
@given(st.builds(msp.Attitude, *[st.integers(-1800, 1800).map(lambda d: math.radians(d / 10))] * 2,
                 st.integers(0, 359).map(math.radians)))
def test_attitude_round_trip_at_wire_resolution(att):
    (back,) = msp.MspDecoder(typed=True).feed(msp.encode_message(att))
    assert back.roll_rad == pytest.approx(att.roll_rad, abs=1e-12)
    assert back.yaw_rad == pytest.approx(att.yaw_rad, abs=1e-12)


frames = st.builds(
    lambda kind, d, cmd, payload, flags: (
        (msp.encode_v1(d, cmd % 255, payload), msp.MspFrame(1, d, cmd % 255, payload))
        if kind == 1 else
        (msp.encode_v2(d, cmd, payload, flags), msp.MspFrame(2, d, cmd, payload, flags))
        if kind == 2 else
        (msp.encode_v2_over_v1(d, cmd, payload[:200], flags),
         msp.MspFrame(2, d, cmd, payload[:200], flags))),
    st.sampled_from([1, 2, 3]), st.sampled_from("<>!"), st.integers(0, 0xFFFF),
    st.binary(max_size=40), st.integers(0, 255))


def streams(garbage=None, damaged=True):
    return props.streams(frames, garbage, damaged, trailing=True)


@FUZZ
@given(streams())
def test_fuzz_garbage_damage_and_chunking(stream):
    data, intact, cuts = stream
    props.check_stream(msp.MspDecoder, data, intact, cuts)


@FUZZ
@given(streams(garbage=st.binary(max_size=12).filter(lambda b: b"$" not in b), damaged=False))
def test_fuzz_garbage_without_sync_is_counted_exactly(stream):
    data, intact, cuts = stream
    dec, located = props.check_stream(msp.MspDecoder, data, intact, cuts)
    # Noise without '$' cannot start a frame: every frame comes back, every noise byte counted.
    assert [(x.offset, x.message) for x in located] == [(o, m) for o, _, m in intact]
    assert dec.stats.garbage_bytes == len(data) - sum(n for _, n, _ in intact)
    assert dec.stats.bad_checksums == dec.stats.truncated == 0


@FUZZ
@given(st.binary(max_size=400), st.lists(st.integers(0, 400), max_size=8))
def test_fuzz_pure_noise_never_raises(noise, cuts):
    props.check_stream(msp.MspDecoder, noise, [], cuts)
    dec = msp.MspDecoder(typed=True)
    props.feed_chunked(dec, noise, cuts)
    assert dec.buffered == 0


def test_truncated_then_valid_frame_counts_one_truncation():
    good = msp.encode_message(msp.Ack(214))
    raw = msp.encode_message(msp.RawImu((1, 2, 3), (4, 5, 6), (7, 8, 9)))
    dec = msp.MspDecoder(typed=True)
    assert dec.feed(raw[:10] + good + raw) == [msp.Ack(214), msp.RawImu((1, 2, 3), (4, 5, 6),
                                                                         (7, 8, 9))]
    assert (dec.stats.truncated, dec.stats.bad_checksums, dec.stats.garbage_bytes) == (1, 0, 10)


def test_declared_size_beyond_limit_is_garbage_and_does_not_stall():
    huge = b"$X>" + bytes([0]) + (102).to_bytes(2, "little") + (60000).to_bytes(2, "little")
    good = msp.encode_message(msp.Ack(214))
    dec = msp.MspDecoder(typed=True, max_payload=1024)
    assert dec.feed(huge + good) == [msp.Ack(214)]
    assert dec.buffered == 0


def test_multiple_msp_splits_into_the_typed_replies_and_refuses_a_short_one():
    """Betaflight's MSP_MULTIPLE_MSP (msp.c): per command a u8 size, then its payload."""
    cmds = (msp.MSP_RAW_IMU, msp.MSP_ATTITUDE)
    req = msp.multiple_request(cmds)
    assert msp.encode_message(req) == msp.encode_v1(msp.REQUEST, 230, bytes([102, 108]))
    raw = msp.RawImu((1, -2, 256), (16, -33, 0), (0, 0, 0))
    att = msp.Attitude(math.radians(1.5), math.radians(-2.0), math.radians(90.0))
    body = b"".join(bytes([len(p)]) + p for p in (raw.to_payload(), att.to_payload()))
    reply = msp.Unknown(msp.REPLY, msp.MSP_MULTIPLE_MSP, body.hex())
    assert msp.split_multiple(cmds, reply) == [raw, att]
    with pytest.raises(msp.PayloadError, match="ends before 108"):
        msp.split_multiple(cmds, msp.Unknown(msp.REPLY, 230, body[:19].hex()))
    with pytest.raises(msp.PayloadError, match="left over"):
        msp.split_multiple(cmds[:1], reply)
    with pytest.raises(ValueError):
        msp.multiple_request((0x1001,))


def test_the_fcs_clock_is_set_and_read_to_the_millisecond():
    """MSP_SET_RTC carries i32 seconds and u16 ms; MSP_RTC answers a UTC date and time
    (Betaflight msp.c), read back here as ms since 1970; an unset clock answers nothing."""
    req = msp.set_rtc_request(1_000_000_000, 5)
    assert req.cmd == msp.MSP_SET_RTC
    assert bytes.fromhex(req.payload_hex) == struct.pack("<iH", 1_000_000_000, 5)
    # 2001-09-09 01:46:40.005 UTC
    body = struct.pack("<HBBBBBH", 2001, 9, 9, 1, 46, 40, 5)
    reply = msp.parse(msp.MspFrame(1, msp.REPLY, msp.MSP_RTC, body))
    assert msp.rtc_ms(reply) == 1_000_000_000_005
    assert msp.rtc_ms(msp.parse(msp.MspFrame(1, msp.REPLY, msp.MSP_RTC, b""))) is None
    bad = struct.pack("<HBBBBBH", 2001, 13, 9, 1, 46, 40, 5)  # month 13: no date
    assert msp.rtc_ms(msp.parse(msp.MspFrame(1, msp.REPLY, msp.MSP_RTC, bad))) is None
    # a simulated FC's reply is the same bytes
    assert bytes.fromhex(msp.rtc_reply(1_000_000_000_005).payload_hex) == body
    assert msp.rtc_reply(None).payload_hex == ""
