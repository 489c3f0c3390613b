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
"""

from __future__ import annotations

import collections
import select
import time

from drivers.backends.msp_fc import RAW_AND_ATTITUDE, MspImu
from drivers.backends.serial_link import read_some, write_all
from drivers.codecs import msp
from drivers.errors import DeviceError

__all__ = ["MAX_IN_FLIGHT", "PipelinedMspImu"]

#: one answered by the next one's arrival, and one to spare: with two, a reply the serial
#: task had not written when the next request arrived left both in flight, no request went
#: out to wake the TCP thread, and the replies waited for its timeout; the poll then stayed
#: locked at about 67 replies/s, each 12-15 ms late (measured; three: 200/s, none late)
MAX_IN_FLIGHT = 3


class PipelinedMspImu(MspImu):
    """:class:`MspImu` (``attitude``, ``multiple``) polled as the module doc says."""

    def _poll(self) -> None:
        client, period = self.client, 1.0 / self.rate_hz
        frame = msp.encode_message(msp.multiple_request(RAW_AND_ATTITUDE), client.version)
        sock = client.port.sock
        sent: collections.deque[tuple[float, float, float]] = collections.deque()
        due = time.monotonic()
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now >= due:
                    due = max(due + period, now)
                    if sent and now - sent[0][2] > client.timeout_s:
                        raise DeviceError(f"{self.url}: no reply to MSP_MULTIPLE_MSP within "
                                          f"{client.timeout_s * 1e3:.0f} ms")
                    if len(sent) < MAX_IN_FLIGHT:
                        stamp, paused = self.clock.now(), getattr(self.clock, "paused_s", 0.0)
                        with client.lock:
                            write_all(client.port, frame, client.name)
                        sent.append((stamp, paused, now))
                if select.select([sock], [], [], max(0.0, due - time.monotonic()))[0]:
                    for reply in client.decoder.feed(read_some(client.port, client.name)):
                        self._take(reply, sent)
        except DeviceError as exc:
            with self._lock:
                self._error = exc

    def _take(self, reply: msp.MspMessage, sent: collections.deque) -> None:
        """The reply to the oldest request in flight (the firmware answers in order)."""
        if isinstance(reply, msp.ErrorReply) and reply.cmd == msp.MSP_MULTIPLE_MSP:
            raise DeviceError(f"{self.url}: FC refused MSP_MULTIPLE_MSP")
        if not (isinstance(reply, msp.Unknown) and reply.cmd == msp.MSP_MULTIPLE_MSP
                and sent):
            return
        stamp, paused, _ = sent.popleft()
        self._add_row(stamp, paused, *self._split(reply))
