"""The one module that imports pyserial: open a port by URL, read with deadlines.

Drivers receive a ``serial.SerialBase`` (a real port, ``loop://``, ``spy://``, a pty
path) and use ``read_some`` / ``write_all`` so that timeouts and disconnects become
``DeviceError``s naming the port.
"""

from __future__ import annotations

import sys
import time

import serial

from drivers.errors import DeviceError


class _NoTermiosError(Exception):
    """Never raised: Windows has no termios."""


# pyserial's POSIX port lets termios.error (not an OSError) escape flush()
TermiosError: type[Exception] = _NoTermiosError
if sys.platform != "win32":
    from termios import error as _termios_error

    TermiosError = _termios_error


def list_ports() -> list[tuple[str, str, str]]:
    """(device, description, hwid) of every serial port pyserial sees, sorted by device."""
    from serial.tools import list_ports as pyserial_list_ports

    ports = sorted(pyserial_list_ports.comports(), key=lambda p: p.device)
    return [(p.device, p.description or "", p.hwid or "") for p in ports]


def open_port(url: str, baudrate: int, *, timeout_s: float = 0.01) -> serial.SerialBase:
    """``serial_for_url`` with errors turned into ``DeviceError`` (the port name in it)."""
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s,
                                     write_timeout=1.0)
    except (serial.SerialException, ValueError, OSError) as exc:
        raise DeviceError(f"serial {url}: cannot open ({exc})") from None


def read_some(port: serial.SerialBase, name: str) -> bytes:
    """Whatever arrived (waits at most the port's read timeout); '' when nothing did."""
    try:
        # pyserial defines in_waiting on each platform's Serial class, not on SerialBase;
        # every port opened here (serial_for_url) has it
        n = port.in_waiting  # pyright: ignore[reportAttributeAccessIssue]
        return port.read(n if n > 0 else 1)
    except (serial.SerialException, OSError, TermiosError, TypeError) as exc:
        raise DeviceError(f"{name}: serial read failed, device gone? ({exc})") from None


def write_all(port: serial.SerialBase, data: bytes, name: str) -> None:
    try:
        port.write(data)
        port.flush()
    except (serial.SerialException, OSError, TermiosError) as exc:
        raise DeviceError(f"{name}: serial write failed, device gone? ({exc})") from None


class Deadline:
    """A monotonic deadline for request/response loops."""

    def __init__(self, seconds: float) -> None:
        self.end = time.monotonic() + seconds

    @property
    def expired(self) -> bool:
        return time.monotonic() >= self.end
