"""Simulated-device world processes forked from one interpreter that has imported them.

Why: a world process started as a fresh interpreter imported numpy, scipy and the
simulated devices before it could serve, while the host waited: 0.3-1.1 s of CPU and as
much wall time on a loaded machine (the test suite starts 130 of them). A zygote, as
multiprocessing's ``forkserver`` is, imports them once per host process and forks a
child per world, which answers in 0.05-0.08 s (``benchmarks/world_start.py``). The
zygote is a fresh interpreter (``python -m`` this module), single-threaded, so a fork
copies no other thread's locks; multiprocessing's own forkserver would import the host's
``__main__`` into every child.

Each child leads a session of its own (``drivers.device_priority``) and watches the host
that asked for it through a pidfd, so it ends with that host whoever its parent is. The
zygote ends with its host too. It reaps its children as they end (their CPU time counts
as its children's); the host knows a child by a pidfd, which tells it when the child has
ended (its exit code is not kept).
"""

from __future__ import annotations

import atexit
import gc
import importlib
import os
import pickle
import select
import signal
import socket
import subprocess
import sys
import threading
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

from drivers.errors import DeviceError

__all__ = ["PRELOAD", "ForkedProcess", "fork_world"]

#: what the worlds' builds import (numpy, scipy's rotations and splines, the devices):
#: imported once in the zygote. A world needing more imports it in its child.
PRELOAD = ("numpy", "scipy.spatial.transform", "scipy.interpolate", "scipy.signal",
           "serial", "can", "drivers.sim_worlds", "drivers.sim.imu_rig",
           "drivers.wire_sim.world_process", "drivers.wire_sim.imu_world",
           "drivers.wire_sim.plant_peers", "drivers.wire_sim.msp_fc",
           "drivers.wire_sim.pi_hexapod", "drivers.wire_sim.gx3",
           "drivers.wire_sim.loadcell_board", "drivers.wire_sim.vesc",
           "drivers.wire_sim.vesc_uart", "drivers.wire_sim.dronecan_esc",
           "drivers.wire_sim.can_node", "drivers.wire_sim.can_socket",
           "drivers.wire_sim.sitl_plant", "drivers.wire_sim.sitl_imu_world")
_START_TIMEOUT_S = 30.0  # the zygote imports numpy and scipy: seconds when loaded
_REPLY_TIMEOUT_S = 10.0
_PID = 8  # bytes of a pid on the zygote's socket
#: what a forked child runs: ``main(its connection to the host, the host's pidfd)``
ChildMain = Callable[[Connection, int], None]


class ForkedProcess:
    """The host's handle on a world's process, as ``subprocess.Popen`` is on a child's:
    ``pid``, ``poll()`` (None while it runs), ``wait(timeout)`` and ``kill()``. Its pidfd
    is open while the process runs: that is the whole state."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        try:
            self._pidfd: int | None = os.pidfd_open(pid)
        except ProcessLookupError:  # it ended already
            self._pidfd = None

    def poll(self) -> int | None:
        """None while the process runs; -1 once it has ended (its code is not kept)."""
        return self._waited(0.0)

    def wait(self, timeout: float | None = None) -> int:
        code = self._waited(timeout)
        if code is None:
            raise subprocess.TimeoutExpired(f"world process {self.pid}", timeout or 0.0)
        return code

    def kill(self) -> None:
        if self.poll() is None and self._pidfd is not None:
            try:
                signal.pidfd_send_signal(self._pidfd, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def _waited(self, timeout: float | None) -> int | None:
        """-1 if the process has ended within ``timeout`` (its pidfd then closed), else None."""
        if self._pidfd is not None and select.select([self._pidfd], [], [], timeout)[0]:
            os.close(self._pidfd)
            self._pidfd = None
        return None if self._pidfd is not None else -1

    def __del__(self) -> None:
        pidfd = getattr(self, "_pidfd", None)
        if pidfd is not None:
            os.close(pidfd)


class _Zygote:
    """This host's zygote process and the socket it takes fork requests on."""

    def __init__(self) -> None:
        ours, theirs = socket.socketpair()
        root = str(Path(__file__).resolve().parents[2])  # where ``drivers`` is importable
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            p for p in (root, os.environ.get("PYTHONPATH", "")) if p),
            # one BLAS thread: the zygote forks, and its worlds' arrays are small
            "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
        self.process = subprocess.Popen(
            [sys.executable, "-m", __name__, str(theirs.fileno()), str(os.getpid())],
            pass_fds=(theirs.fileno(),), env=env, stdin=subprocess.DEVNULL,
            start_new_session=True)
        theirs.close()
        self.socket = ours
        self.owner = os.getpid()
        self.netns = _netns()  # the zygote's, and its worlds': the starting thread's
        ours.settimeout(_START_TIMEOUT_S)
        try:
            ready = ours.recv(5) == b"ready"
        except OSError as exc:
            self.close()
            raise DeviceError(f"the simulated devices' zygote did not start in "
                              f"{_START_TIMEOUT_S:g} s ({exc})") from None
        if not ready:
            self.close()
            raise DeviceError("the simulated devices' zygote ended before it was ready "
                              "(its error is on stderr)")
        ours.settimeout(_REPLY_TIMEOUT_S)

    def fork(self, fd: int, main: ChildMain) -> int:
        """A child that runs ``main`` on socket ``fd``; its pid."""
        socket.send_fds(self.socket, [pickle.dumps((os.getcwd(), main))], [fd])
        pid = self.socket.recv(_PID, socket.MSG_WAITALL)
        if len(pid) < _PID:
            raise OSError("the zygote ended")
        return int.from_bytes(pid, "little")

    def close(self) -> None:
        self.socket.close()
        try:
            self.process.wait(5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


_lock = threading.Lock()
_zygote: _Zygote | None = None


@atexit.register
def _close_zygote() -> None:
    """The zygote ends with its host anyway; closed here, it is waited for."""
    global _zygote
    with _lock:
        if _zygote is not None and _zygote.owner == os.getpid():
            _zygote.close()
        _zygote = None


def fork_world(fd: int, main: ChildMain) -> ForkedProcess:
    """Fork a world process that runs ``main(connection on fd, host's pidfd)``
    (``drivers.wire_sim.world_process.serve``; pickled by name) from this host's zygote
    (:func:`_zygote_here`); a zygote that fails the fork is replaced once."""
    global _zygote
    with _lock:
        for attempt in (1, 2):
            zygote = _zygote_here()
            try:
                return ForkedProcess(zygote.fork(fd, main))
            except OSError as exc:
                zygote.close()
                _zygote = None
                if attempt == 2:
                    raise DeviceError(f"the simulated devices' zygote failed to fork a "
                                      f"world ({exc})") from None
    raise AssertionError("unreachable")


def _zygote_here() -> _Zygote:
    """The kept zygote, started on first use, and again in a forked host, when it ended,
    or when the calling thread is in another network namespace than the zygote (a test
    beside a firmware in a namespace of its own), so the world's loopback is always the
    caller's. Called under ``_lock``."""
    global _zygote
    if _zygote is not None and _zygote.owner != os.getpid():
        _zygote.socket.close()  # a forked host's copy: the zygote is its parent's
        _zygote = None
    elif _zygote is not None and (_zygote.process.poll() is not None
                                  or _zygote.netns != _netns()):
        _zygote.close()
        _zygote = None
    if _zygote is None:
        _zygote = _Zygote()
    return _zygote


def _netns() -> int:
    """The calling thread's network namespace, by inode; 0 where /proc cannot tell."""
    try:
        return os.stat("/proc/thread-self/ns/net").st_ino
    except OSError:
        return 0


# -- the zygote ----------------------------------------------------------------------------
def _reap(*_: object) -> None:
    """Wait for every child that has ended (``SIGCHLD``): no zombies."""
    while True:
        try:
            pid, _status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:  # no children left
            return
        if pid == 0:  # the rest still run
            return


def _zygote_main(ctrl_fd: int, host_pid: int) -> None:
    """Import ``PRELOAD``, then fork a world process per request until the host is gone."""
    ctrl = socket.socket(fileno=ctrl_fd)
    host = os.pidfd_open(host_pid)
    for name in PRELOAD:
        importlib.import_module(name)
    gc.freeze()  # what every child shares stays out of their collectors' passes
    signal.signal(signal.SIGCHLD, _reap)
    ctrl.sendall(b"ready")
    while True:
        if host in select.select([ctrl, host], [], [])[0]:
            return  # the host is gone: so are its requests
        request, fds, _, _ = socket.recv_fds(ctrl, 4096, 1)
        if not request or not fds:
            return  # the host closed its end
        pid = os.fork()
        if pid == 0:  # the world's process
            code = 1
            try:
                ctrl.close()
                signal.signal(signal.SIGCHLD, signal.SIG_DFL)
                os.setsid()  # a session, so a scheduling group, of its own
                cwd, main = pickle.loads(request)
                os.chdir(cwd)
                main(Connection(fds[0]), host)
                code = 0
            except BaseException:
                traceback.print_exc()
            finally:
                os._exit(code)
        os.close(fds[0])
        ctrl.sendall(pid.to_bytes(_PID, "little"))


if __name__ == "__main__":
    _zygote_main(int(sys.argv[1]), int(sys.argv[2]))
