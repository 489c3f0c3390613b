"""Betaflight's interactive CLI over its MSP port: settings applied, checked, saved.

Why the interactive CLI and not MSP: PIDs, rates, filters, ``motor_idle`` and the
blackbox device are CLI settings, and ``blackbox_device`` is read only at boot, so the
settings must be saved and the firmware started again anyway. In 4.6.0 ``save`` writes
``eeprom.bin`` and **exits the process** (the SITL's reset is ``exit(0)``): the caller
relaunches it in the same working directory, where the new launch reads the saved
settings. The interactive CLI also leaves the CLI arming-disable flag set until that
restart, which the relaunch clears too.

Each line is sent alone and its answer read up to the next prompt; an answer holding
``###ERROR`` (unknown name, value out of range, bad argument count) or ``Invalid name``
stops before ``save``, so nothing half-applied is ever saved.

Before any launch, :func:`unknown_settings` refuses a ``set`` of a name the binary does not
have: every setting the firmware was built with is a NUL-terminated string in it (its CLI
prints the names from that table), so a name absent from the file is a typo or a setting of
another build (``dshot_bidir`` in the SITL), known in milliseconds rather than after a
launch. A name found may still be refused by the firmware (a string that is no setting, a
value out of range): the CLI stays the authority.
"""

from __future__ import annotations

import contextlib
import re
import socket
import time
from pathlib import Path

from drivers.backends.tcp_link import connect
from drivers.errors import DeviceError

__all__ = ["CLI_TIMEOUT_S", "ERROR_MARKS", "CliError", "apply_and_save", "unknown_settings"]

PROMPT = b"\r\n# "
CLI_TIMEOUT_S = 2.0  # one line's answer (the serial task runs at 100 Hz)
ENTER = b"#"
#: how the CLI answers a line it refused (cli.c:442-446 and its parsers)
ERROR_MARKS = ("###ERROR", "Invalid name", "Invalid value", "Parse error")


class CliError(DeviceError):
    """The firmware refused a CLI line: its text and the firmware's answer."""


_SET = re.compile(r"set\s+([A-Za-z0-9_]+)\s*=", re.IGNORECASE)


def unknown_settings(binary: Path, lines: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """The ``(where, name)`` of each ``set NAME = ...`` line whose name ``binary`` does not
    hold (module doc): refused before the firmware is launched."""
    names = [(where, m.group(1).lower()) for where, line in lines
             if (m := _SET.match(line.strip()))]
    if not names:
        return []
    data = binary.read_bytes()
    return [(where, name) for where, name in names if name.encode() + b"\0" not in data]


def _read_to_prompt(sock: socket.socket, name: str, timeout_s: float) -> str:
    deadline = time.monotonic() + timeout_s
    buf = b""
    while not buf.endswith(PROMPT):
        left = deadline - time.monotonic()
        if left <= 0:
            raise DeviceError(f"{name}: no CLI prompt within {timeout_s:g} s "
                              f"(got {buf[-80:]!r})")
        sock.settimeout(left)
        try:
            chunk = sock.recv(4096)
        except TimeoutError:
            continue
        if not chunk:
            raise DeviceError(f"{name}: the CLI connection closed (got {buf[-80:]!r})")
        buf += chunk
    return buf[: -len(PROMPT)].decode("ascii", "replace")


def apply_and_save(host: str, port: int, lines: list[tuple[str, str]], name: str, *,
                   connect_timeout_s: float = 2.0) -> None:
    """Enter the CLI, send each ``(where, line)`` and ``save``. ``where`` names the line
    in a refusal (``file:line``). The firmware exits after ``save``; a refused line raises
    ``CliError`` before anything is saved."""
    sock = connect(host, port, name, connect_timeout_s)
    try:
        sock.sendall(ENTER)
        _read_to_prompt(sock, name, CLI_TIMEOUT_S)
        for where, line in lines:
            sock.sendall(line.encode("ascii") + b"\n")
            answer = _read_to_prompt(sock, name, CLI_TIMEOUT_S)
            for mark in ERROR_MARKS:
                if mark in answer:
                    text = " ".join(answer.replace("#", " ").split()[-12:])
                    raise CliError(f"{where}: the firmware refused {line!r} ({text})")
        sock.sendall(b"save\n")
        with contextlib.suppress(OSError):  # the firmware exits: its answer may be cut
            sock.settimeout(CLI_TIMEOUT_S)
            while sock.recv(4096):
                pass
    finally:
        sock.close()
