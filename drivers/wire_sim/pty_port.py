"""A pseudo-terminal pair for simulated serial devices (protocols.md §9.3).

The driver opens ``path`` with pyserial like a real port; the simulator reads and writes
the master side. The slave is put in raw mode at once (otherwise the line discipline
echoes and eats control bytes), and simulators speak only in answer to a request or
after ``wait_for_open`` — bytes written before the driver opens the port are lost.
"""

from __future__ import annotations

import os
import pty
import select
import threading
import tty
from collections.abc import Callable


class PtyDevice:
    """Runs ``handler(data) -> reply bytes`` for every chunk the driver writes; a
    ``tick()`` callback (optional) may add unsolicited bytes (continuous streams)."""

    def __init__(self, handler: Callable[[bytes], bytes],
                 tick: Callable[[], bytes] | None = None, tick_s: float = 0.01) -> None:
        self.master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.handler = handler
        self.tick = tick
        self.tick_s = tick_s
        self._stop = threading.Event()
        self._silent = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"pty-{self.path}", daemon=True)

    def start(self) -> PtyDevice:
        self._thread.start()
        return self

    def disconnect(self) -> None:
        """Fault: the device stops answering (bytes are read and dropped)."""
        self._silent.set()

    def reconnect(self) -> None:
        self._silent.clear()

    def write(self, data: bytes) -> None:
        if data and not self._silent.is_set():
            os.write(self.master, data)

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], self.tick_s)
            if ready:
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    return
                reply = self.handler(data)
                self.write(reply)
            if self.tick is not None:
                self.write(self.tick())

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
        # once only: a second stop must not close fd numbers the process has reused since
        fds, self.master, self._slave = (self.master, self._slave), -1, -1
        for fd in fds:
            if fd < 0:
                continue
            try:
                os.close(fd)
            except OSError:
                pass
