"""A flight controller's motor driven through its MSP receiver: the ESC a dead host stops.

The motor test (``MspMotorEsc``) holds its last value forever when the host dies. This
path arms the FC and commands the throttle channel over ``MSP_SET_RAW_RC`` instead, from a
thread of the bench sending a frame every ``1 / rate_hz``. The FC's receiver failsafe is
then the dead-host stop: no frame for 150 ms is RXLOSS, the throttle is held for 300 ms and
then goes low (armed idle), and stage 2 (``failsafe_delay``, procedure DROP) disarms. At
open the backend sets ``failsafe_delay`` and DROP (an EEPROM write, only when they
differ: the FC applies them at its next ``failsafeReset``) and finds, or adds, an ARM
range on an AUX channel (``MSP_SET_MODE_RANGE``, effective at once).

The sender is tied to the host: while armed, if the host has not commanded for
``host_timeout_s`` (a stalled command loop) it disarms the FC through the switch and
refuses further commands. Needs Betaflight's MSP receiver: on the SITL, no UDP RC packet
may ever reach the firmware (it would switch the receiver to UDP for good, and UDP RC
never times out). Pulse to throttle: :class:`drivers.codecs.msp_rc.ThrottleMap`.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

from drivers.backends.msp_fc import MspNoReply, MspRefused
from drivers.codecs import msp
from drivers.codecs import msp_rc as rc
from drivers.contracts import ChannelInfo, DeviceInfo
from drivers.errors import DeviceError

__all__ = ["MspRcEsc"]

ARM_AUX_DEFAULT = 0  # AUX1, as in Betaflight's own SITL harness
ARM_FLAGS = {1 << 1: "FAILSAFE", 1 << 2: "RX_FAILSAFE", 1 << 3: "NOT_DISARMED",
             1 << 5: "RUNAWAY_TAKEOFF", 1 << 7: "THROTTLE", 1 << 8: "ANGLE",
             1 << 9: "BOOT_GRACE_TIME", 1 << 12: "CALIBRATING", 1 << 13: "CLI",
             1 << 28: "ARM_SWITCH"}
ARM_SWITCH = 1 << 28
DISARM_WAIT_S = 1.0
ARM_WAIT_S = 2.0  # switch on to armed: 0.06-0.11 s measured on the SITL
READY_POLL_S = 0.5  # at open: how often to ask whether the FC would arm
SWITCH_CYCLE_S = 0.3  # not armed after this long: switch off for half of it, then on


def _flags(bits: int) -> str:
    names = [n for b, n in ARM_FLAGS.items() if bits & b]
    rest = bits & ~sum(ARM_FLAGS)
    return ", ".join(names + ([f"0x{rest:x}"] if rest else [])) or "none"


class MspRcEsc:
    """Motor ``motor_index`` of an FC armed on its MSP receiver, as an ``Esc``."""

    def __init__(self, client: Any, motor_index: int, *, min_us: float = 1000.0,
                 max_us: float = 2000.0, url: str = "msp", rate_hz: float = 50.0,
                 host_timeout_s: float = 1.0, failsafe_delay_s: float = 1.0,
                 arm_timeout_s: float = 10.0) -> None:
        self.client = client
        self.motor_index = motor_index
        self.url = url
        self.map = rc.ThrottleMap()
        self.min_us = max(min_us, float(msp.MOTOR_MIN_US))
        self.max_us = min(max_us, self.map.max_us)
        self.period_s = 1.0 / rate_hz
        self.host_timeout_s = host_timeout_s
        self.arm_timeout_s = arm_timeout_s
        self.failsafe_delay_ds = round(failsafe_delay_s * 10)
        self._lock = threading.Lock()
        self._throttle = rc.THROTTLE_LOW_US
        self._arm_on = False
        self._last_host_t = time.monotonic()
        self._guarded = False  # the host guard runs from arm() returning to disarm()
        self._stalled = False
        self._error: DeviceError | None = None
        self.frames = 0
        self.max_frame_gap_s = 0.0  # between acknowledged frames while armed
        self.arming_gap_s = 0.0  # the same while arm() waits: an arm refused for RX_FAILSAFE
        self._stop = threading.Event()
        self._frame_done = threading.Event()
        self._thread = threading.Thread(target=self._send_loop, name=f"msp-rc-{url}",
                                        daemon=True)
        self._configure_failsafe()
        self.arm_range = self._arm_range()
        self._thread.start()
        try:
            self._wait_ready()
        except BaseException:
            self.close()
            raise

    # -- set-up ---------------------------------------------------------------------------

    def _call(self, cmd: int, payload: bytes = b"", what: str = "") -> bytes:
        try:
            reply = self.client.request(msp.Unknown(msp.REQUEST, cmd, payload.hex()))
        except MspRefused:
            raise DeviceError(f"{self.url}: the flight controller refused {what or cmd}: "
                                  "the RC control path needs Betaflight's MSP receiver; for "
                                  "the motor test remove the propeller and set "
                                  "options.propellers_off = true") from None
        return bytes.fromhex(getattr(reply, "payload_hex", ""))

    def _status(self) -> msp.StatusEx:
        """STATUS_EX, sent just after an RC frame went through (while the sender runs):
        the FC answers one command at a time, so a poll never delays a due frame."""
        if self._thread.is_alive():
            self._frame_done.clear()
            self._frame_done.wait(2 * self.period_s)
        reply = self.client.request(msp.Request(msp.MSP_STATUS_EX))
        if not isinstance(reply, msp.StatusEx):
            raise DeviceError(f"{self.url}: unexpected status reply {reply!r}")
        return reply

    def _configure_failsafe(self) -> None:
        """Stage 2 after ``failsafe_delay``, procedure DROP; written only if different."""
        have = rc.FailsafeConfig.from_payload(
            self._call(rc.MSP_FAILSAFE_CONFIG, what="MSP_FAILSAFE_CONFIG"))
        want = rc.FailsafeConfig(self.failsafe_delay_ds, have.landing_time_s,
                                 have.throttle_us, have.switch_mode,
                                 have.throttle_low_delay_ds, rc.DROP)
        if want == have:
            return
        if self._status().armed:
            raise DeviceError(f"{self.url}: the flight controller is armed; its failsafe "
                              "can only be configured disarmed (disarm it first)")
        self._call(rc.MSP_SET_FAILSAFE_CONFIG, want.to_payload(), "MSP_SET_FAILSAFE_CONFIG")
        self._call(rc.MSP_EEPROM_WRITE, what="MSP_EEPROM_WRITE")  # applies it (failsafeReset)

    def _arm_range(self) -> rc.ModeRange:
        """The FC's ARM range if it has one, else ARM on AUX1 at 1700..2100 in a free slot."""
        ranges = rc.decode_mode_ranges(self._call(rc.MSP_MODE_RANGES, what="MSP_MODE_RANGES"))
        for r in ranges:
            if r.box == rc.ARM_BOX and r.used and r.aux + 4 < rc.CHANNELS \
                    and not r.contains(rc.AUX_OFF_US):
                return r
        free = next((i for i, r in enumerate(ranges) if not r.used), None)
        if free is None:
            raise DeviceError(f"{self.url}: no free mode-range slot for an ARM switch")
        arm = rc.ModeRange(rc.ARM_BOX, ARM_AUX_DEFAULT, rc.us_to_step(1700),
                           rc.us_to_step(2100))
        self._call(rc.MSP_SET_MODE_RANGE, rc.encode_mode_range(free, arm), "MSP_SET_MODE_RANGE")
        return arm

    # -- the sender -----------------------------------------------------------------------

    def _frame(self) -> list[int]:
        ch = [rc.STICK_CENTRE_US] * 4 + [rc.AUX_OFF_US] * (rc.CHANNELS - 4)
        ch[2] = self._throttle
        r = self.arm_range
        if self._arm_on:
            ch[4 + r.aux] = (rc.step_to_us(r.start_step) + rc.step_to_us(r.end_step)) // 2
        return ch

    def _send_loop(self) -> None:
        """One frame per period; late, it skips ahead (a burst would not help the FC). A
        reply later than the client's timeout is retried, not fatal, until no frame has
        gone through for the FC's own ``failsafe_delay``: by then its failsafe acts."""
        due = last_ok = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due = max(due + self.period_s, time.monotonic())
            with self._lock:
                if self._guarded and time.monotonic() - self._last_host_t > self.host_timeout_s:
                    self._stalled = True  # the host stopped commanding: disarm by switch
                    self._guarded = self._arm_on = False
                    self._throttle = rc.THROTTLE_LOW_US
                frame = rc.encode_raw_rc(self._frame())
                guarded = self._guarded
            try:
                self._call(rc.MSP_SET_RAW_RC, frame, "MSP_SET_RAW_RC")
            except DeviceError as exc:
                if isinstance(exc, MspNoReply) and \
                        time.monotonic() - last_ok < self.failsafe_delay_ds / 10:
                    continue
                self._error = exc  # raised by the host's next command; the FC's failsafe acts
                return
            now = time.monotonic()
            if guarded:  # armed and commanded: the gap the FC's failsafe must tolerate
                self.max_frame_gap_s = max(self.max_frame_gap_s, now - last_ok)
            self.arming_gap_s = max(self.arming_gap_s, now - last_ok)
            last_ok = now
            self.frames += 1
            self._frame_done.set()

    def _check(self) -> None:
        if self._error is not None:
            raise self._error
        if self._stalled:
            raise DeviceError(f"{self.url}: disarmed: the host sent no command for "
                              f"{self.host_timeout_s:g} s")

    # -- Esc ------------------------------------------------------------------------------

    def describe(self) -> DeviceInfo:
        return DeviceInfo(
            kind="esc", model="flight controller armed on its MSP receiver (MSP_SET_RAW_RC)",
            url=self.url,
            channels=(ChannelInfo("throttle_us", "us", 1.0 / self.period_s, self.min_us,
                                  self.max_us),),
            extra={"motor_index": self.motor_index, "control": "rc",
                   "rc_rate_hz": 1.0 / self.period_s, "host_timeout_s": self.host_timeout_s,
                   "failsafe_delay_s": self.failsafe_delay_ds / 10, "failsafe": "DROP",
                   "arm_aux": self.arm_range.aux + 1,
                   "dead_host": "the FC's receiver failsafe: throttle low, then disarmed"})

    def _wait_ready(self) -> None:
        """Wait (at open, not in the command loop) until only the ARM switch keeps the FC
        from arming: the boot grace (5 s after the FC starts), 0.5 s of valid RC, an
        established attitude."""
        deadline = time.monotonic() + self.arm_timeout_s
        while True:
            if self._error is not None:
                raise self._error
            flags = self._status().arming_disable_flags
            if not flags & ~ARM_SWITCH:
                return
            if time.monotonic() > deadline:
                raise DeviceError(f"{self.url}: the flight controller does not allow arming "
                                  f"within {self.arm_timeout_s:g} s ({_flags(flags)}; "
                                  f"{self.frames} RC frames sent)")
            time.sleep(READY_POLL_S)  # the RC frames come first: RX_FAILSAFE clears only
            # after 0.5 s of frames never 150 ms apart

    def arm(self) -> None:
        """ARM switch on with the throttle low; returns once the FC says armed. The host
        guard starts when this returns: a status reply slow under load is not a stalled
        host."""
        with self._lock:
            if self._error is not None:
                raise self._error
            self._stalled = self._guarded = False
            self._throttle = rc.THROTTLE_LOW_US
            self._arm_on = True
            self.arming_gap_s = 0.0
        deadline = time.monotonic() + ARM_WAIT_S
        cycle_at = time.monotonic() + SWITCH_CYCLE_S
        while not self._status().armed:
            if time.monotonic() > cycle_at:  # the FC may want the switch seen off again
                self._set_switch(False)      # (e.g. just after a failsafe): cycle it
                time.sleep(SWITCH_CYCLE_S / 2)
                self._set_switch(True)
                cycle_at = time.monotonic() + SWITCH_CYCLE_S
            if time.monotonic() > deadline:
                flags = _flags(self._status().arming_disable_flags)
                self.disarm()
                raise DeviceError(f"{self.url}: the flight controller did not arm within "
                                  f"{ARM_WAIT_S:g} s ({flags}; RC frames at most "
                                  f"{1e3 * self.arming_gap_s:.0f} ms apart)")
            time.sleep(0.02)
        with self._lock:
            self._last_host_t = time.monotonic()
            self._guarded = True

    def _set_switch(self, on: bool) -> None:
        with self._lock:
            self._arm_on = on

    def set_pulse_us(self, pulse_us: float) -> None:
        pulse = float(pulse_us)
        if not math.isfinite(pulse):
            raise DeviceError(f"{self.url}: pulse width must be finite, got {pulse_us!r}")
        with self._lock:
            self._check()
            self._last_host_t = time.monotonic()
            if self._arm_on:
                self._throttle = self.map.rc_for(min(self.max_us, max(self.min_us, pulse)))

    def disarm(self) -> None:
        """Throttle low and ARM off, then wait (at most 1 s) for the FC to say disarmed.
        Never raises: the FC's receiver failsafe is the fallback."""
        with self._lock:
            self._guarded = self._arm_on = False
            self._throttle = rc.THROTTLE_LOW_US
        deadline = time.monotonic() + DISARM_WAIT_S
        while time.monotonic() < deadline and self._thread.is_alive():
            try:
                if not self._status().armed:
                    return
            except DeviceError:
                return
            time.sleep(0.02)

    def close(self) -> None:
        self.disarm()
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
