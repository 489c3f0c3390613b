"""A simulated PI-style hexapod controller answering GCS text commands on loopback TCP.

Behaviour from protocols.md §6.1-§6.3: replies terminated per the GCS rule, ``ERR?``
returns and clears the last error (2 unknown command, 1 syntax, 15 invalid axis,
7 out of limits, 9 pivot refused, 10 after a stop, 17 parameter out of range), POS?/MOV?/
ONT?/SPI?/VLS? answer ``AXIS=value`` lines, #5 a hex bit mask of moving axes, #9 of
running wave generators, #7 the ready character, #24/STP/HLT stop.

Two modes:

* stand-alone (no ``plant``): MOV/MVR move all axes together at the system velocity
  (VLS, controller units per second) on the wall clock; wave-generator commands are
  accepted and recorded (``commands``) but move nothing.
* on a plant (a :class:`drivers.sim.hexapod_device.SimHexapodDevice`, the same simulated
  hexapod the plain simulated IMU bench uses, on its simulated clock): wave tables
  written point by point (``WAV <t> <X|&> PNT <first> <n> <values>``, the form the
  backend chose, [U] on hardware) are followed when ``WGO`` starts their generators
  (generator k drives axis k of X Y Z U V W at WTR servo cycles per point; the plant runs
  the clamped cubic spline through the points), the data recorder (DRC option 1/2/3,
  RTR) restarts with every ``WGO`` start and ``DRR?`` answers GCS data arrays of the
  points recorded so far; SPI sets the plant's pivot; #24 freezes the platform.

Faults: ``disconnect()`` (silent: commands read, never answered), ``stall(s, n)``
(replies on the n-th accepted connection come ``s`` seconds late, wall clock) and
``drop_connections()`` (the controller closes every client connection; new ones are
accepted). ``commands`` lists every command received, ``by_connection`` the command
names per accepted connection; ``pose_at(t)`` gives the platform pose in controller units.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import numpy as np

from drivers.codecs import gcs
from drivers.contracts import HexapodLimitError, Trajectory
from drivers.errors import DeviceError

if TYPE_CHECKING:  # the simulated IMU bench's hexapod, when the controller drives one
    from drivers.sim.hexapod_device import SimHexapodDevice

PIVOT_AXES = ("R", "S", "T")  # §6.3 [U]: pivot coordinate names, unverified in the sources
_SI_PER_WIRE = np.array([1e-3, 1e-3, 1e-3, math.pi / 180, math.pi / 180, math.pi / 180])
_MOVE_RATE_HZ = 100.0  # MOV on a plant: a smooth path sampled at this rate
_RECORD_NAMES = {1: "Commanded Position", 2: "Actual Position", 3: "Position Error"}


def _num(v: float) -> str:
    """Six decimals (mm, deg) without trailing zeros: 0.5, -3.999876, 0."""
    text = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


class _Axis:
    def __init__(self) -> None:
        self.start = 0.0
        self.target = 0.0
        self.t0 = 0.0
        self.duration = 0.0

    def value(self, now: float) -> float:
        if self.duration <= 0 or now >= self.t0 + self.duration:
            return self.target
        return self.start + (self.target - self.start) * (now - self.t0) / self.duration


class _Refused(Exception):
    """A command refused with a GCS error code."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


class SimPiController:
    """Loopback TCP server; ``start()`` returns it, ``address`` is (host, port)."""

    def __init__(self, *, velocity: float = 10.0, limit: float = 50.0,
                 host: str = "127.0.0.1", port: int = 0, plant: SimHexapodDevice | None = None,
                 servo_cycle_s: float = gcs.SERVO_CYCLE_S_C887,
                 recorder_points: int = 1 << 22, max_wave_points: int = 1 << 20,
                 travel: dict[str, tuple[float, float]] | None = None,
                 referenced: bool = True, servo: bool = True) -> None:
        self.velocity = velocity  # controller units per second for every axis (VLS)
        self.limit = limit  # |value| limit of every axis, controller units
        # soft limits TMN?/TMX? per axis (controller units); default +-limit
        self.travel = {a: (-limit, limit) for a in gcs.HEXAPOD_AXES}
        self.travel.update(travel or {})
        self.referenced = referenced  # FRF?: a C-887 references all axes at once (FRF X)
        self.servo: dict[str, bool] = dict.fromkeys(gcs.HEXAPOD_AXES, servo)  # SVO?
        self.plant = plant
        self.servo_cycle_s = servo_cycle_s
        self.recorder_points = recorder_points
        self.max_wave_points = max_wave_points
        self._now: Callable[[], float] = plant.clock.now if plant is not None else time.monotonic
        self.axes: dict[str, _Axis] = {a: _Axis() for a in gcs.HEXAPOD_AXES}
        self.pivot: dict[str, float] = dict.fromkeys(PIVOT_AXES, 0.0)
        self.error = 0
        self.commands: list[gcs.GcsCommand] = []
        # wave generator and data recorder state
        self.wave_tables: dict[int, list[float]] = {}
        self.wave_select: dict[int, int] = {}  # generator -> table (WSL)
        self.wave_rate: dict[int, int] = {}  # generator -> servo cycles per point (WTR)
        self.wave_cycles: dict[int, int] = {}  # generator -> cycles (WGC)
        self.wave_running: set[int] = set()
        self.record_tables: dict[int, tuple[str, int]] = {}  # table -> (axis, option)
        self.record_rate = 1  # servo cycles per point (RTR)
        self.record_t0: float | None = None
        self._lock = threading.RLock()
        self._server = socket.create_server((host, port))
        self._server.settimeout(0.05)
        self.address = self._server.getsockname()[:2]
        self._stop = threading.Event()
        self._silent = threading.Event()
        self._threads: list[threading.Thread] = []
        self._conns: list[socket.socket] = []
        self.by_connection: list[list[str]] = []
        self._stall: dict[int, float] = {}

    def start(self) -> SimPiController:
        t = threading.Thread(target=self._accept, name="sim-pi-accept", daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=1.0)
        self._server.close()

    def disconnect(self) -> None:
        """Fault: the controller stops answering (commands are read and ignored)."""
        self._silent.set()

    def stall(self, seconds: float, connection: int = 0) -> None:
        """Fault: replies on the ``connection``-th accepted connection come late."""
        self._stall[connection] = float(seconds)

    def drop_connections(self) -> None:
        """Fault: the controller closes every client connection (new ones are accepted);
        the platform carries on with what it was doing."""
        with self._lock:
            conns, self._conns = self._conns, []
        for conn in conns:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def pose_at(self, now: float | None = None) -> dict[str, float]:
        now = self._now() if now is None else now
        with self._lock:
            return dict(zip(gcs.HEXAPOD_AXES, self._poses(np.array([now]))[0], strict=True))

    # ------------------------------------------------------------------ server
    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with self._lock:
                self._conns.append(conn)
                self.by_connection.append([])
                index = len(self.by_connection) - 1
            t = threading.Thread(target=self._serve, args=(conn, index), daemon=True)
            t.start()
            self._threads.append(t)

    def _serve(self, conn: socket.socket, index: int) -> None:
        dec = gcs.GcsCommandDecoder()
        conn.settimeout(0.05)
        with conn:
            while not self._stop.is_set():
                try:
                    data = conn.recv(1 << 16)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                for cmd in dec.feed(data):
                    self.commands.append(cmd)
                    self.by_connection[index].append(cmd.name)
                    reply = self._handle(cmd)
                    if reply is not None and not self._silent.is_set():
                        delay = self._stall.pop(index, 0.0)
                        if delay > 0:
                            time.sleep(delay)
                        try:
                            conn.sendall(reply)
                        except OSError:
                            return

    # ------------------------------------------------------------------ state
    def _poses(self, t: np.ndarray) -> np.ndarray:
        """Platform pose ``(n, 6)`` in controller units (mm, deg) at times ``t``."""
        if self.plant is not None:
            pose, _, _ = self.plant.kinematics_at(t)
            return pose / _SI_PER_WIRE
        return np.array([[ax.value(float(tt)) for ax in self.axes.values()] for tt in t])

    def _moving(self, now: float) -> bool:
        if self.plant is not None:
            return bool(self.plant.is_moving())
        return any(ax.value(now) != ax.target for ax in self.axes.values())

    def _running(self, now: float) -> set[int]:
        if self.wave_running and not (self.plant is not None and self.plant.is_moving()):
            self.wave_running = set()
        return self.wave_running

    # ------------------------------------------------------------------ commands
    def _fail(self, code: int) -> None:
        self.error = code

    def _axis_pairs(self, args: tuple[str, ...], names) -> dict[str, float] | None:
        if not args or len(args) % 2:
            self._fail(1)  # parameter syntax error
            return None
        out = {}
        for name, text in zip(args[::2], args[1::2], strict=True):
            if name not in names:
                self._fail(15)  # invalid axis
                return None
            try:
                out[name] = float(text)
            except ValueError:
                self._fail(1)
                return None
        return out

    @staticmethod
    def _ints(args: tuple[str, ...], n: int | None = None) -> list[int]:
        if not args or (n is not None and len(args) != n):
            raise _Refused(1)
        try:
            return [int(a) for a in args]
        except ValueError:
            raise _Refused(1) from None

    def _values(self, values: Mapping[str, float]) -> bytes:
        return gcs.encode_reply(f"{k}={v:.6f}" for k, v in values.items())

    def _ready_to_move(self) -> None:
        """Error 5 (move without reference or with servo off), as the controller refuses."""
        if not self.referenced or not all(self.servo.values()):
            raise _Refused(5)

    def _move(self, targets: dict[str, float], now: float) -> None:
        self._ready_to_move()
        if any(not self.travel[a][0] <= v <= self.travel[a][1] for a, v in targets.items()):
            self._fail(7)  # position out of limits
            return
        if self.plant is not None:
            self._plant_move(self.plant, targets, now)
            return
        cur = {a: ax.value(now) for a, ax in self.axes.items()}
        dist = max(abs(targets[a] - cur[a]) for a in targets)
        duration = dist / self.velocity if self.velocity > 0 else 0.0
        for a, v in targets.items():  # all axes start and arrive together
            ax = self.axes[a]
            ax.start, ax.target, ax.t0, ax.duration = cur[a], v, now, duration

    def _plant_move(self, plant: SimHexapodDevice, targets: dict[str, float],
                    now: float) -> None:
        """MOV on a plant: a raised-cosine path whose peak speed is the system velocity."""
        if plant.is_moving():
            raise _Refused(17)
        here = self._poses(np.array([now]))[0]
        goal = here.copy()
        for a, v in targets.items():
            goal[gcs.HEXAPOD_AXES.index(a)] = v
        dist = float(np.abs(goal - here).max())
        if dist == 0.0:
            return
        duration = max(math.pi / 2 * dist / max(self.velocity, 1e-9), 2.0 / _MOVE_RATE_HZ)
        s = (1.0 - np.cos(np.pi * np.linspace(0.0, 1.0, round(duration * _MOVE_RATE_HZ) + 1)))
        poses = (here + np.outer(s / 2.0, goal - here)) * _SI_PER_WIRE
        poses[0] = plant.kinematics_at(np.array([now]))[0][0]
        self._plant_run(plant, Trajectory("MOV", (len(poses) - 1) / duration, poses))
        for a, v in targets.items():
            self.axes[a].target = v  # MOV? answers the last commanded target

    @staticmethod
    def _plant_run(plant: SimHexapodDevice, traj: Trajectory) -> None:
        try:
            plant.upload(traj)
            plant.start()
        except HexapodLimitError:
            raise _Refused(7) from None
        except DeviceError:
            raise _Refused(17) from None

    def _halt(self, now: float) -> None:
        self.wave_running = set()
        if self.plant is not None:
            try:
                self.plant.stop()
            except DeviceError:
                pass  # a plant fault loses the reply, not the stop
        for ax in self.axes.values():
            v = ax.value(now)
            ax.start = ax.target = v
            ax.duration = 0.0
        self.error = gcs.STOPPED_BY_COMMAND

    # -- wave generator -------------------------------------------------------------------
    def _wav(self, args: tuple[str, ...]) -> None:
        if len(args) < 3:
            raise _Refused(1)
        table = self._ints(args[:1])[0]
        append, shape = args[1], args[2]
        if append not in ("X", "&", "+"):
            raise _Refused(1)
        if shape != "PNT":
            return  # other shapes: accepted and recorded in ``commands``, not generated
        first, n = self._ints(args[3:5], 2)
        try:
            values = [float(v) for v in args[5:]]
        except ValueError:
            raise _Refused(1) from None
        if len(values) != n or first < 1 or append == "+":
            raise _Refused(17)
        old = self.wave_tables.get(table, []) if append == "&" else []
        if len(old) + n > self.max_wave_points:
            raise _Refused(17)
        self.wave_tables[table] = old + values

    def _wgo(self, args: tuple[str, ...], now: float) -> None:
        pairs = self._ints(args)
        if len(pairs) % 2:
            raise _Refused(1)
        modes = dict(zip(pairs[::2], pairs[1::2], strict=True))
        if any(g not in range(1, 7) for g in modes) or any(m not in (0, 1) for m in
                                                           modes.values()):
            raise _Refused(17)
        stop = {g for g, m in modes.items() if m == 0}
        go = {g for g, m in modes.items() if m == 1}
        if stop & self._running(now):
            self._halt(now)
            self.error = 0  # stopping a generator is not an error
        if not go:
            return
        self._ready_to_move()
        if self.plant is not None:
            if self._moving(now):
                raise _Refused(17)
            self._plant_run(self.plant, self._wave_trajectory(go, now))
        self.wave_running = set(go)
        self.record_t0 = now  # the recorder restarts with the generators [U]

    def _wave_trajectory(self, generators: set[int], now: float) -> Trajectory:
        rates = {self.wave_rate.get(g, 1) for g in generators}
        tables = [t for g in generators
                  if (t := self.wave_tables.get(self.wave_select.get(g, -1))) is not None]
        if len(rates) != 1 or len(tables) != len(generators) or \
                any(len(t) < 2 for t in tables) or \
                len({len(t) for t in tables}) != 1 or \
                any(self.wave_cycles.get(g, 1) != 1 for g in generators):
            raise _Refused(17)  # the simulator runs equal tables once, at one rate
        n = len(tables[0])
        here = self._poses(np.array([now]))[0]
        poses = np.tile(here, (n, 1))
        for g in generators:
            poses[:, g - 1] = self.wave_tables[self.wave_select[g]]
        (rate,) = rates
        return Trajectory("wave", 1.0 / (rate * self.servo_cycle_s), poses * _SI_PER_WIRE)

    # -- data recorder --------------------------------------------------------------------
    def _drr(self, args: tuple[str, ...], now: float) -> bytes:
        ints = self._ints(args)
        if len(ints) < 3:
            raise _Refused(26)
        offset, count, tables = ints[0], ints[1], ints[2:]
        if offset < 1 or count < 0 or any(t not in self.record_tables for t in tables):
            raise _Refused(17)
        period = self.record_rate * self.servo_cycle_s
        available = 0
        t0 = self.record_t0
        if t0 is not None:
            available = min(math.floor((now - t0) / period + 1e-9) + 1, self.recorder_points)
        k = np.arange(offset - 1, min(offset - 1 + count, available))
        # no points without a start (available is 0)
        poses = self._poses(t0 + k * period) if t0 is not None and k.size else np.empty((0, 6))
        cols = []
        for table in tables:
            axis, option = self.record_tables[table]
            cols.append(np.zeros(k.size) if option == 3 else
                        poses[:, gcs.HEXAPOD_AXES.index(axis)])
        data = np.column_stack(cols) if k.size else np.empty((0, len(tables)))
        header = ["# REM rotorbench simulated C-887 data recorder", "# VERSION = 1",
                  "# TYPE = 1", "# SEPARATOR = 32", f"# DIM = {len(tables)}",
                  f"# SAMPLE_TIME = {period:.6g}", f"# NDATA = {k.size}",
                  *(f"# NAME{i} = {_RECORD_NAMES[self.record_tables[t][1]]} of axis "
                    f"{self.record_tables[t][0]}" for i, t in enumerate(tables)),
                  "# END_HEADER"]
        rows = [" ".join(_num(v) for v in row) for row in data]
        return gcs.encode_reply([*header, *rows])

    # -- dispatch -------------------------------------------------------------------------
    def _handle(self, cmd: gcs.GcsCommand) -> bytes | None:
        with self._lock:
            now = self._now()
            try:
                return self._dispatch(cmd.name, cmd.args, now)
            except _Refused as exc:
                code = exc.code
            except DeviceError:  # a fault of the simulated plant: the command failed
                code = 17
            except (ValueError, IndexError, KeyError):  # arguments of the wrong shape
                code = 1
            self._fail(code)
            return gcs.encode_reply(["0"]) if cmd.name.endswith("?") else None

    def _dispatch(self, name: str, args: tuple[str, ...], now: float) -> bytes | None:
        if name == "ERR?":
            code, self.error = self.error, 0
            return gcs.encode_reply([str(code)])
        if name == "*IDN?":
            return gcs.encode_reply(["rotorbench simulator,C-887,0,0.0.0"])
        if name == "CSV?":
            return gcs.encode_reply(["2.0"])
        if name == "SAI?":
            return gcs.encode_reply(list(gcs.HEXAPOD_AXES))
        moving = self._moving(now)
        if name in ("POS?", "MOV?", "ONT?"):
            axes = args or gcs.HEXAPOD_AXES
            if any(a not in self.axes for a in axes):
                self._fail(15)
                return gcs.encode_reply(["0"]) if name == "ONT?" else self._values({})
            if name == "POS?":
                pose: dict[str, float] = dict(zip(gcs.HEXAPOD_AXES, self._poses(np.array([now]))[0],
                                strict=True))
                return self._values({a: pose[a] for a in axes})
            if name == "MOV?":
                return self._values({a: self.axes[a].target for a in axes})
            return gcs.encode_reply(f"{a}={int(not moving)}" for a in axes)
        if name in ("MOV", "MVR"):
            pairs = self._axis_pairs(args, self.axes)
            if pairs is not None:
                if name == "MVR":
                    base: dict[str, float] = dict(zip(
                        gcs.HEXAPOD_AXES, self._poses(np.array([now]))[0], strict=True)) \
                        if self.plant is not None else \
                        {a: ax.target for a, ax in self.axes.items()}
                    pairs = {a: base[a] + v for a, v in pairs.items()}
                self._move(pairs, now)
            return None
        if name == "SPI":
            pairs = self._axis_pairs(args, self.pivot)
            if pairs is not None:
                if moving:
                    self._fail(9)  # setting the pivot point not possible while moving
                else:
                    self.pivot.update(pairs)
                    if self.plant is not None:
                        r, s, t = (self.pivot[a] * 1e-3 for a in PIVOT_AXES)
                        self.plant.set_pivot((r, s, t))
            return None
        if name == "SPI?":
            return self._values(self.pivot)
        if name == "VLS":
            try:
                self.velocity = float(args[0])
            except (IndexError, ValueError):
                self._fail(1)
            return None
        if name == "VLS?":
            return gcs.encode_reply([f"{self.velocity:.6f}"])
        if name == "#5":
            mask = 0x3F if moving else 0
            return gcs.encode_reply([format(mask, "X")])
        if name == "#9":
            mask = sum(1 << (g - 1) for g in self._running(now))
            return gcs.encode_reply([format(mask, "X")])
        if name == "#7":
            return gcs.encode_reply([gcs.BUSY_CHAR if moving else gcs.READY_CHAR])
        if name in ("#24", "STP", "HLT"):
            self._halt(now)
            return None
        if name == "WAV":
            self._wav(args)
            return None
        if name == "WSL":
            g, t = self._ints(args, 2)
            self.wave_select[g] = t
            return None
        if name == "WTR":
            g, rate, *_ = self._ints(args)
            if rate < 1:
                raise _Refused(17)
            self.wave_rate[g] = rate
            return None
        if name == "WGC":
            g, cycles = self._ints(args, 2)
            self.wave_cycles[g] = cycles
            return None
        if name == "WGO":
            self._wgo(args, now)
            return None
        if name == "DRC":
            if len(args) != 3 or args[1] not in self.axes:
                raise _Refused(1 if len(args) != 3 else 15)
            table, option = self._ints((args[0], args[2]), 2)
            if option not in _RECORD_NAMES:
                raise _Refused(17)
            self.record_tables[table] = (args[1], option)
            return None
        if name == "RTR":
            (rate,) = self._ints(args, 1)
            if rate < 1:
                raise _Refused(17)
            self.record_rate = rate
            return None
        if name == "DRR?":
            return self._drr(args, now)
        if name == "SVO":
            pairs = self._axis_pairs(args, self.servo)
            if pairs is not None:
                self.servo.update({a: v != 0 for a, v in pairs.items()})
            return None
        if name == "FRF":
            if any(a not in self.axes for a in args):
                raise _Refused(15)
            if not all(self.servo.values()):
                raise _Refused(5)
            self.referenced = True  # at once: the simulator has no reference move to run
            return None
        if name in ("SVO?", "FRF?", "TMN?", "TMX?"):
            axes = args or gcs.HEXAPOD_AXES
            if any(a not in self.axes for a in axes):
                raise _Refused(15)
            if name in ("SVO?", "FRF?"):
                on = self.servo if name == "SVO?" else dict.fromkeys(axes, self.referenced)
                return gcs.encode_reply(f"{a}={int(on[a])}" for a in axes)
            k = 0 if name == "TMN?" else 1
            return self._values({a: self.travel[a][k] for a in axes})
        if name == "WSL?":
            gens = self._ints(args) if args else list(range(1, 7))
            return gcs.encode_reply(f"{g}={self.wave_select.get(g, 0)}" for g in gens)
        if name == "WGO?":
            gens = self._ints(args) if args else list(range(1, 7))
            running = self._running(now)
            return gcs.encode_reply(f"{g}={int(g in running)}" for g in gens)
        if name == "DRC?":
            tables = self._ints(args) if args else sorted(self.record_tables)
            if any(t not in self.record_tables for t in tables):
                raise _Refused(17)
            return gcs.encode_reply(f"{t}={self.record_tables[t][0]} {self.record_tables[t][1]}"
                                    for t in tables)
        if name.endswith("?"):
            self._fail(2)
            return gcs.encode_reply(["0"])
        self._fail(2)  # unknown command
        return None
