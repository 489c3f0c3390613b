"""MSP over TCP: the port that carries nothing but whole MSP request frames.

A Betaflight UART idle between frames reads single bytes as commands: ``'R'`` reboots to
the bootloader (the SITL process exits), ``'#'`` opens the CLI, ``0x02`` the
non-interactive CLI. On a serial port a stray byte is noise the bench cannot rule out; on
this port it cannot happen: ``MspTcpPort.write`` sends a buffer only if it is, byte for
byte, a sequence of complete, checksummed MSP requests (v1, v2 or v2-over-v1), and
refuses anything else with a ``DeviceError`` before a byte leaves. Connecting and closing
send no payload bytes at all.
"""

from __future__ import annotations

from drivers.backends.tcp_link import TcpPort, connect
from drivers.codecs import msp
from drivers.errors import DeviceError

DEFAULT_PORT = 5761  # Betaflight SITL: UART1 (the MSP port) is TCP 5760 + 1


def whole_requests(data: bytes) -> bool:
    """True if ``data`` is exactly one or more complete, valid MSP request frames."""
    if not data:
        return False
    dec = msp.MspDecoder(max_payload=0xFFFF)
    found = dec.feed_located(data) + dec.flush_located()
    at = 0
    for loc in found:
        if loc.offset != at or loc.message.direction != msp.REQUEST:
            return False
        at += loc.length
    return at == len(data)


class MspTcpPort(TcpPort):
    """A ``TcpPort`` whose writes are whole MSP requests or nothing."""

    def write(self, data: bytes) -> int:
        data = bytes(data)
        if not whole_requests(data):
            shown = data[:16].hex(" ") + (" ..." if len(data) > 16 else "")
            raise DeviceError(f"{self.name}: refused to send {len(data)} bytes that are not "
                              f"whole MSP requests ({shown}): a stray byte can reboot or "
                              "stop the flight controller")
        return super().write(data)


def open_port(host: str, port: int, name: str, *, connect_timeout_s: float) -> MspTcpPort:
    """The flight controller's MSP port at ``host:port``, connected."""
    return MspTcpPort(connect(host, port, name, connect_timeout_s), name)
