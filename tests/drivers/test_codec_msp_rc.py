"""The RC control path's payloads and the pulse <-> throttle map (no firmware needed)."""

from __future__ import annotations

import struct

import pytest

from drivers.codecs import msp_rc as rc


def test_throttle_map_inverts_and_keeps_idle_low():
    m = rc.ThrottleMap()
    for pulse in (1100.0, 1400.0, 1502.0, 1999.0):
        assert abs(m.pulse_for(m.rc_for(pulse)) - pulse) <= 0.5  # one RC microsecond
    # what the 4.6.0 SITL output for these throttle channels (measured, +-2 us)
    for thr, out in ((1100, 1104), (1500, 1502), (1900, 1899), (2000, 2000)):
        assert abs(m.pulse_for(thr) - out) <= 2
    assert m.rc_for(1000.0) == m.rc_for(1055.0) == rc.THROTTLE_LOW_US < m.min_check_us
    assert m.rc_for(2500.0) == 2000


def test_raw_rc_refuses_invalid_pulses():
    assert rc.encode_raw_rc([1500, 1500, 1000, 1500]) == struct.pack("<4H", 1500, 1500, 1000,
                                                                     1500)
    for bad in ([], [0, 1500], [1500, 2200]):
        with pytest.raises(ValueError, match="MSP_SET_RAW_RC"):
            rc.encode_raw_rc(bad)


def test_mode_ranges_and_failsafe_config_round_trip():
    ranges = rc.decode_mode_ranges(bytes([0, 0, 32, 48, 1, 2, 0, 0]))
    assert ranges[0] == rc.ModeRange(0, 0, 32, 48) and ranges[0].used
    assert ranges[0].contains(1900) and not ranges[0].contains(rc.AUX_OFF_US)
    assert not ranges[1].used
    assert rc.encode_mode_range(3, ranges[0]) == bytes([3, 0, 0, 32, 48, 0, 0])
    payload = bytes.fromhex("0f3ce80300640001")  # the 4.6.0 SITL's defaults
    cfg = rc.FailsafeConfig.from_payload(payload)
    assert (cfg.delay_ds, cfg.throttle_us, cfg.procedure) == (15, 1000, rc.DROP)
    assert cfg.to_payload() == payload
    with pytest.raises(ValueError):
        rc.decode_mode_ranges(b"\0\0\0")
