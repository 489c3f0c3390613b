"""A TCP connection as a byte port: a flight controller behind ser2net, a WiFi-MSP bridge
or Betaflight's SITL (its UARTs are TCP ports 5760 + n).

``TcpPort`` has the small part of pyserial's port interface the request/response clients
use (``read``, ``in_waiting``, ``write``, ``flush``, ``close``, ``timeout``), so the serial
backends' clients (``drivers.backends.msp_fc.MspClient``) run over it unchanged. A socket
error or a peer that closed the connection is a ``DeviceError`` naming the URL.
"""

from __future__ import annotations

import contextlib
import select
import socket
import struct
import sys

from drivers.errors import DeviceError

READ_TIMEOUT_S = 0.01  # like the serial ports' read timeout: a short wait, then the caller's loop


def connect(host: str, port: int, name: str, timeout_s: float) -> socket.socket:
    """A connected TCP socket (Nagle off: small requests go out at once)."""
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise DeviceError(f"{name}: cannot connect to {host}:{port} ({reason})") from None
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


class TcpPort:
    """A connected socket read with a short timeout, like a serial port."""

    def __init__(self, sock: socket.socket, name: str, *,
                 timeout_s: float = READ_TIMEOUT_S) -> None:
        self.sock = sock
        self.name = name
        self.timeout = timeout_s
        sock.settimeout(timeout_s)
        self.is_open = True

    def _gone(self, why: str) -> DeviceError:
        return DeviceError(f"{self.name}: connection {why}, device gone?")

    @property
    def in_waiting(self) -> int:
        """Bytes ready to read without waiting (0 where the OS cannot say)."""
        if sys.platform == "win32" or not self.is_open:
            return 0
        import fcntl
        import termios

        try:
            ready = select.select([self.sock], [], [], 0)[0]
            if not ready:
                return 0
            raw = fcntl.ioctl(self.sock.fileno(), termios.FIONREAD, b"\0\0\0\0")
            return max(1, struct.unpack("i", raw)[0])  # readable with 0 bytes: closed
        except OSError:
            return 1  # let read() report it

    def read(self, n: int = 1) -> bytes:
        """Up to ``n`` bytes; ``b""`` when nothing arrived within the timeout."""
        if not self.is_open:
            raise self._gone("already closed")
        try:
            data = self.sock.recv(max(1, n))
        except TimeoutError:
            return b""
        except OSError as exc:
            raise self._gone(f"failed ({exc.strerror or exc})") from None
        if not data:
            raise self._gone("closed by the peer")
        return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise self._gone("already closed")
        try:
            self.sock.sendall(data)
        except OSError as exc:
            raise self._gone(f"failed ({exc.strerror or exc})") from None
        return len(data)

    def flush(self) -> None:
        """Nothing to drain: ``sendall`` has handed every byte to the kernel."""

    def close(self) -> None:
        if self.is_open:
            self.is_open = False
            with contextlib.suppress(OSError):
                self.sock.close()
