"""The RC path's own logic against a scripted FC (no firmware): the host guard and the
sender's tolerance of a slow reply. The firmware's side: test_sitl_dead_host.py."""

from __future__ import annotations

import threading
import time

import pytest

from drivers.backends.msp_fc import MspNoReply
from drivers.backends.msp_rc_esc import MspRcEsc
from drivers.codecs import msp
from drivers.codecs import msp_rc as rc
from drivers.errors import DeviceError

FAILSAFE_1S_DROP = rc.FailsafeConfig(10, 60, 1000, 0, 100, rc.DROP).to_payload()
ARM_RANGE = bytes([0, 0, 32, 48]) + bytes(4 * 19)


class ScriptedFc:
    """Answers like a 4.6.0 FC on its MSP receiver: armed while the last RC frame has
    the ARM switch on; ``slow_s`` delays the RC replies (a starved firmware)."""

    def __init__(self) -> None:
        self.armed = False
        self.slow_s = 0.0
        self.frames: list[bytes] = []
        self.failsafe = FAILSAFE_1S_DROP
        self.lock = threading.RLock()

    def request(self, m: msp.Request | msp.Unknown) -> object:
        if isinstance(m, msp.Request):
            assert m.cmd == msp.MSP_STATUS_EX, m
            return msp.StatusEx(125, 0, 0, int(self.armed), 0)
        if m.cmd == rc.MSP_FAILSAFE_CONFIG:
            return msp.Unknown(msp.REPLY, m.cmd, self.failsafe.hex())
        if m.cmd in (rc.MSP_SET_FAILSAFE_CONFIG, rc.MSP_EEPROM_WRITE):
            self.failsafe = bytes.fromhex(m.payload_hex) or self.failsafe
            return msp.Unknown(msp.REPLY, m.cmd, "")
        if m.cmd == rc.MSP_MODE_RANGES:
            return msp.Unknown(msp.REPLY, m.cmd, ARM_RANGE.hex())
        if m.cmd == rc.MSP_SET_RAW_RC:
            if self.slow_s:
                time.sleep(self.slow_s)
                raise MspNoReply("fc: no reply to MSP command 200 within 100 ms")
            payload = bytes.fromhex(m.payload_hex)
            self.frames.append(payload)
            self.armed = payload[8:10] != (1000).to_bytes(2, "little")  # AUX1
            return msp.Unknown(msp.REPLY, m.cmd, "")
        raise AssertionError(f"unexpected request {m!r}")


def test_the_host_guard_starts_at_arm_and_disarms_a_silent_host():
    fc = ScriptedFc()
    esc = MspRcEsc(fc, 0, rate_hz=100.0, host_timeout_s=0.5)
    try:
        esc.arm()
        assert fc.armed
        for _ in range(20):  # a host commanding every 20 ms keeps it armed
            esc.set_pulse_us(1500)
            time.sleep(0.02)
        assert fc.armed
        time.sleep(1.2)  # silent for over twice host_timeout_s
        assert not fc.armed
        with pytest.raises(DeviceError, match=r"no command for 0\.5 s"):
            esc.set_pulse_us(1500)
    finally:
        esc.close()
    assert not fc.armed


def test_a_late_reply_is_retried_until_the_failsafe_delay():
    fc = ScriptedFc()
    esc = MspRcEsc(fc, 0, rate_hz=100.0, failsafe_delay_s=1.5, host_timeout_s=9.0)
    assert rc.FailsafeConfig.from_payload(fc.failsafe).delay_ds == 15  # written at open
    try:
        esc.arm()
        fc.slow_s = 0.1  # late replies for well within failsafe_delay_s: the sender goes on
        time.sleep(0.3)
        fc.slow_s = 0.0
        time.sleep(0.1)
        esc.set_pulse_us(1500)
        fc.slow_s = 0.1  # late for longer than failsafe_delay_s: the sender gives up
        time.sleep(2.5)
        with pytest.raises(DeviceError, match="no reply"):
            esc.set_pulse_us(1500)
    finally:
        fc.slow_s = 0.0
        esc.close()
