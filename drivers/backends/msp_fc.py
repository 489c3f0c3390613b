"""A flight controller over MSP (serial): the IMU under test and a motor-test ESC.

``MspClient`` does request/response on one port (protocols.md §1: strictly request/
response, no documented deadline; 100 ms is the reference's suggested client timeout
[U]). ``MspImu`` polls RAW_IMU and ATTITUDE on a thread and hands the rows out as a
``Sensor``; ``MspMotorEsc`` drives one motor through MSP_SET_MOTOR as an ``Esc``;
``MspImuSensor`` is ``MspImu`` as the IMU bench's IMU under test (``IMU_CHANNELS``).

The IMU under test: INAV sends the gyro of RAW_IMU (§1.4) in whole deg/s, Betaflight in
the gyro's counts, 16.4 per deg/s (``msp.BTFL_GYRO_LSB_PER_DPS``; ``gyro_lsb_per_dps``
for a gyro at another range);
the accelerometer in counts, 1 g = ``acc_1g`` (Betaflight: the driver's ``acc_1G``, 2048
for the MPU6000/6050/ICM-2060x class at ±16 g; INAV: always 512). RAW_IMU carries no time
stamp, so a row is stamped with the host clock when its request went out: the FC's
sensor/filter latency and the wire's latency become part of the hexapod-IMU time offset
the calibration estimates, and their jitter is noise; unless the FC tells its clock in the
same reply (Betaflight: ``MSP_SET_RTC`` once, then ``MSP_RTC`` in each poll's
``MSP_MULTIPLE_MSP``, ``MspImu._poll``), which keeps that jitter out.

Safety, from §1.7: Betaflight applies SET_MOTOR values **only while disarmed** (the
configurator motor test), and the motors then really spin. Betaflight and INAV keep the
last motor-test value with no expiry (docs/protocols.md, "dead host"): a host that dies
leaves the motor running. ``MspMotorEsc`` therefore refuses to open unless the rig says
the propeller is off (``propellers_off``), refuses to start while the FC reports itself
armed (STATUS_EX flight-mode flag bit 0), and ``close()``/``disarm()`` always send every
motor to 1000.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.backends.serial_link import Deadline, read_some, write_all
from drivers.codecs import msp
from drivers.codecs.stream import link_losses
from drivers.contracts import (
    IMU_ATTITUDE_CHANNELS,
    Block,
    ChannelInfo,
    Clock,
    DeviceInfo,
    MonotonicClock,
)
from drivers.contracts import IMU_CHANNELS as BENCH_IMU_CHANNELS
from drivers.errors import DeviceError

DEFAULT_TIMEOUT_S = 0.1  # §1.9 timing note: ~100 ms at 115200 baud [U]
#: an MSP request unanswered this long is sent again (``MspClient.request``): the FCs here
#: answer within 10-20 ms (a serial task at 100 Hz)
RESEND_AFTER_S = 0.05
#: an IMU poll with no reply for this long has lost its FC (a single missed reply is a
#: frame lost on the line, counted, and the poll goes on): the silence a run allows any
#: device (``bench.engine.run_loop``'s ``stale_s``)
NO_REPLY_LIMIT_S = 0.5


class MspRefused(DeviceError):
    """The FC answered a command with MSP's error flag: it does not know or allow it. A
    caller with a fallback (an older firmware's STATUS, a clock it need not set) catches
    this one; any other device error stays an error."""


class MspNoReply(DeviceError):
    """No reply to a command within the client's timeout."""


class MspClient:
    """Request/response over one serial port, shared by the IMU poller and the ESC."""

    def __init__(self, port: Any, name: str = "msp", *, timeout_s: float = DEFAULT_TIMEOUT_S,
                 version: int = 1, max_payload: int = 512) -> None:
        self.port = port
        self.name = name
        self.timeout_s = timeout_s
        self.version = version
        self.decoder = msp.MspDecoder(max_payload, typed=True)
        self.lock = threading.RLock()
        self.resends = 0  # requests sent again (``request``)
        self.stale_replies = 0  # earlier requests' replies passed over (``request``)

    def request(self, message: msp.MspMessage, *, resend: bool = True,
                stale: Callable[[msp.MspMessage], bool] | None = None) -> msp.MspMessage:
        """Send a request (or SET command) and return the FC's reply to that command.
        A reply ``stale`` says is an earlier request's (counted, ``stale_replies``) is
        passed over, and the wait goes on for this request's own.

        With ``resend``, a request not answered within ``RESEND_AFTER_S`` is sent again,
        then after twice that, and so on until ``timeout_s``: a reply lost on the link (a
        UART's noise; the SITL's TCP thread drops and repeats reply bytes, a race in its
        ``dyad`` buffer, docs/protocols.md) costs that wait, not the whole timeout, as
        Betaflight Configurator sends an unanswered request again after its ``MSP.TIMEOUT``.
        The commands sent here set values or read them, so a second one does what the first
        did; the doubling bounds what a stalled FC has queued when it wakes. A poll asks
        without: its next poll is its retry, and a second reply to a slow request would be
        taken by the polls after it, each stamped a poll late."""
        if isinstance(message, msp.Request | msp.Ack | msp.ErrorReply | msp.Unknown):
            cmd = message.cmd  # the messages without a CMD of their own
        else:
            cmd = message.CMD
        frame = msp.encode_message(message, self.version)
        with self.lock:
            self._drop_waiting()
            write_all(self.port, frame, self.name)
            deadline = Deadline(self.timeout_s)
            wait = RESEND_AFTER_S
            resend_at = time.monotonic() + wait if resend else math.inf
            while True:
                # the timeout stands only if a read begun after the deadline finds no
                # reply: a host that was itself off the processor past it reads the reply
                # that waits in the port's buffer (the FC did answer in time)
                last_look = deadline.expired
                for reply in self.decoder.feed(read_some(self.port, self.name)):
                    if getattr(reply, "cmd", getattr(reply, "CMD", None)) != cmd:
                        continue  # a late reply to an earlier request
                    if isinstance(reply, msp.ErrorReply):
                        raise MspRefused(f"{self.name}: FC refused MSP command {cmd}")
                    if isinstance(reply, (msp.Request, msp.SetMotor)):
                        continue  # our own request echoed (loopback)
                    if stale is not None and stale(reply):
                        self.stale_replies += 1
                        continue
                    return reply
                if last_look:
                    raise MspNoReply(f"{self.name}: no reply to MSP command {cmd} within "
                                      f"{self.timeout_s * 1e3:.0f} ms")
                if time.monotonic() >= resend_at:
                    write_all(self.port, frame, self.name)
                    self.resends += 1
                    wait *= 2
                    resend_at = time.monotonic() + wait

    def _drop_waiting(self) -> None:
        """Drop what waits unread before a request: a reply that came after its request
        was given up on, which MSP (no sequence numbers) would otherwise hand to this
        request if it is of the same command."""
        try:
            waiting = self.port.in_waiting
        except (OSError, AttributeError, TypeError, ValueError):
            return  # a port closed or gone (pyserial's closed port: TypeError): the write
            # that follows says so
        if waiting > 0:
            self.decoder.feed(read_some(self.port, self.name))  # counted, and dropped

    def identify(self) -> tuple[str, msp.ApiVersion]:
        variant = self.request(msp.Request(msp.MSP_FC_VARIANT))
        api = self.request(msp.Request(msp.MSP_API_VERSION))
        if not isinstance(variant, msp.FcVariant) or not isinstance(api, msp.ApiVersion):
            raise DeviceError(f"{self.name}: unexpected identification replies")
        return variant.name, api

    def firmware(self) -> dict[str, str]:
        """Variant, MSP API, firmware version and board: what a bring-up report shows.
        FC_VERSION / BOARD_INFO an older firmware refuses are left out."""
        variant, api = self.identify()
        out = {"variant": variant, "msp_api": f"{api.api_major}.{api.api_minor}"}
        for cmd, key in ((msp.MSP_FC_VERSION, "version"), (msp.MSP_BOARD_INFO, "board")):
            try:
                reply = self.request(msp.Request(cmd))
            except MspRefused:
                continue
            if isinstance(reply, msp.FcVersion):
                out[key] = str(reply)
            elif isinstance(reply, msp.BoardInfo):
                out[key] = reply.board_id + (f" ({reply.target_name})" if reply.target_name
                                             else "")
        return out

    def armed(self) -> bool:
        """Arming state from STATUS_EX (STATUS where refused): flight-mode flag bit 0."""
        try:
            reply = self.request(msp.Request(msp.MSP_STATUS_EX))
        except MspRefused:
            reply = self.request(msp.Request(msp.MSP_STATUS))
        if not isinstance(reply, (msp.StatusEx, msp.FcStatus)):
            raise DeviceError(f"{self.name}: unexpected status reply {reply!r}")
        return bool(reply.flight_mode_flags & msp.ARMED_FLAG)


#: what the IMU role asks a Betaflight FC for in one MSP_MULTIPLE_MSP request
RAW_AND_ATTITUDE = (msp.MSP_RAW_IMU, msp.MSP_ATTITUDE)
OFFSET_ROWS = 400  # the rows whose best bound gives the FC's clock against the host's
IMU_CHANNELS = ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2", "gyro_x_rad_s", "gyro_y_rad_s",
                "gyro_z_rad_s", "roll_rad", "pitch_rad", "yaw_rad")


class MspImu:
    """The FC's IMU and attitude, polled at ``rate_hz`` on a thread (``Sensor``)."""

    def __init__(self, client: MspClient, *, rate_hz: float = 100.0, acc_1g: float | None = None,
                 clock: Clock | None = None, url: str = "serial://msp",
                 attitude: bool = True, gyro_lsb_per_dps: float | None = None,
                 multiple: bool = False, max_round_trip_s: float = math.inf) -> None:
        self.client = client
        self.multiple = multiple  # Betaflight: both in one MSP_MULTIPLE_MSP round trip
        # the FC read its sensors somewhere between request and reply: a row whose round
        # trip took longer has a time stamp worse than that, and is dropped
        self.max_round_trip_s = max_round_trip_s
        self.slow_rows = 0
        self.missed_replies = 0
        self.rate_hz = rate_hz
        self.attitude = attitude  # False: RAW_IMU only (roll/pitch/yaw NaN), twice the rate
        self.clock = clock or MonotonicClock()
        self.url = url
        self.variant, self.api = client.identify()
        self.acc_1g = acc_1g
        self.gyro_lsb_per_dps = gyro_lsb_per_dps
        try:  # fail at open, not in the poller, when the scaling is unknown
            msp.imu_si(msp.RawImu((0, 0, 0), (0, 0, 0), (0, 0, 0)), self.variant, acc_1g)
        except ValueError as exc:
            raise DeviceError(f"{url}: {exc}") from None
        self._rows: list[tuple[float, ...]] = []
        # each timed row's bound on the FC's clock against the host's (_serve_delay), and
        # the whole second the FC's clock was set to (_set_rtc)
        self._bounds: collections.deque[float] = collections.deque(maxlen=OFFSET_ROWS)
        self._rtc_set_s = 0
        # a timed poll's request (_request), made once: it goes out hundreds of times a second
        self._timed_cmds = (*(RAW_AND_ATTITUDE if attitude else RAW_AND_ATTITUDE[:1]),
                            msp.MSP_RTC)
        self._timed_request = msp.multiple_request(self._timed_cmds)
        self._error: DeviceError | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, name=f"msp-imu-{url}", daemon=True)
        self._thread.start()

    def describe(self) -> DeviceInfo:
        units = ["m/s^2"] * 3 + ["rad/s"] * 3 + ["rad"] * 3
        return DeviceInfo(kind="imu", model=f"flight controller ({self.variant}, MSP API "
                          f"{self.api.api_major}.{self.api.api_minor})", url=self.url,
                          channels=tuple(ChannelInfo(n, u, self.rate_hz)
                                         for n, u in zip(IMU_CHANNELS, units, strict=True)))

    def _poll(self) -> None:
        """Polls on a fixed schedule (a slow reply delays one poll, not all later ones). A
        reply that does not come is counted (``link_errors``: ``no_reply``) and the poll
        goes on, as over a UART that lost a frame (its requests are not sent again: the next
        poll is the retry); the next poll's row is dropped (it may have been handed the late
        reply). A reply still later is dropped before a later request is sent
        (``MspClient._drop_waiting``), unless it comes inside that request's round trip,
        ahead of its own reply: no MSP client can tell the two apart, but a timed poll (below)
        can, by the FC's clock (served before the last row), and waits on for its own
        reply, which would otherwise be handed to the next request and, a poll too early
        for it, move the clocks' offset. No reply for ``NO_REPLY_LIMIT_S`` is the FC
        gone, and ends the poll with the error.

        An FC that takes the host's time (``MSP_SET_RTC``) and answers ``MSP_MULTIPLE_MSP``
        (Betaflight) is asked its clock (``MSP_RTC``) in each poll's request, read by the
        firmware within microseconds of RAW_IMU: the row is stamped when the FC served it
        (``_serve_delay``), not when the host sent for it, so the host's and the link's
        latency jitter (a loaded host's, or a simulated FC's at its time scale) stays out
        of the stamps. Its clock counts whole milliseconds."""
        period = 1.0 / self.rate_hz
        nan = msp.Attitude(math.nan, math.nan, math.nan)
        try:
            timed = self._set_rtc()
        except DeviceError as exc:
            with self._lock:
                self._error = exc
            return
        due = last_reply = time.monotonic()
        after_miss = False
        last_served_ms = -1
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due = max(due + period, time.monotonic() - period)
            # the FC answers with its latest sample, taken about when the request arrives:
            # the send time is the host time least disturbed by the reply's read latency
            stamp = self.clock.now()
            paused = getattr(self.clock, "paused_s", 0.0)  # a paced clock's stalls
            try:
                raw, att, served_ms = self._request(nan, timed, last_served_ms)
            except MspRefused as exc:
                if not timed:
                    with self._lock:
                        self._error = exc
                    return
                timed = False  # MSP_MULTIPLE_MSP refused (INAV): the send-time stamps
                continue
            except MspNoReply as exc:
                if time.monotonic() - last_reply > NO_REPLY_LIMIT_S:
                    with self._lock:
                        self._error = DeviceError(f"{exc} (none for {NO_REPLY_LIMIT_S:g} s)")
                    return
                self.missed_replies += 1  # a reply lost on the line, or late: if late,
                after_miss = True  # the next poll may be handed it, and is not kept
                continue
            except DeviceError as exc:
                with self._lock:
                    self._error = exc
                return
            last_reply = time.monotonic()
            if after_miss:
                after_miss = False
                self.slow_rows += 1
                continue
            if served_ms is None:
                self._add_row(stamp, paused, raw, att)
            else:  # the rig's clock runs at the FC's rate: a real one's, or a world's paced
                last_served_ms = served_ms
                self._add_row(stamp + self._serve_delay(served_ms, stamp), paused, raw, att,
                              timed=True)

    def _set_rtc(self) -> bool:
        """Set the FC's clock to the time of day, as the radios' and ground stations' MSP
        scripts do on connect (its blackbox logs keep true dates); False when the FC
        refuses it or says nothing."""
        self._rtc_set_s = int(time.time())
        try:
            self.client.request(msp.set_rtc_request(self._rtc_set_s))
        except (MspRefused, MspNoReply):
            return False
        return True

    def _serve_delay(self, served_ms: int, sent: float) -> float:
        """From the request's send (``sent``, on a host clock at the rate of the FC's) to
        the FC's serving it, in seconds. The FC's clock against the host's is offset by the
        largest ``sent - served`` of the last ``OFFSET_ROWS`` rows (a request is served
        after it was sent; the fastest one was served at once); both clocks run on through
        any pause of the rig's (a row spanning one is dropped), so the offset holds. Half a
        millisecond is added: the FC's clock counts whole ones."""
        served = (served_ms - self._rtc_set_s * 1000) / 1000.0
        self._bounds.append(sent - served)
        return served + max(self._bounds) - sent + 5e-4

    def _add_row(self, stamp: float, paused: float, raw: Any, att: Any, *,
                 timed: bool = False) -> None:
        """One row stamped ``stamp``, unless its round trip was too long (see __init__)
        and the FC did not say itself when it read its sensors (``timed``)."""
        if not isinstance(raw, msp.RawImu) or not isinstance(att, msp.Attitude):
            return
        if (not timed and self.clock.now() - stamp > self.max_round_trip_s) or \
                getattr(self.clock, "paused_s", 0.0) != paused:
            self.slow_rows += 1  # (a paced clock does not count what it paused)
            return
        acc, gyro = msp.imu_si(raw, self.variant, self.acc_1g,
                               gyro_lsb_per_dps=self.gyro_lsb_per_dps)
        with self._lock:
            self._rows.append((stamp, *acc, *gyro, att.roll_rad, att.pitch_rad, att.yaw_rad))

    def _request(self, nan: msp.Attitude, timed: bool = False,
                 served_after_ms: int = -1) -> tuple[Any, Any, int | None]:
        """RAW_IMU and ATTITUDE, and the FC's clock when ``timed``: one MSP_MULTIPLE_MSP
        round trip with ``multiple`` or ``timed``; a timed reply the FC served before
        ``served_after_ms`` is an earlier request's, passed over."""
        request = self.client.request
        if timed:
            cmds = self._timed_cmds
            # the last reply the check split, with its parts and the FC's clock: the reply
            # taken is the last one checked, so it is not split a second time
            checked: msp.MspMessage | None = None
            parts: list[msp.MspMessage] = []
            served_ms: int | None = None

            def stale(reply: msp.MspMessage) -> bool:
                nonlocal checked, parts, served_ms
                try:
                    parts = msp.split_multiple(cmds, reply)
                except msp.PayloadError:
                    return False  # not a timed reply: _split says so
                checked, served_ms = reply, msp.rtc_ms(parts[-1])
                return served_ms is not None and served_ms < served_after_ms

            reply = request(self._timed_request, resend=False, stale=stale)
            if checked is not reply:
                self._split(reply, cmds)  # raises: not a timed reply
            raw, *rest, _ = parts  # rest: ATTITUDE, if asked
            return raw, rest[0] if rest else nan, served_ms
        if self.attitude and self.multiple:
            raw, att = self._split(request(msp.multiple_request(RAW_AND_ATTITUDE), resend=False))
            return raw, att, None
        raw = request(msp.Request(msp.MSP_RAW_IMU), resend=False)
        att = request(msp.Request(msp.MSP_ATTITUDE), resend=False) if self.attitude else nan
        return raw, att, None

    def _split(self, reply: msp.MspMessage,
               cmds: tuple[int, ...] = RAW_AND_ATTITUDE) -> list[msp.MspMessage]:
        """The replies to ``cmds`` (RAW_IMU, ATTITUDE) out of a MSP_MULTIPLE_MSP reply
        (``DeviceError`` if not)."""
        try:
            return msp.split_multiple(cmds, reply)
        except msp.PayloadError as exc:
            raise DeviceError(f"{self.url}: {exc}") from None

    def link_errors(self) -> dict[str, int]:
        """Replies lost on the serial link (bad checksums, truncated, malformed frames;
        requests no reply came to)."""
        lost = link_losses(self.client.decoder.stats)
        return {**lost, "no_reply": self.missed_replies} if self.missed_replies else lost

    def read_block(self) -> Block:
        with self._lock:
            rows, self._rows = self._rows, []
            err = self._error
        if err is not None:
            raise err
        if not rows:
            return Block.empty(IMU_CHANNELS)
        arr = np.array(rows, dtype=float)
        return Block(arr[:, 0], {n: arr[:, k + 1] for k, n in enumerate(IMU_CHANNELS)})

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)


DEAD_HOST = ("Betaflight and INAV keep the last MSP_SET_MOTOR value when the host stops "
             "sending (no timeout), so a dead host leaves the motor running")


class MspMotorEsc:
    """One motor of the FC driven by MSP_SET_MOTOR (motor test, FC disarmed) as an ``Esc``.

    The FC must stay *disarmed* for the values to apply (§1.7): ``arm()`` reads the
    arming state and refuses while the FC is armed. The FC holds the last value if the
    host dies, so the backend opens only for runs with the propeller off
    (``propellers_off=True``).
    """

    def __init__(self, client: MspClient, motor_index: int, *, min_us: float = 1000.0,
                 max_us: float = 2000.0, url: str = "serial://msp",
                 propellers_off: bool = False) -> None:
        if not propellers_off:
            raise DeviceError(f"{url}: MSP motor test refused for a propellers-on run: "
                              f"{DEAD_HOST}; remove the propeller and set "
                              "options.propellers_off = true, or use a VESC, DroneCAN or "
                              "NI-DAQmx ESC")
        if not 0 <= motor_index < msp.MOTOR_SLOTS:
            raise DeviceError(f"{url}: motor index must be 0..{msp.MOTOR_SLOTS - 1}")
        self.client = client
        self.motor_index = motor_index
        self.min_us = max(min_us, msp.MOTOR_MIN_US)
        self.max_us = min(max_us, msp.MOTOR_MAX_US)
        self.url = url
        self._armed = False
        self.resent = 0

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind="esc", model="flight controller motor test (MSP_SET_MOTOR)",
                          url=self.url,
                          channels=(ChannelInfo("throttle_us", "us", 0.0, self.min_us,
                                                self.max_us),),
                          extra={"motor_index": self.motor_index, "propellers_off": True,
                                 "dead_host": DEAD_HOST})

    def _send(self, pulse_us: float) -> None:
        """SET_MOTOR, sent again while no reply comes (``MspClient.request``): it sets
        every motor's value, so a second one does what the first did (a reply lost on the
        line does not end a run)."""
        values = [msp.MOTOR_MIN_US] * msp.MOTOR_SLOTS
        values[self.motor_index] = round(pulse_us)
        with self.client.lock:  # the resends of this request only (others share the client)
            before = self.client.resends
            try:
                reply = self.client.request(msp.SetMotor(tuple(values)))
            finally:
                self.resent += self.client.resends - before
        if not isinstance(reply, msp.Ack):
            raise DeviceError(f"{self.url}: SET_MOTOR not acknowledged ({reply!r})")

    def link_errors(self) -> dict[str, int]:
        """SET_MOTOR commands sent again because no reply came in time."""
        return {"resent": self.resent} if self.resent else {}

    def arm(self) -> None:
        if self.client.armed():
            raise DeviceError(f"{self.url}: the flight controller is armed; motor-test "
                              "values apply only while it is disarmed (disarm it first)")
        self._send(msp.MOTOR_MIN_US)
        self._armed = True

    def set_pulse_us(self, pulse_us: float) -> None:
        pulse = float(pulse_us)
        if not math.isfinite(pulse):
            raise DeviceError(f"{self.url}: pulse width must be finite, got {pulse_us!r}")
        if self._armed:
            self._send(min(self.max_us, max(self.min_us, pulse)))

    def disarm(self) -> None:
        """Every motor to 1000 (stop). Never raises."""
        self._armed = False
        try:
            self._send(msp.MOTOR_MIN_US)
        except DeviceError:
            pass

    def close(self) -> None:
        self.disarm()


_MSP_GYRO = ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")
#: a row polled further than this from any FDM packet the firmware accepted is stale
STALE_GAP_S = 0.05
_MSP_ACC = ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2")


class MspImuSensor:
    """An :class:`MspImu` as the IMU under test (the contract's ``IMU_CHANNELS``); with
    ``attitude`` the FC's own attitude too (``IMU_ATTITUDE_CHANNELS``, Betaflight's
    MSP_ATTITUDE convention: :func:`drivers.codecs.msp.attitude_quat_enu`)."""

    def __init__(self, imu: Any, rate_hz: float | None = None, *, port: Any = None,
                 peer: Any = None, attitude: bool = False,
                 stale_gap_s: float = STALE_GAP_S) -> None:
        if attitude and (not imu.attitude or imu.variant != "BTFL"):
            raise DeviceError(f"{imu.url}: the attitude columns need a Betaflight FC polled "
                              f"for MSP_ATTITUDE (got {imu.variant})")
        self.imu = imu
        self.attitude = attitude
        self.channels = (*BENCH_IMU_CHANNELS, *(IMU_ATTITUDE_CHANNELS if attitude else ()))
        self.rate_hz = imu.rate_hz if rate_hz is None else rate_hz  # of the rig clock
        self.port, self.peer = port, peer  # closed with the sensor; the simulated FC
        self._last_t = -math.inf
        self.stale_gap_s = stale_gap_s
        self.stale_rows = 0  # dropped: the peer says the FC's sensors were not refreshed

    def describe(self) -> DeviceInfo:
        info = self.imu.describe()
        rate = self.rate_hz
        chans = tuple(ChannelInfo(c, "rad/s" if "gyro" in c else "m/s^2", rate)
                      for c in BENCH_IMU_CHANNELS)
        chans += tuple(ChannelInfo(c, "", rate) for c in self.channels[len(chans):])
        return DeviceInfo("imu", info.model, info.url, chans,
                          {"time_stamps": "when the FC read it, by its clock (MSP_RTC), or "
                                          "the host clock at the request (RAW_IMU has none)"})

    def link_errors(self) -> dict[str, int]:
        return self.imu.link_errors()

    def read_block(self) -> Block:
        """The rows since the previous call; a row not later than the one before (two
        replies within one clock tick) is dropped, so stamps strictly increase."""
        b = self.imu.read_block()
        src = (*_MSP_GYRO, *_MSP_ACC)
        t = np.asarray(b.t_s, float)
        keep = t > np.maximum.accumulate(np.concatenate(([self._last_t], t[:-1])))
        fresh = getattr(self.peer, "fresh", None)
        if fresh is not None and t.size:  # a launched firmware: its heartbeat
            ok = fresh(t, self.stale_gap_s)
            self.stale_rows += int(np.count_nonzero(keep & ~ok))
            keep &= ok
        if not keep.any():
            return Block.empty(self.channels)
        self._last_t = float(t[keep][-1])
        values = {c: np.asarray(b.values[s], float)[keep]
                  for c, s in zip(BENCH_IMU_CHANNELS, src, strict=True)}
        if self.attitude:
            rpy = np.column_stack([np.asarray(b.values[c], float)[keep]
                                   for c in ("roll_rad", "pitch_rad", "yaw_rad")])
            q = np.array([msp.attitude_quat_enu(msp.Attitude(*map(float, r))) for r in rpy])
            q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # one hemisphere: w >= 0
            values.update({c: q[:, i] for i, c in enumerate(IMU_ATTITUDE_CHANNELS)})
        return Block(t[keep], values)

    def close(self) -> None:
        try:
            self.imu.close()
        finally:
            if self.port is not None:
                self.port.close()
