"""What the host can see: serial ports (pyserial) and CAN interfaces (python-can).

For ``rotorbench devices``. The vendor libraries stay in their one backend module each
(``backends.serial_link``, ``backends.can_link``), imported here lazily; a missing library
or an interface whose probe fails is reported, never raised. python-can's
``detect_available_configs`` asks each interface in turn (some load vendor DLLs), so it
runs on a thread with a deadline and only over the interfaces named.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

__all__ = ["CAN_INTERFACES", "CanConfig", "SerialPort", "can_configs", "serial_ports"]

# python-can interfaces that can enumerate their channels (python-can 4.x docs);
# "virtual" and "udp_multicast" are left out: they are always "available" and name no device.
CAN_INTERFACES = ("socketcan", "pcan", "kvaser", "vector", "ixxat", "gs_usb", "cantact",
                  "nixnet", "etas")


@dataclass(frozen=True)
class SerialPort:
    device: str
    description: str
    hwid: str

    @property
    def url(self) -> str:
        return f"serial://{self.device}"  # /dev/ttyUSB0 -> serial:///dev/ttyUSB0


@dataclass(frozen=True)
class CanConfig:
    interface: str
    channel: str

    @property
    def url(self) -> str:
        return f"can://{self.interface}/{self.channel}"


def serial_ports() -> tuple[list[SerialPort], str]:
    """Serial ports and a note ('' or why none could be listed)."""
    try:
        from drivers.backends import serial_link
    except ImportError as exc:
        return [], f"pyserial not installed ({exc})"
    try:
        ports = serial_link.list_ports()
    except Exception as exc:  # a platform backend failing must not end the listing
        return [], f"listing serial ports failed: {exc}"
    return [SerialPort(*port) for port in ports], ""


def can_configs(interfaces: tuple[str, ...] = CAN_INTERFACES,
                timeout_s: float = 5.0) -> tuple[list[CanConfig], str]:
    """CAN interfaces/channels python-can detects, and a note ('' or what went wrong)."""
    try:
        from drivers.backends import can_link
    except ImportError as exc:
        return [], f"python-can not installed ({exc})"
    found: list[CanConfig] = []
    notes: list[str] = []

    def detect() -> None:
        # interfaces without their vendor library log a warning each; the note says enough
        logger = logging.getLogger("can")
        level = logger.level
        logger.setLevel(logging.CRITICAL)
        try:
            _detect()
        finally:
            logger.setLevel(level)

    def _detect() -> None:
        for name in interfaces:
            try:
                configs = can_link.detect_configs(name)
            except Exception as exc:  # one broken interface must not hide the others
                notes.append(f"{name}: {exc}")
                continue
            found.extend(CanConfig(interface, channel) for interface, channel in configs)

    worker = threading.Thread(target=detect, name="can-detect", daemon=True)
    worker.start()
    worker.join(timeout_s)
    if worker.is_alive():
        notes.append(f"CAN detection still running after {timeout_s:g} s; list incomplete")
    return list(found), "; ".join(notes)
