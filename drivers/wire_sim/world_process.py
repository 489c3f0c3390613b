"""A simulated device world in a child process of its own, as a real device's firmware is.

Why: as threads of the host's process the simulated devices share its interpreter lock,
so a loaded machine (or a busy host) starves them and they answer late; in a process of
their own they are scheduled like the firmware they stand for.

:class:`WorldProcess` has the child forked by this host's zygote
(:mod:`drivers.wire_sim.world_forks`: an interpreter that has imported numpy, scipy and
the devices once, with no copy of the host's threads or locks). The child calls
``build(*args)`` (an importable function, so it pickles by name) for the world object and
then serves requests over a socket pair until told to stop or until its host ends (end
of file, or the host's pidfd). A request names an object of the world (``None``: the
world itself; else a key of its ``peers``) and an attribute path on it, to call or to
read (a ``DeviceError`` raised there is raised here with its message). :class:`Remote` is
the host's handle on such an object. The devices' transports (pty paths, loopback ports)
work across processes as they do across a cable; the world reports what to open in the
replies.
"""

from __future__ import annotations

import gc
import os
import select
import socket
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from drivers.device_priority import raise_device_priority
from drivers.errors import DeviceError
from drivers.wire_sim.world_forks import fork_world

__all__ = ["Constant", "DeviceWorld", "FastSwitching", "Remote", "RemoteDevice",
           "WorldProcess", "one_device", "serve"]

_START_TIMEOUT_S = 30.0  # a world's build: seconds on a loaded machine
_STOP_TIMEOUT_S = 5.0
# Each device is a thread that wakes for a request or a frame, answers in well under a
# millisecond and sleeps again. A thread woken from a short system call while another
# thread runs Python waits up to the interpreter's switch interval (5 ms by default) for
# it, each time: at 600 MSP polls a second (1.7 ms apart) that halved the polls served.
SWITCH_INTERVAL_S = 0.0002


class WorldProcess:
    """The host's side of a world served by a child process (see module doc)."""

    def __init__(self, build: Callable[..., Any], *args: Any, name: str = "sim-world") -> None:
        ours, theirs = socket.socketpair()
        self._lock = threading.Lock()
        self.name = name
        try:
            self.process = fork_world(theirs.fileno(), serve)
        except BaseException:
            ours.close()
            raise
        finally:
            theirs.close()
        self._conn = Connection(ours.detach())
        self._conn.send((build, args))
        if not self._conn.poll(_START_TIMEOUT_S):
            self.close()
            raise DeviceError(f"{name}: the simulated devices' process did not start in "
                              f"{_START_TIMEOUT_S:g} s")
        try:
            self._reply()
        except BaseException:
            self.close()
            raise

    def request(self, op: str, key: str | None, attrs: tuple[str, ...], args: tuple = ()) -> Any:
        """``op`` "call", "get" or "set" on ``attrs`` of the world's object ``key``."""
        with self._lock:
            try:
                self._conn.send((op, key, attrs, args))
                return self._reply()
            except (EOFError, OSError, BrokenPipeError):
                raise DeviceError(f"{self.name}: the simulated devices' process is "
                                  f"gone") from None

    def _reply(self) -> Any:
        status, value = self._conn.recv()
        if status == "device":
            raise DeviceError(value)
        if status == "err":
            raise DeviceError(f"{self.name}: {value}")
        return value

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def remote(self, key: str | None) -> Remote:
        return Remote(self, key)

    def close(self) -> None:
        """Stop the world (its devices first), then the process; safe to call twice."""
        if self.alive:
            try:
                with self._lock:
                    self._conn.send(("stop", None, (), ()))
            except OSError:
                pass
            try:
                self.process.wait(_STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(_STOP_TIMEOUT_S)
        self._conn.close()


class FastSwitching:
    """The host's interpreter switches threads every ``SWITCH_INTERVAL_S`` while entered
    (nested: the first entry sets it, the last exit restores it): a host polling a
    time-scaled world hundreds of times a second on one thread while another reads a
    stream has the same waits as the world's devices (see ``SWITCH_INTERVAL_S``)."""

    _lock = threading.Lock()
    _depth = 0
    _saved = 0.0

    def __enter__(self) -> FastSwitching:
        with FastSwitching._lock:
            if FastSwitching._depth == 0:
                FastSwitching._saved = sys.getswitchinterval()
                sys.setswitchinterval(min(FastSwitching._saved, SWITCH_INTERVAL_S))
            FastSwitching._depth += 1
        return self

    def __exit__(self, *exc: object) -> None:
        with FastSwitching._lock:
            FastSwitching._depth -= 1
            if FastSwitching._depth == 0:
                sys.setswitchinterval(FastSwitching._saved)


class Remote:
    """An object of a child's world: ``r.port.disconnect()`` calls it there; ``r.get("x")``
    reads an attribute. Values cross the pipe pickled."""

    def __init__(self, world: WorldProcess, key: str | None,
                 attrs: tuple[str, ...] = ()) -> None:
        self._world, self._key, self._attrs = world, key, attrs

    def __getattr__(self, name: str) -> Remote:
        if name.startswith("__"):
            raise AttributeError(name)
        return Remote(self._world, self._key, (*self._attrs, name))

    def __call__(self, *args: Any) -> Any:
        return self._world.request("call", self._key, self._attrs, args)

    def get(self, name: str) -> Any:
        return self._world.request("get", self._key, (*self._attrs, name))

    def set(self, name: str, value: Any) -> None:
        """Set an attribute there (a fault switch, a controller's state)."""
        self._world.request("set", self._key, (*self._attrs, name), (value,))


class RemoteDevice:
    """A device of a child's world as the host holds it: where to open it (``path``, a pty,
    or ``address``, a loopback host and port), its ``port`` (a :class:`Remote`: tests break
    the wire with it) and ``stop()``. Nothing else answers, so ``getattr(device, name,
    None)`` tells the truth (a bare :class:`Remote` answers every name)."""

    def __init__(self, world: WorldProcess, key: str, where: str | tuple[str, int]) -> None:
        self.remote = Remote(world, key)
        self.port = Remote(world, key, ("port",))
        self.path = where if isinstance(where, str) else None
        self.address = tuple(where) if not isinstance(where, str) else None

    def stop(self) -> None:
        self.remote.stop()


class DeviceWorld:
    """A world of one device (key ``device``): a device stand-in of its own in a process,
    as a unit test of its backend wants one, stopped with the world."""

    def __init__(self, device: Any) -> None:
        self.device = device
        self.peers = {"device": device}

    def close(self) -> None:
        self.device.stop()


@dataclass(frozen=True)
class Constant:
    """A stand-in model that reads the same whatever it is asked (``Constant(v)(t) == v``):
    a value, so it crosses to a device's process pickled, where a lambda cannot."""

    value: Any

    def __call__(self, *_args: Any) -> Any:
        return self.value


def one_device(make: Callable[..., Any], kwargs: dict[str, Any]) -> DeviceWorld:
    """``WorldProcess(one_device, make, kwargs)``: the child's world is ``make(**kwargs)``,
    started (``make`` an importable class or function; its device has ``start`` and
    ``stop``)."""
    return DeviceWorld(make(**kwargs).start())


# -- the child ---------------------------------------------------------------------------
def serve(conn: Connection, host: int) -> None:
    """The child's main: build the world, report ready, serve until stop or until the
    process whose pidfd is ``host`` has ended."""
    raise_device_priority()  # before any thread: each inherits it
    threading.Thread(target=_watch_host, args=(host,), name="host-watch",
                     daemon=True).start()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        build, args = conn.recv()
        world = build(*args)
    except BaseException as exc:
        conn.send(("err", f"building the simulated world: {exc!r}"))
        return
    # a device's firmware does not stop for a collector: what the build made (numpy, scipy
    # and the world's devices, about 70 000 objects) is left out of the cyclic collector,
    # whose full pass over it holds every device of this process (18 ms of an idle core
    # here, longer when preempted meanwhile); bench.engine.frozen_heap does the same for
    # the bench's heap during a run
    gc.freeze()
    conn.send(("ok", None))
    try:
        while True:
            try:
                op, key, attrs, call_args = conn.recv()
            except (EOFError, OSError):  # the parent died: no one to serve
                break
            if op == "stop":
                break
            try:
                obj = world if key is None else world.peers[key]
                for name in attrs if op == "get" else attrs[:-1]:
                    obj = getattr(obj, name)
                if op == "call":
                    value = getattr(obj, attrs[-1])(*call_args)
                elif op == "set":
                    setattr(obj, attrs[-1], call_args[0])
                    value = None
                else:
                    value = obj
                conn.send(("ok", value))
            except DeviceError as exc:  # a device's own words, as in the host's process
                conn.send(("device", str(exc)))
            except Exception as exc:
                conn.send(("err", f"{'.'.join(attrs)}: {exc!r}"))
    finally:
        world.close()


def _watch_host(host: int) -> None:
    """End the child when its host is gone, whatever the main loop does."""
    select.select([host], [], [])
    os._exit(0)
