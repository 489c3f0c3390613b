"""VESC USB/UART codec: protocols.md §3.3-§3.4 packets, transcripts, round trips, fuzzing."""

from __future__ import annotations

import os
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import vesc_uart as vu
from drivers.codecs.checksums import crc16_xmodem
from drivers.codecs.transcript import parse_hex_dump

props = sys.modules["rotorbench_tests_codec_props"]  # codec_props.py, loaded by conftest.py
T = props.FIXTURES / "vesc_uart"
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)

REQUESTS = [vu.Request(vu.COMM_FW_VERSION), vu.Request(vu.COMM_GET_VALUES),
            vu.Request(vu.COMM_ALIVE), vu.SetDuty(0.25), vu.SetCurrent(10.0), vu.SetRpm(12000)]


def test_crc_check_value():
    assert crc16_xmodem(b"123456789") == 0x31C3  # §3.3


def test_transcript_requests_decode_and_encode_byte_for_byte():
    data = parse_hex_dump((T / "requests.hex").read_text())
    dec = vu.VescUartDecoder(replies=False)
    assert dec.feed(data) == REQUESTS
    assert b"".join(vu.encode(m) for m in REQUESTS) == data
    assert dec.stats.garbage_bytes == 0


def test_transcript_get_values_reply():
    data = parse_hex_dump((T / "replies.hex").read_text())
    (v,) = vu.VescUartDecoder(replies=True).feed(data)
    assert (v.temp_fet_c, v.temp_motor_c, v.motor_current_a, v.input_current_a) == \
        pytest.approx((35.2, 40.1, 10.5, 3.1))
    assert (v.duty, v.erpm, v.voltage_in_v, v.tachometer) == pytest.approx(
        (0.25, 12000, 24.3, 123456))
    assert v.controller_id == 1 and v.fault_code == 0 and v.timeout_active is False


def test_older_firmware_prefix_and_short_payload():
    full = vu.Values(30.0, 31.0, 1.0, 2.0, 0.0, 1.0, 0.5, 7000, 12.0).to_payload()
    (v,) = vu.VescUartDecoder(replies=True).feed(vu.frame(full[:29]))  # up to V_in
    assert v.voltage_in_v == pytest.approx(12.0) and v.tachometer is None
    dec = vu.VescUartDecoder(replies=True)
    assert dec.feed(vu.frame(full[:20])) == [] and dec.stats.malformed == 1


def test_long_packet_header():
    payload = bytes([99]) + bytes(300)
    data = vu.frame(payload)
    assert data[:3] == b"\x03\x01\x2d" and data[-1] == 3
    assert vu.VescUartDecoder(replies=True).feed(data) == [vu.Unknown(99, payload.hex())]
    with pytest.raises(ValueError):
        vu.frame(b"")


values = st.builds(lambda t, c, d, e, v: vu.Values(t, t, c, c, 0.0, c, d, e, v,
                                                    controller_id=3, timeout_active=False),
                   st.integers(-400, 1200).map(lambda x: x / 10),
                   st.integers(-100_000, 100_000).map(lambda x: x / 100),
                   st.integers(-1000, 1000).map(lambda x: x / 1000),
                   st.integers(-200_000, 200_000).map(float),
                   st.integers(0, 800).map(lambda x: x / 10))


@FUZZ
@given(values)
def test_values_round_trip(v):
    (back,) = vu.VescUartDecoder(replies=True).feed(vu.encode(v))
    assert back.erpm == v.erpm and back.voltage_in_v == pytest.approx(v.voltage_in_v)
    assert back.duty == pytest.approx(v.duty) and back.controller_id == 3


frames = st.one_of(
    st.sampled_from(REQUESTS).map(lambda m: (vu.encode(m), m)),
    st.integers(-100_000, 100_000).map(lambda d: vu.SetDuty(d / 1e5))
    .map(lambda m: (vu.encode(m), m)))


def streams(garbage=None, damaged=True):
    return props.streams(frames, garbage, damaged)


def _host_decoder():
    return vu.VescUartDecoder(replies=False)


@FUZZ
@given(streams())
def test_fuzz_garbage_damage_and_chunking(stream):
    data, intact, cuts = stream
    props.check_stream(_host_decoder, data, intact, cuts)


@FUZZ
@given(streams(garbage=st.binary(max_size=12).filter(lambda b: not set(b) & {2, 3}),
               damaged=False))
def test_fuzz_garbage_without_start_bytes_is_counted_exactly(stream):
    data, intact, cuts = stream
    dec, located = props.check_stream(_host_decoder, data, intact, cuts)
    assert [(x.offset, x.message) for x in located] == [(o, m) for o, _, m in intact]
    assert dec.stats.garbage_bytes == len(data) - sum(n for _, n, _ in intact)


@FUZZ
@given(st.binary(max_size=400), st.lists(st.integers(0, 400), max_size=8))
def test_fuzz_pure_noise_never_raises(noise, cuts):
    props.check_stream(_host_decoder, noise, [], cuts)
