"""The host guard both CAN ESC backends share (VESC, DroneCAN).

A CAN ESC stops when its commands stop, so the backend's own thread repeats the command
every ``period_s``; but only while the host itself keeps commanding. When the host has
not called ``set_pulse_us`` for ``host_timeout_s`` (a stalled host), the thread sends one
stop command and stops refreshing, and the ESC's own timeout keeps the motor off. An
error on that thread is kept and raised by the host's next command.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

from drivers.contracts import ChannelInfo, DeviceInfo
from drivers.errors import DeviceError

__all__ = ["DutyEsc", "HostGuardedCanEsc"]


class HostGuardedCanEsc:
    """Base of the CAN ``Esc`` backends. A subclass sets its own state first, then calls
    ``__init__`` (which starts the refresh thread), and fills in the hooks below."""

    def __init__(self, url: str, period_s: float, host_timeout_s: float,
                 thread_name: str) -> None:
        self.url = url
        self._period_s = period_s
        self._host_timeout_s = host_timeout_s
        self._lock = threading.Lock()
        self._armed = False
        self._last_host_t = time.monotonic()
        self._stalled = False
        self._error: DeviceError | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._refresh, name=thread_name, daemon=True)
        self._thread.start()

    # -- what a subclass fills in (called with the lock held) ---------------------------

    def _hold(self, pulse_us: float) -> None:
        """Keep ``pulse_us`` as the command in force."""
        raise NotImplementedError

    def _hold_idle(self) -> None:
        raise NotImplementedError

    def _send_held(self) -> None:
        """Send the command in force (a stop while disarmed)."""
        raise NotImplementedError

    def _send_stop(self) -> None:
        raise NotImplementedError

    def _each_period(self, now: float) -> None:
        """Anything the thread sends every period, armed or not."""

    # -- Esc ----------------------------------------------------------------------------

    def arm(self) -> None:
        with self._lock:
            self._raise_pending()
            self._armed = True
            self._hold_idle()
            self._touch()
            self._send_held()

    def set_pulse_us(self, pulse_us: float) -> None:
        pulse = float(pulse_us)
        if not math.isfinite(pulse):
            raise DeviceError(f"{self.url}: pulse width must be finite, got {pulse_us!r}")
        with self._lock:
            self._raise_pending()
            self._hold(pulse)
            self._touch()
            if self._armed:
                self._send_held()

    def disarm(self) -> None:
        """Idle + disarm (a stop command). Never raises: the ESC's own command timeout is
        the fallback when the bus is gone."""
        with self._lock:
            self._armed = False
            self._hold_idle()
            try:
                self._send_held()
            except DeviceError:
                pass

    def close(self) -> None:
        self.disarm()
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)

    @property
    def host_stalled(self) -> bool:
        """True once the refresh has stopped the motor because the host went silent."""
        return self._stalled

    # -- guard --------------------------------------------------------------------------

    def _touch(self) -> None:
        self._last_host_t = time.monotonic()
        self._stalled = False

    def _raise_pending(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def _refresh(self) -> None:
        while not self._stop.wait(self._period_s):
            with self._lock:
                now = time.monotonic()
                try:
                    self._each_period(now)
                    if not self._armed:
                        continue
                    if now - self._last_host_t > self._host_timeout_s:
                        if not self._stalled:
                            self._send_stop()
                            self._stalled = True
                        continue  # stopped; the ESC's own timeout keeps it off
                    self._send_held()
                except DeviceError as exc:
                    self._error = exc


class DutyEsc(HostGuardedCanEsc):
    """A host-guarded ESC commanded by duty (the VESC on CAN and on USB/UART): the pulse
    width in force, clamped to ``settings.min_us .. max_us``, maps linearly to duty 0..1;
    disarmed or at idle it is 0. A subclass sends ``_duty()`` in ``_send_held``."""

    def __init__(self, link: Any, settings: Any, url: str, command_timeout_s: float,
                 thread_name: str) -> None:
        """``settings``: min_us, max_us, keepalive_s (inside the ESC's own
        ``command_timeout_s``), host_timeout_s."""
        if settings.keepalive_s >= command_timeout_s:
            raise DeviceError(f"{url}: keepalive_s must be below the VESC's "
                              f"{command_timeout_s} s command timeout")
        self.link = link
        self.settings = settings
        self._pulse_us = settings.min_us
        super().__init__(url, settings.keepalive_s, settings.host_timeout_s, thread_name)

    def _info(self, model: str, extra: dict[str, Any]) -> DeviceInfo:
        s = self.settings
        return DeviceInfo(
            kind="esc", model=model, url=self.url,
            channels=(ChannelInfo("throttle_us", "us", 1.0 / s.keepalive_s, s.min_us, s.max_us),),
            extra={"keepalive_s": s.keepalive_s, "host_timeout_s": s.host_timeout_s,
                   "command": "SET_DUTY (linear)", **extra})

    def _hold(self, pulse_us: float) -> None:
        s = self.settings
        self._pulse_us = min(s.max_us, max(s.min_us, pulse_us))

    def _hold_idle(self) -> None:
        self._pulse_us = self.settings.min_us

    def _duty(self) -> float:
        if not self._armed:
            return 0.0
        s = self.settings
        return min(1.0, max(0.0, (self._pulse_us - s.min_us) / (s.max_us - s.min_us)))
