"""The pipelined MSP poll on a link that loses and repeats replies, as the Betaflight SITL's
TCP port does (its main thread and TCP thread share the reply buffer without a lock):
no reply is taken for another request's, and lost ones do not stop the poll."""

from __future__ import annotations

import contextlib
import datetime
import socket
import struct
import threading
import time

import numpy as np

from drivers.backends.msp_fc import MspClient
from drivers.backends.msp_pipeline import LOST_AFTER_S, PipelinedMspImu
from drivers.backends.msp_tcp import open_port
from drivers.codecs import msp

ACC_1G = 1000  # the served time's milliseconds ride in acc x, one count each


class LossyFc:
    """An FC on a loopback TCP port that answers MSP_MULTIPLE_MSP with RAW_IMU (acc x:
    the millisecond of its clock it served at, modulo 30 s), ATTITUDE, RTC and the
    requests' API_VERSION tags; ``lose``, ``repeat`` and ``cut`` name the replies (by
    count) it drops, sends twice, or cuts to half and drops the rest of; it drops every
    reply in the ``mute`` window (seconds after its clock was set)."""

    def __init__(self, lose=(), repeat=(), cut=(), mute=(0.0, 0.0)) -> None:
        self.lose, self.repeat, self.cut = set(lose), set(repeat), set(cut)
        self.mute = mute
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.served = 0
        self.rtc: tuple[int, float] | None = None  # the ms it was set to, and when
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.server.accept()
        decoder = msp.MspDecoder()
        with conn, contextlib.suppress(OSError):  # the poll closed with replies unread
            while data := conn.recv(4096):
                for frame in decoder.feed(data):
                    conn.sendall(self._reply(frame))

    def _now_ms(self) -> int:
        assert self.rtc is not None
        set_ms, at = self.rtc
        return set_ms + int((time.monotonic() - at) * 1000)

    def _part(self, cmd: int, ms: int) -> bytes:
        """One part of a reply served at the FC's millisecond ``ms``: one reading of its
        clock per reply, as a real FC serves one request in one run of its task (read
        per part, a thread starved between the parts gave RAW_IMU and RTC milliseconds
        apart, and the test blamed the poll's stamps)."""
        if cmd == msp.MSP_RAW_IMU:
            return struct.pack("<9h", ms % 30000, 0, ACC_1G, 0, 0, 0, 0, 0, 0)
        if cmd == msp.MSP_ATTITUDE:
            return struct.pack("<3h", 0, 0, 0)
        if cmd == msp.MSP_RTC:
            at = datetime.datetime.fromtimestamp(ms // 1000, datetime.UTC)
            return struct.pack("<HBBBBBH", at.year, at.month, at.day, at.hour, at.minute,
                               at.second, ms % 1000)
        return bytes((0, 1, 47))  # API_VERSION

    def _reply(self, frame: msp.MspFrame) -> bytes:
        if frame.cmd == msp.MSP_FC_VARIANT:
            return msp.encode_v1(msp.REPLY, frame.cmd, b"BTFL")
        if frame.cmd == msp.MSP_API_VERSION:
            return msp.encode_v1(msp.REPLY, frame.cmd, self._part(frame.cmd, 0))
        if frame.cmd == msp.MSP_SET_RTC:
            seconds, millis = struct.unpack("<iH", frame.payload)
            self.rtc = (seconds * 1000 + millis, time.monotonic())
            return msp.encode_v1(msp.REPLY, frame.cmd)
        assert frame.cmd == msp.MSP_MULTIPLE_MSP
        self.served += 1
        ms = self._now_ms()
        parts = b"".join(bytes((len(p),)) + p
                         for p in (self._part(cmd, ms) for cmd in frame.payload))
        out = msp.encode_v1(msp.REPLY, frame.cmd, parts)
        assert self.rtc is not None
        since_set = time.monotonic() - self.rtc[1]
        if self.served in self.lose or self.mute[0] <= since_set < self.mute[1]:
            return b""
        if self.served in self.cut:
            return out[: len(out) // 2]
        return out * 2 if self.served in self.repeat else out

    def close(self) -> None:
        self.server.close()


class HostClock:
    """The rig's clock: the host's monotonic one, as the FC's RTC is here."""

    def now(self) -> float:
        return time.monotonic()


def poll(fc: LossyFc, seconds: float) -> tuple[PipelinedMspImu, np.ndarray, np.ndarray]:
    """Poll ``fc`` at 200 Hz for ``seconds``: the poll, its rows' times and the served
    milliseconds their acc x carries."""
    port = open_port("127.0.0.1", fc.port, "fc", connect_timeout_s=2.0)
    imu = PipelinedMspImu(MspClient(port, "fc", timeout_s=1.0), rate_hz=200.0,
                          acc_1g=ACC_1G, clock=HostClock(), multiple=True)
    time.sleep(seconds)
    block = imu.read_block()
    imu.close()
    port.close()
    acc_x = block.values["acc_x_m_s2"] / msp.STANDARD_GRAVITY * ACC_1G
    return imu, np.asarray(block.t_s), np.rint(acc_x)


def test_lost_repeated_and_cut_replies_neither_stop_the_poll_nor_go_to_other_requests():
    # three lost in a row: by order, three requests in flight with no reply to come, and
    # the poll stopped; a repeat and a cut shifted every later reply onto the next request
    fc = LossyFc(lose=(40, 41, 42), repeat=(80, 120), cut=(160,))
    try:
        imu, t, served = poll(fc, 1.6)
    finally:
        fc.close()
    errors = imu.link_errors()
    # it went on at its rate, but for the three lost: all in flight, given up after
    # LOST_AFTER_S (1.6 s at 200 a second is 320)
    assert fc.served > 320 - LOST_AFTER_S * 200 - 20, fc.served
    assert errors["no_reply"] == 4, errors  # three lost, one cut
    assert errors["stray_reply"] == 2, errors  # the repeats
    assert t.size > 230
    # each row is stamped when the FC served it: its own reply, never another's (the
    # offset is bounded by the fastest serve; an FC millisecond is whole)
    late = (t * 1000 - served) % 30000
    late = np.where(late > 15000, late - 30000, late)
    offset = np.median(late)
    assert np.all(np.abs(late - offset) < 3.0), (late - offset).min()


def test_a_request_with_no_reply_is_given_up_and_the_poll_goes_on():
    """A request never answered (nor any after it, for a while) is given up after
    ``LOST_AFTER_S``: the poll sends new ones, and stays alive."""
    fc = LossyFc(mute=(0.2, 0.6))  # 0.4 s of the FC's replies lost
    try:
        imu, t, _ = poll(fc, 1.5)
    finally:
        fc.close()
    assert imu.link_errors()["no_reply"] >= 0.4 / LOST_AFTER_S * 3
    assert np.count_nonzero(t > t[0] + 0.6 + LOST_AFTER_S) > 100  # it went on
