"""Betaflight's MSP receiver and failsafe settings: the payloads of the RC control path.

A flight controller whose receiver is MSP (Betaflight's default provider; in the SITL until
the first UDP RC packet) takes its RC channels from ``MSP_SET_RAW_RC`` and, unlike the
motor test, notices when they stop: RXLOSS 150 ms after the last frame, flight channels
held for 300 ms, then stage 2 (``failsafe_delay``), which with procedure DROP disarms.
These are the payloads the bench needs for that path, little-endian as in ``msp.c``
(4.6.0): raw RC, one ARM mode range, the failsafe configuration, and the map between a
motor pulse and the RC throttle that produces it.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["ARM_BOX", "AUX_OFF_US", "AUX_ON_US", "CHANNELS", "DROP", "MSP_EEPROM_WRITE",
           "MSP_FAILSAFE_CONFIG", "MSP_MODE_RANGES", "MSP_SET_FAILSAFE_CONFIG",
           "MSP_SET_MODE_RANGE", "MSP_SET_RAW_RC", "STICK_CENTRE_US", "THROTTLE_LOW_US",
           "FailsafeConfig", "ModeRange",
           "ThrottleMap", "decode_mode_ranges", "encode_mode_range", "encode_raw_rc",
           "step_to_us", "us_to_step"]

MSP_MODE_RANGES = 34
MSP_SET_MODE_RANGE = 35
MSP_FAILSAFE_CONFIG = 75
MSP_SET_FAILSAFE_CONFIG = 76
MSP_SET_RAW_RC = 200
MSP_EEPROM_WRITE = 250

ARM_BOX = 0  # permanent box id of ARM (msp_box.c)
DROP = 1  # failsafe_procedure: 0 AUTO-LAND, 1 DROP (disarm), 2 GPS-RESCUE
CHANNELS = 10  # AETR + AUX1..6: what a non-FPU target processes; the rest would read 0
AUX_OFF_US = 1000
AUX_ON_US = 1900  # inside the usual ARM range 1700..2100
STICK_CENTRE_US = 1500
RC_MIN_US, RC_MAX_US = 885, 2115  # rx_min_usec, rx_max_usec: valid pulses
THROTTLE_LOW_US = 1000  # below min_check 1050: idle when armed, and arming allowed


def step_to_us(step: int) -> int:
    """A mode-range step as a channel value: 900 + 25 x step (rc_modes.h)."""
    return 900 + 25 * step


def us_to_step(us: int) -> int:
    return max(0, min(48, (us - 900) // 25))


def encode_raw_rc(channels: list[int] | tuple[int, ...]) -> bytes:
    """``MSP_SET_RAW_RC``: u16 per channel in raw (AETR...) order, each a valid pulse."""
    bad = [c for c in channels if not RC_MIN_US <= c <= RC_MAX_US]
    if bad or not channels:
        raise ValueError(f"MSP_SET_RAW_RC channels must be {RC_MIN_US}..{RC_MAX_US} us, "
                         f"got {list(channels)}")
    return struct.pack(f"<{len(channels)}H", *channels)


@dataclass(frozen=True)
class ModeRange:
    """One mode-activation range: box ``box`` is on while AUX ``aux`` (0 = AUX1) is in
    ``start_step .. end_step`` (both ends in 25 us steps from 900 us)."""

    box: int
    aux: int
    start_step: int
    end_step: int

    @property
    def used(self) -> bool:
        return self.start_step < self.end_step

    def contains(self, us: int) -> bool:
        return step_to_us(self.start_step) <= us <= step_to_us(self.end_step)


def decode_mode_ranges(payload: bytes) -> list[ModeRange]:
    """``MSP_MODE_RANGES`` reply: 4 bytes per slot (box, aux, start, end)."""
    if len(payload) % 4:
        raise ValueError(f"MSP_MODE_RANGES payload of {len(payload)} bytes, not 4 per slot")
    return [ModeRange(*payload[i:i + 4]) for i in range(0, len(payload), 4)]


def encode_mode_range(index: int, rng: ModeRange) -> bytes:
    """``MSP_SET_MODE_RANGE``: slot, box, aux, start, end, logic OR, no linked mode."""
    return bytes([index, rng.box, rng.aux, rng.start_step, rng.end_step, 0, 0])


@dataclass(frozen=True)
class FailsafeConfig:
    """``MSP_FAILSAFE_CONFIG``: ``delay_ds`` is stage 1's length in tenths of a second
    (1..200 in 4.6.0, applied by the next EEPROM write's ``failsafeReset``)."""

    delay_ds: int
    landing_time_s: int
    throttle_us: int
    switch_mode: int
    throttle_low_delay_ds: int
    procedure: int

    _FMT = struct.Struct("<BBHBHB")

    @classmethod
    def from_payload(cls, p: bytes) -> FailsafeConfig:
        if len(p) < cls._FMT.size:
            raise ValueError(f"MSP_FAILSAFE_CONFIG payload of {len(p)} bytes, expected "
                             f"{cls._FMT.size}")
        return cls(*cls._FMT.unpack_from(p))

    def to_payload(self) -> bytes:
        return self._FMT.pack(self.delay_ds, self.landing_time_s, self.throttle_us,
                              self.switch_mode, self.throttle_low_delay_ds, self.procedure)


@dataclass(frozen=True)
class ThrottleMap:
    """Motor pulse <-> RC throttle for an armed FC at rest (acro, no stick input, so the
    PID sum stays ~0 and every motor gets the mixer's throttle).

    Betaflight scales the throttle channel from ``min_check`` .. ``max_rc`` (1050 .. 2000 by
    default; ``thr_mid`` 50 %, ``thr_expo`` 0: linear) onto the motor range ``idle_us`` ..
    ``max_us`` (armed low 1000 + ``motor_idle`` 5.5 % = 1055, ``max_throttle`` 2000).
    Measured on the 4.6.0 SITL: within 2 us of this line from 1100 to 2000."""

    min_check_us: int = 1050
    max_rc_us: int = 2000
    idle_us: float = 1055.0
    max_us: float = 2000.0

    def rc_for(self, pulse_us: float) -> int:
        """The throttle channel that makes the motor output ``pulse_us`` (idle and below:
        the channel's low end, which the FC also needs to arm)."""
        if pulse_us <= self.idle_us:
            return THROTTLE_LOW_US
        frac = min(1.0, (pulse_us - self.idle_us) / (self.max_us - self.idle_us))
        return round(self.min_check_us + frac * (self.max_rc_us - self.min_check_us))

    def pulse_for(self, rc_us: float) -> float:
        """The motor output an armed FC gives for throttle channel ``rc_us``."""
        frac = min(1.0, max(0.0, (rc_us - self.min_check_us)
                            / (self.max_rc_us - self.min_check_us)))
        return self.idle_us + frac * (self.max_us - self.idle_us)
