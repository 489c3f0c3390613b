"""A flight controller flown on its MSP receiver: all four sticks and the ANGLE switch.

The RC control path of :class:`drivers.backends.msp_rc_esc.MspRcEsc` (ARM on an AUX
switch set through ``MSP_SET_MODE_RANGE``, a frame every period from a thread, the FC's
receiver failsafe as the dead-host stop, the host guard that disarms when the host stops
commanding) with roll, pitch and yaw sticks besides the throttle, and a second switch for
Betaflight's ANGLE mode (self-levelling: the roll and pitch sticks command angles).

Why MSP RC and not the SITL's UDP RC: once one UDP RC packet arrives the SITL's receiver
is UDP for good and never detects its loss (the sticks freeze where they were); MSP RC
goes to failsafe 150 ms after its last frame, and stage 2 disarms.
"""

from __future__ import annotations

import math
import time
from typing import Any

from drivers.backends.msp_rc_esc import MspRcEsc
from drivers.codecs import msp_rc as rc
from drivers.errors import DeviceError

__all__ = ["ANGLE_AUX", "ANGLE_BOX", "MspRcSticks"]

ANGLE_BOX = 1  # permanent box id of ANGLE (msp_box.c)
ANGLE_AUX = 1  # AUX2


class MspRcSticks(MspRcEsc):
    """Sticks (us, AETR) and the ANGLE switch of an FC armed on its MSP receiver."""

    def __init__(self, client: Any, **kwargs: Any) -> None:
        self._sticks = (rc.STICK_CENTRE_US,) * 3  # roll, pitch, yaw
        self._angle_on = False
        self.angle_range = rc.ModeRange(ANGLE_BOX, ANGLE_AUX, rc.us_to_step(1700),
                                        rc.us_to_step(2100))
        super().__init__(client, 0, url=kwargs.pop("url", "msp-rc-sticks"), **kwargs)

    def _arm_range(self) -> rc.ModeRange:
        """The ARM range (``MspRcEsc``), then an ANGLE range on AUX2 in a free slot."""
        arm = super()._arm_range()
        ranges = rc.decode_mode_ranges(self._call(rc.MSP_MODE_RANGES, what="MSP_MODE_RANGES"))
        if not any(r == self.angle_range for r in ranges):
            free = next((i for i, r in enumerate(ranges) if not r.used), None)
            if free is None:
                raise DeviceError(f"{self.url}: no free mode-range slot for an ANGLE switch")
            self._call(rc.MSP_SET_MODE_RANGE, rc.encode_mode_range(free, self.angle_range),
                       "MSP_SET_MODE_RANGE")
        return arm

    def _frame(self) -> list[int]:
        ch = super()._frame()
        ch[0], ch[1], ch[3] = self._sticks
        if self._angle_on:
            a = self.angle_range
            ch[4 + a.aux] = (rc.step_to_us(a.start_step) + rc.step_to_us(a.end_step)) // 2
        return ch

    def set_sticks(self, roll_us: float, pitch_us: float, yaw_us: float,
                   throttle_us: float, *, angle: bool) -> None:
        """The next frames' sticks (each within the valid pulse range) and ANGLE switch;
        counts as the host commanding (the host guard)."""
        values = (roll_us, pitch_us, yaw_us, throttle_us)
        if not all(math.isfinite(v) for v in values):
            raise DeviceError(f"{self.url}: sticks must be finite, got {values}")
        lo, hi = rc.RC_MIN_US, rc.RC_MAX_US
        r, p, y, t = (round(min(hi, max(lo, v))) for v in values)
        with self._lock:
            self._check()
            self._last_host_t = time.monotonic()
            self._sticks = (r, p, y)
            self._angle_on = angle
            if self._arm_on:
                self._throttle = t

    def disarm(self) -> None:
        """Sticks centred, ANGLE off, then ``MspRcEsc.disarm`` (throttle low, ARM off)."""
        with self._lock:
            self._sticks = (rc.STICK_CENTRE_US,) * 3
            self._angle_on = False
        super().disarm()
