"""KISS / BLHeli_32 ESC telemetry codec: CRC vectors, transcripts, round trips, fuzzing."""

from __future__ import annotations

import os
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import kiss
from drivers.codecs.transcript import parse_hex_dump

props = sys.modules["rotorbench_tests_codec_props"]  # codec_props.py, loaded by conftest.py
T = props.FIXTURES / "kiss"
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)
FRAME_1 = kiss.Telemetry(36.0, 12.34, 5.67, 89.0, 98_700.0)
FRAME_2 = kiss.Telemetry(25.0, 11.0, 0.0, 0.0, 0.0)


def _betaflight_crc8(data: bytes) -> int:
    """Betaflight's updateCrc8/calculateCrc8 (esc_sensor.c), transcribed bit by bit."""
    crc = 0
    for byte in data:
        crc_u = byte ^ crc
        for _ in range(8):
            crc_u = (0x07 ^ (crc_u << 1)) & 0xFF if crc_u & 0x80 else (crc_u << 1) & 0xFF
        crc = crc_u
    return crc


@pytest.mark.parametrize(("data", "crc"), [
    (b"123456789", 0xF4),  # CRC-8/SMBUS check value (poly 0x07, init 0, no reflection)
    (b"", 0x00), (b"\x00", 0x00), (b"\x01", 0x07), (b"\x80", 0x89), (b"\xff", 0xF3),
    (bytes.fromhex("2404D20237005903DB"), 0x04),  # frame 1 of telemetry.hex
])
def test_crc8_known_vectors(data, crc):
    assert kiss.crc8(data) == crc == _betaflight_crc8(data)


@given(st.binary(max_size=64))
def test_crc8_is_betaflights(data):
    assert kiss.crc8(data) == _betaflight_crc8(data)


def test_transcript_bytes_to_values_and_back():
    data = parse_hex_dump((T / "telemetry.hex").read_text())
    dec = kiss.KissDecoder()
    assert dec.feed(data) == [FRAME_1, FRAME_2]
    assert b"".join(map(kiss.encode, (FRAME_1, FRAME_2))) == data
    assert FRAME_1.rpm(7) == pytest.approx(14_100.0)  # 98 700 eRPM / 7 pole pairs
    assert dec.stats.garbage_bytes == 0 and dec.stats.bad_checksums == 0


def test_noisy_transcript_resyncs_and_counts_crc_errors():
    data = parse_hex_dump((T / "noisy.hex").read_text())
    dec = kiss.KissDecoder()
    assert dec.feed(data) + dec.flush() == [FRAME_1, FRAME_1]
    s = dec.stats
    assert s.bad_checksums == 1  # the flipped frame 2 (its tail's windows are resync tries)
    # the window at the stray byte failed and frame 1 starts inside it: a cut frame (the
    # stream's rule), as is frame 2's cut tail at the end (too short to judge: not counted)
    assert s.truncated == 1
    assert s.resyncs == 2 and s.messages == 2 and s.garbage_bytes == 1 + 10 + 6
    assert s.bytes_in == len(data) == s.frame_bytes + s.garbage_bytes


def test_fields_clamp_to_the_wire():
    t = kiss.Telemetry(-5.0, 700.0, -1.0, 1e9, 1e12)
    (back,) = kiss.KissDecoder().feed(kiss.encode(t))
    assert (back.temperature_c, back.voltage_v, back.current_a) == (0.0, 655.35, 0.0)
    assert (back.consumption_mah, back.erpm) == (65535.0, 6_553_500.0)


telemetry = st.builds(kiss.Telemetry,
                      st.integers(0, 255).map(float),
                      st.integers(0, 0xFFFF).map(lambda x: x / 100),
                      st.integers(0, 0xFFFF).map(lambda x: x / 100),
                      st.integers(0, 0xFFFF).map(float),
                      st.integers(0, 0xFFFF).map(lambda x: x * 100.0))


@FUZZ
@given(telemetry)
def test_round_trip(t):
    (back,) = kiss.KissDecoder().feed(kiss.encode(t))
    assert back == t


frames = telemetry.map(lambda t: (kiss.encode(t), t))


@FUZZ
@given(props.streams(frames))
def test_fuzz_garbage_damage_and_chunking(stream):
    data, intact, cuts = stream
    props.check_stream(kiss.KissDecoder, data, intact, cuts)


@FUZZ
@given(props.streams(frames, garbage=st.just(b""), damaged=False))
def test_fuzz_back_to_back_frames_decode_exactly(stream):
    data, intact, cuts = stream
    dec, located = props.check_stream(kiss.KissDecoder, data, intact, cuts)
    assert [(x.offset, x.message) for x in located] == [(o, m) for o, _, m in intact]
    assert dec.stats.garbage_bytes == 0


@FUZZ
@given(st.binary(max_size=400), st.lists(st.integers(0, 400), max_size=8))
def test_fuzz_pure_noise_never_raises(noise, cuts):
    props.check_stream(kiss.KissDecoder, noise, [], cuts)
