"""A port that dies mid-write or mid-read becomes a DeviceError naming the device."""

from __future__ import annotations

import termios

import pytest

from drivers.backends.serial_link import read_some, write_all
from drivers.errors import DeviceError


class _DeadPty:
    """What pyserial's POSIX port does when the pty's other end has closed."""

    in_waiting = 0

    def write(self, data: bytes) -> int:
        return len(data)

    def flush(self) -> None:
        raise termios.error(5, "Input/output error")

    def read(self, n: int) -> bytes:
        raise termios.error(5, "Input/output error")


def test_termios_error_on_flush_is_a_device_error():
    with pytest.raises(DeviceError, match="fc: serial write failed"):
        write_all(_DeadPty(), b"$M<", "fc")


def test_termios_error_on_read_is_a_device_error():
    with pytest.raises(DeviceError, match="fc: serial read failed"):
        read_some(_DeadPty(), "fc")
