"""Transcript tests in PyMeasure's ``expected_protocol`` style, for every backend.

``ScriptedPort([(written, reply), ...])`` stands in for a serial port (pyserial's
``in_waiting``/``read``/``write``/``flush``) or a TCP socket (``sendall``/``recv``): each
pair says which exact bytes the backend must write next and what the device answers to
them; a pair with ``written == b""`` is a reply the device sends unasked (a stream). A write
that differs from the script fails at once with both byte strings; ``done()`` says whether
every pair was used. The backend under test runs unchanged on it: the test checks the bytes
of a sequence of calls and the parsed results of the canned replies.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence


class ScriptMismatch(AssertionError):
    """The backend wrote something the script does not expect."""


class ScriptedPort:
    def __init__(self, script: Sequence[tuple[bytes, bytes]], timeout_s: float = 0.01) -> None:
        self.script = [(bytes(w), bytes(r)) for w, r in script]
        self.timeout = timeout_s
        self.written = bytearray()  # every byte the backend wrote, for the record
        self._pending = bytearray()  # written bytes not yet matched to a pair
        self._out = bytearray()  # reply bytes the backend may read
        self._cond = threading.Condition()
        self.closed = False
        self.errors: list[str] = []
        # reads that found nothing: one after the stream's last byte means the reader has
        # decoded and stored all it read, and asks again (its decoder's byte count runs
        # ahead of the rows it stores)
        self.idle_reads = 0
        self._release_unasked()

    # -- the script ------------------------------------------------------------------------
    def _release_unasked(self) -> None:
        while self.script and not self.script[0][0]:
            self._out += self.script.pop(0)[1]

    def send(self, data: bytes) -> None:
        """The device sends ``data`` now, unasked (the next part of a stream)."""
        with self._cond:
            self._out += data
            self._cond.notify_all()

    def done(self) -> bool:
        with self._cond:
            return not self.script and not self._pending

    # -- the device side of a write --------------------------------------------------------
    def write(self, data: bytes) -> int:
        with self._cond:
            self.written += data
            self._pending += data
            while self.script and self._pending:
                want = self.script[0][0]
                n = min(len(want), len(self._pending))
                if bytes(self._pending[:n]) != want[:n]:
                    msg = (f"wrote {bytes(self._pending).hex(' ')}, the script expects "
                           f"{want.hex(' ')}")
                    self.errors.append(msg)
                    raise ScriptMismatch(msg)
                if n < len(want):
                    break  # the rest of the message is still to come
                del self._pending[:n]
                self._out += self.script.pop(0)[1]
                self._release_unasked()
            if self._pending and not self.script:
                msg = f"wrote {bytes(self._pending).hex(' ')} after the end of the script"
                self.errors.append(msg)
                raise ScriptMismatch(msg)
            self._cond.notify_all()
        return len(data)

    sendall = write

    def flush(self) -> None:
        pass

    # -- the host side of a read -----------------------------------------------------------
    @property
    def in_waiting(self) -> int:
        with self._cond:
            return len(self._out)

    def read(self, n: int = 1) -> bytes:
        deadline = time.monotonic() + (self.timeout or 0.0)
        with self._cond:
            while not self._out and not self.closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    self.idle_reads += 1
                    return b""
                self._cond.wait(left)
            out = bytes(self._out[:n])
            del self._out[:n]
            return out

    def recv(self, n: int) -> bytes:
        return self.read(n)

    def reset_input_buffer(self) -> None:
        with self._cond:
            self._out.clear()

    def settimeout(self, timeout_s: float | None) -> None:
        self.timeout = timeout_s

    def setsockopt(self, *args: object) -> None:
        pass

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()


def wait_for(predicate, timeout_s: float = 2.0) -> bool:
    """Poll ``predicate()`` until true or the timeout (the backends read on threads)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return bool(predicate())
