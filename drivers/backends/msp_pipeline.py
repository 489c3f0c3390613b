"""Betaflight SITL's RAW_IMU and ATTITUDE polled with the next request out before the
last reply came back: one row per period, each stamped within a millisecond or so.

Why, from the 4.6.0 source: the firmware serves one MSP command per run of its serial
task (msp_serial.c:486-510), and the SITL's TCP thread hands a reply to the socket only
when it next wakes, on new input or after its 10 ms select timeout (sitl.c:298,
dyad.c:683-735: a stream is selected for writing only if it had output pending when the
loop began). Request and reply in turn take 10 ms each, and the round trip bounds no
better when the firmware read its sensors. Here a request goes out every ``1 / rate_hz``
whether or not its predecessor was answered: its arrival wakes the TCP thread, which
sends the reply ready by then, so each reply comes back a period after its request, and
the firmware read its sensors within one run of its serial task (1 ms at
``serial_update_rate_hz = 1000``) of the request's arrival. So the send time is the
row's stamp, and a reply later than ``max_round_trip_s`` (a stalled host or firmware)
drops its row. The port must be a socket's (``MspTcpPort``).

Better still, the firmware says when it served: the poll sets the FC's clock
(``MSP_SET_RTC``) and asks ``MSP_RTC`` in the same ``MSP_MULTIPLE_MSP``, which reads it
within microseconds of RAW_IMU. A row is then stamped with that time on the rig's clock
(its send stamp plus the delay from send to serve), and kept however late its reply
came. Why: the send time is only as good as the bench's own schedule; with the bench's
process scheduled every 15 ms on a loaded host, each request went out late, the reply
before it waited for it in the TCP thread, every round trip outlasted 12 ms and every row
was dropped (the run stopped on "no samples"). The FC's clock and the host's monotonic
clock run at one rate (the SITL's is that clock, at rate 1 with the feeder's 25 ms
stamps); their offset is the largest ``send - served`` of the last rows (a request is
served after it was sent; the fastest one was served at once). An FC that refuses the
clock keeps the send-time stamps.

Replies carry no sequence number, and the link loses and repeats them: the SITL's main
thread appends reply bytes to its TCP stream's buffer while its TCP thread sends from and
empties that buffer, without a lock (serial_tcp.c ``tcpWrite``, dyad.c ``dyad_write`` and
``stream_flushWriteBuffer``), so a reply's bytes are now and then dropped or sent twice
(beside four CPU hogs, one reply cut short and three answered twice in 11917; none in 5962
on an idle machine). Matched by order, each such event shifted every later reply onto the
wrong request for good, and three lost ones left three requests in flight that no reply
would ever come to: the poll stopped, and the run with it ("no reply within 3000 ms"). So
each request is tagged: ``k`` (0 to ``TAGS - 1``, in turn) extra MSP_API_VERSIONs at its
end, answered by as many extra parts in its reply. A reply is its request's, the oldest in
flight with its tag; the requests before that one lost theirs (counted, ``no_reply``); a
reply whose tag none in flight has is a repeat or came after its request was given up
(counted, ``stray_reply``), and is dropped. A request unanswered for ``LOST_AFTER_S`` is
given up, so lost replies never stall the poll; its late reply would need ``TAGS`` requests
sent after it to be taken for another's.
"""

from __future__ import annotations

import collections
import select
import time
from typing import Any, NamedTuple

from drivers.backends.msp_fc import RAW_AND_ATTITUDE, MspImu, MspRefused
from drivers.backends.serial_link import read_some, write_all
from drivers.codecs import msp
from drivers.errors import DeviceError

__all__ = ["LOST_AFTER_S", "MAX_IN_FLIGHT", "TAGS", "PipelinedMspImu"]

RAW_ATTITUDE_RTC = (*RAW_AND_ATTITUDE, msp.MSP_RTC)

#: one answered by the next one's arrival, and one to spare: with two, a reply the serial
#: task had not written when the next request arrived left both in flight, no request went
#: out to wake the TCP thread, and the replies waited for its timeout; the poll then stayed
#: locked at about 67 replies/s, each 12-15 ms late (measured; three: 200/s, none late)
MAX_IN_FLIGHT = 3
TAGS = 8  # a request's tag: how many TAG_FILLERs end it (module doc)
TAG_FILLER = msp.MSP_API_VERSION  # a read with a 3-byte reply and no side effect
#: a request unanswered this long is given up (its reply lost, or the FC stalled): well
#: within the half second of silence that ends a run, well past a loaded host's round trip
LOST_AFTER_S = 0.25


class _Sent(NamedTuple):
    """A request in flight: its tag, the rig clock's time and pauses, the host's time."""

    tag: int
    stamp: float
    paused: float
    wall: float


class PipelinedMspImu(MspImu):
    """:class:`MspImu` (``attitude``, ``multiple``) polled as the module doc says."""

    def __init__(self, client: Any, **kwargs: Any) -> None:
        self.stray_replies = 0  # before the poll thread starts (MspImu.__init__ starts it)
        super().__init__(client, **kwargs)

    def _poll(self) -> None:
        client, period = self.client, 1.0 / self.rate_hz
        try:
            cmds = RAW_ATTITUDE_RTC if self._set_rtc() else RAW_AND_ATTITUDE
        except DeviceError as exc:
            with self._lock:
                self._error = exc
            return
        frames = [msp.encode_message(msp.multiple_request((*cmds, *(TAG_FILLER,) * tag)),
                                     client.version) for tag in range(TAGS)]
        sock = client.port.sock
        sent: collections.deque[_Sent] = collections.deque()
        due = heard = time.monotonic()
        count = 0
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now >= due:
                    due = max(due + period, now)
                    if now - heard > client.timeout_s:
                        raise DeviceError(f"{self.url}: no reply to MSP_MULTIPLE_MSP within "
                                          f"{client.timeout_s * 1e3:.0f} ms")
                    while sent and now - sent[0].wall > LOST_AFTER_S:
                        sent.popleft()
                        self.missed_replies += 1
                    if len(sent) < MAX_IN_FLIGHT:
                        tag, count = count % TAGS, count + 1
                        stamp, paused = self.clock.now(), getattr(self.clock, "paused_s", 0.0)
                        with client.lock:
                            write_all(client.port, frames[tag], client.name)
                        sent.append(_Sent(tag, stamp, paused, now))
                if select.select([sock], [], [], max(0.0, due - time.monotonic()))[0]:
                    for reply in client.decoder.feed(read_some(client.port, client.name)):
                        if self._take(reply, sent, cmds):
                            heard = time.monotonic()
        except DeviceError as exc:
            with self._lock:
                self._error = exc

    def _take(self, reply: msp.MspMessage, sent: collections.deque[_Sent],
              cmds: tuple[int, ...]) -> bool:
        """The reply to the request in flight with its tag (module doc); whether it was
        one."""
        if isinstance(reply, msp.ErrorReply) and reply.cmd == msp.MSP_MULTIPLE_MSP:
            raise MspRefused(f"{self.url}: FC refused MSP_MULTIPLE_MSP")
        if not (isinstance(reply, msp.Unknown) and reply.cmd == msp.MSP_MULTIPLE_MSP):
            return False
        try:
            parts = msp.multiple_parts(reply)
        except msp.PayloadError:
            parts = []  # a tag below 0: no request's
        tag = len(parts) - len(cmds)
        older = next((i for i, req in enumerate(sent) if req.tag == tag), None)
        if older is None:
            self.stray_replies += 1
            return False
        for _ in range(older):
            sent.popleft()
            self.missed_replies += 1
        req = sent.popleft()
        try:  # the tag's fillers are counted, not read
            raw, att, *clock = msp.parse_multiple(cmds, parts)
        except msp.PayloadError as exc:
            raise DeviceError(f"{self.url}: {exc}") from None
        served_ms = msp.rtc_ms(clock[0]) if clock else None
        if served_ms is None:
            self._add_row(req.stamp, req.paused, raw, att)
        else:
            self._add_row(req.stamp + self._serve_delay(served_ms, req.wall), req.paused,
                          raw, att, timed=True)
        return True

    def link_errors(self) -> dict[str, int]:
        """:meth:`MspImu.link_errors`, and the replies dropped as repeats or too late."""
        errors = super().link_errors()
        return {**errors, "stray_reply": self.stray_replies} if self.stray_replies else errors
