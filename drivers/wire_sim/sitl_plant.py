"""The simulated plant as the Betaflight SITL's vehicle: FDM in, motor output out.

The firmware answers every FDM packet it accepts with one motor update and sends nothing
while FDM is silent (betaflight-sitl.md §1.4), so this peer is the firmware's heartbeat
as well as its world: one thread sends a level, resting FDM packet every
``1 / rate_hz`` (>= 100 Hz) to UDP 9003 and, between packets, reads the motor updates
from UDP 9001 (``servo_packet_raw``: microseconds in Betaflight's motor order, no re-ordering or
rescaling, and none for the firmware's stale re-sync reply). Each update sets the
:class:`~drivers.wire_sim.plant_peers.WirePlant`'s ESC command at its arrival, so the
motor, propeller, load cell and power sensor see what the firmware outputs, when it
outputs it, and never what the bench asked for.

The packets need not be at rest: ``fdm(wall_t)`` gives each one (the IMU bench's hexapod
world: ``drivers.wire_sim.sitl_imu_world``), and without a plant (``plant=None``) the
motor updates only prove the firmware alive (``wait_output``, ``check``).

``changes()`` keeps each change of the watched motor's output with its arrival time
(the machine's monotonic clock): the other half of the command-to-output delay
(``drivers.command_delay``).

On the propulsion stand the peer runs with the plant in the world's process
(``drivers.wire_sim.world_process``), as the simulated serial devices do: a loaded host no
longer delays the FDM stream, the firmware's output or the load-cell board it drives.
:class:`RemoteSitlPeer` is the bench's handle on it there.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import math
import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Any, Self

import numpy as np

from drivers.backends.sitl_fdm_link import motor_listener
from drivers.codecs.sitl import (
    FDM_PORT,
    MOTOR_RAW_PORT,
    MOTOR_RAW_SIZE,
    decode_motor_raw,
    encode_fdm_at_rest,
    fdm_stamps,
)
from drivers.errors import DeviceError

__all__ = ["RemoteSitlPeer", "SitlPlantPeer"]

IDLE_WAIT_S = 0.3  # at stop: how long the firmware's output may take to reach idle
MAX_SILENCE_S = 0.5  # fed but no motor update for this long: the firmware stalled
LIVENESS_PERIOD_S = 0.05  # the host's handle asks the peer in the world this often
WORLD_SILENT_S = 1.0  # the world's process unanswering for this long: the plant is deaf


class SitlPlantPeer:
    """FDM feeder and motor listener on loopback, driving ``plant`` (if any) from motor
    ``motor_index`` (0 = Betaflight motor 1); ``fdm(wall_t)`` makes each packet."""

    def __init__(self, plant: Any, motor_index: int, *, rate_hz: float = 250.0,
                 host: str = "127.0.0.1",
                 fdm: Callable[[float], bytes] | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        self.plant = plant
        stamps = fdm_stamps()  # at rest: the firmware's clock at real time, even under load
        self.fdm = fdm or (lambda _wall_t: encode_fdm_at_rest(next(stamps)))
        self.clock = clock  # stamps the motor updates for fresh() (the rig's clock)
        self._beats: collections.deque[float] = collections.deque(maxlen=8192)
        self.motor_index = motor_index
        self.period_s = 1.0 / rate_hz
        self.host = host
        self.fdm_sent = 0
        self.updates = 0  # motor updates received
        self.last_us = math.nan
        self.error: DeviceError | None = None  # why the loop stopped, if it failed
        self.last_update_t = math.nan  # arrival of the latest motor update (monotonic)
        self._fed_since = math.nan  # feeding (again) since
        self._changes: list[tuple[float, float]] = []
        self._lock = threading.Lock()
        self._feeding = threading.Event()
        self._feeding.set()
        self._stop = threading.Event()
        self._rx = motor_listener(host)
        self._tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._thread = threading.Thread(target=self._run, name="sitl-plant", daemon=True)

    def start(self) -> Self:
        self._fed_since = time.monotonic()
        self._thread.start()
        return self

    def wait_output(self, timeout_s: float) -> None:
        """Return once the firmware's first motor update has arrived, or raise."""
        deadline = time.monotonic() + timeout_s
        while self.updates == 0:
            if self.error is not None:
                raise self.error
            if time.monotonic() > deadline:
                raise DeviceError(f"the Betaflight SITL sent no motor output within "
                                  f"{timeout_s:g} s of the first FDM packet ({self.fdm_sent} "
                                  f"sent to UDP {FDM_PORT}, none back on {MOTOR_RAW_PORT})")
            time.sleep(0.01)

    def check(self) -> None:
        """Raise if the loop failed or a fed firmware has gone silent (its output no
        longer reaches the plant: the bench must stop, not command a deaf rig)."""
        if self.error is not None:
            raise self.error
        if not self._feeding.is_set():
            return
        heard = max(self.last_update_t if self.updates else -math.inf, self._fed_since)
        silent = time.monotonic() - heard
        if silent > MAX_SILENCE_S:
            raise DeviceError(f"the Betaflight SITL's motor output stopped: nothing on UDP "
                              f"{MOTOR_RAW_PORT} for {silent:.2f} s while fed FDM")

    # -- the loop -------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._loop()
        except Exception as exc:  # the bench reads it on its next command
            self.error = DeviceError(f"Betaflight SITL plant peer stopped: "
                                     f"{type(exc).__name__}: {exc}")

    def _loop(self) -> None:
        """Late, it skips ahead instead of sending a burst (the resting packets' stamps keep
        the firmware's clock at real time: ``drivers.codecs.sitl.fdm_stamps``)."""
        due = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= due:
                if self._feeding.is_set():
                    with contextlib.suppress(OSError):  # no route yet: try next period
                        self._tx.sendto(self.fdm(now), (self.host, FDM_PORT))
                        self.fdm_sent += 1
                due = max(due + self.period_s, now)
            with contextlib.suppress(OSError, ValueError):
                ready, _, _ = select.select([self._rx], [], [], max(0.0, due - time.monotonic()))
                if ready:
                    self._drain()

    def _drain(self) -> None:
        while True:
            try:
                data = self._rx.recv(256)
            except BlockingIOError:
                return
            t = time.monotonic()
            if len(data) != MOTOR_RAW_SIZE:
                continue
            motors = decode_motor_raw(data).motor_us
            if self.motor_index >= len(motors) or not math.isfinite(motors[self.motor_index]):
                continue
            self._apply(t, motors[self.motor_index])

    def _apply(self, t: float, pulse_us: float) -> None:
        self.last_update_t = t
        self.updates += 1
        if self.clock is not None:
            self._beats.append(self.clock())
        if self.plant is not None:
            self.plant.command_pulse(pulse_us)
        if pulse_us != self.last_us:
            with self._lock:
                self._changes.append((t, pulse_us))
        self.last_us = pulse_us

    # -- what the bench and the tests read ----------------------------------------------
    def changes(self, since: float = -math.inf) -> list[tuple[float, float]]:
        """(arrival time, us) of each change of the motor's output since ``since``."""
        with self._lock:
            return [c for c in self._changes if c[0] >= since]

    def fresh(self, stamps: Any, max_gap_s: float) -> Any:
        """Whether the firmware accepted an FDM packet within ``max_gap_s`` before each of
        ``stamps`` (the rig's clock): each accepted packet brings one motor update, so a
        reading polled where none came just before is one the firmware's sensors did not
        refresh (a starved machine stalled the feeder or the firmware's packet thread,
        while its main thread went on answering with the last packet's data; the packets
        queued meanwhile are taken in a burst after, too late for such a reading)."""
        t = np.asarray(stamps, float)
        beats = np.fromiter(self._beats, float)
        i = np.searchsorted(beats, t, side="right") - 1  # the last beat at or before each
        last = beats[np.maximum(i, 0)] if beats.size else np.full(t.shape, -np.inf)
        return (i >= 0) & (t - last <= max_gap_s)

    def pause(self) -> None:
        """Stop feeding FDM: the firmware then sends no motor output (tests)."""
        self._feeding.clear()

    def resume(self) -> None:
        self._fed_since = time.monotonic()
        self._feeding.set()

    def stop(self) -> None:
        """Let the firmware's idle output (the bench sent 1000 before closing) reach the
        plant, stop the loop, then idle the plant: its ESC has lost the signal."""
        deadline = time.monotonic() + IDLE_WAIT_S
        idle = self.plant.settings.idle_us if self.plant is not None else math.inf
        while (self._thread.is_alive() and self._feeding.is_set() and not self.last_us <= idle
               and time.monotonic() < deadline):
            time.sleep(0.01)
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(1.0)
        self._rx.close()
        self._tx.close()
        if self.plant is not None:
            self.plant.command_pulse(idle)


_KEYS = itertools.count()
_COUNTERS = ("updates", "fdm_sent", "last_us")


class RemoteSitlPeer:
    """The host's handle on a :class:`SitlPlantPeer` in the plant's world process (the
    same calls, each a request there); ``updates``, ``fdm_sent`` and ``last_us`` are read
    there, and answered as they were at ``stop()`` once stopped.

    ``check()`` asks nothing: the bench calls it before every command, and a request to a
    busy world process held the bench's command loop in it (0.51 s once, past the loop's
    watchdog). A thread of this handle asks the peer every ``LIVENESS_PERIOD_S`` instead;
    ``check()`` raises what that thread last heard, or if the world has not answered it
    for ``WORLD_SILENT_S`` (a world that slow no longer drives the plant on time either).
    """

    def __init__(self, world: Any, motor_index: int, rate_hz: float) -> None:
        self._world = world  # a drivers.wire_sim.world_process.WorldProcess
        self._key = f"sitl-plant:{next(_KEYS)}"  # a relaunch starts a new peer
        self._args = (motor_index, rate_hz)
        self._final: dict[str, Any] | None = None
        self._heard_t = math.nan  # when the world last answered the liveness check
        self._error: DeviceError | None = None  # what it answered, if not alive
        self._stop_watch = threading.Event()
        self._watcher = threading.Thread(target=self._watch, name="sitl-liveness", daemon=True)

    def start(self) -> Self:
        self._world.request("call", None, ("start_sitl",), (self._key, *self._args))
        self._heard_t = time.monotonic()
        self._watcher.start()
        return self

    def _watch(self) -> None:
        while not self._stop_watch.wait(LIVENESS_PERIOD_S):
            try:
                self._call("check")
            except DeviceError as exc:
                self._error = exc
                return
            self._heard_t = time.monotonic()

    def _call(self, name: str, *args: Any) -> Any:
        return self._world.request("call", self._key, (name,), args)

    def _get(self, name: str) -> Any:
        if self._final is not None:
            return self._final[name]
        return self._world.request("get", self._key, (name,))

    @property
    def updates(self) -> int:
        return self._get("updates")

    @property
    def fdm_sent(self) -> int:
        return self._get("fdm_sent")

    @property
    def last_us(self) -> float:
        return self._get("last_us")

    def wait_output(self, timeout_s: float) -> None:
        self._call("wait_output", timeout_s)

    def check(self) -> None:
        """Raise what the liveness thread last heard (class doc), without a request."""
        if self._error is not None:
            raise self._error
        silent = time.monotonic() - self._heard_t
        if self._final is None and silent > WORLD_SILENT_S:
            raise DeviceError(f"the simulated plant's process has not answered for "
                              f"{silent:.2f} s: the firmware's output may not reach the plant")

    def changes(self, since: float = -math.inf) -> list[tuple[float, float]]:
        return self._call("changes", since)

    def pause(self) -> None:
        self._call("pause")

    def resume(self) -> None:
        self._call("resume")

    def stop(self) -> None:
        """Stops the peer there (see :meth:`SitlPlantPeer.stop`) and keeps its counters."""
        self._stop_watch.set()
        if self._watcher.is_alive():
            self._watcher.join(WORLD_SILENT_S)
        if self._final is None:
            self._call("stop")
            self._final = {name: self._get(name) for name in _COUNTERS}
