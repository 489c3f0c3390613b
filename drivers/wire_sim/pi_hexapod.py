"""A simulated PI-style hexapod controller answering GCS text commands on loopback TCP.

Behaviour from protocols.md §6.1-§6.3: replies terminated per the GCS rule, ``ERR?``
returns and clears the last error (2 unknown command, 1 syntax, 15 invalid axis,
7 out of limits, 10 after a stop), MOV/MVR move all axes together at the system velocity
(VLS, controller units per second), POS?/MOV?/ONT?/SPI?/VLS? answer ``AXIS=value`` lines,
#5 a hex bit mask of moving axes, #7 the ready character, #24/STP/HLT stop. Wave-generator
and data-recorder commands are accepted and recorded, not executed (``commands`` lists
everything received). ``pose_at(t)`` lets a plant read the platform pose.
"""

from __future__ import annotations

import socket
import threading
import time

from drivers.codecs import gcs

PIVOT_AXES = ("R", "S", "T")  # §6.3 [U]: pivot coordinate names, unverified in the sources


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


class SimPiController:
    """Loopback TCP server; ``start()`` returns it, ``address`` is (host, port)."""

    def __init__(self, *, velocity: float = 10.0, limit: float = 50.0,
                 host: str = "127.0.0.1", port: int = 0) -> None:
        self.velocity = velocity  # controller units per second for every axis (VLS)
        self.limit = limit  # |value| limit of every axis, controller units
        self.axes = {a: _Axis() for a in gcs.HEXAPOD_AXES}
        self.pivot = dict.fromkeys(PIVOT_AXES, 0.0)
        self.error = 0
        self.commands: list[gcs.GcsCommand] = []
        self._lock = threading.Lock()
        self._server = socket.create_server((host, port))
        self._server.settimeout(0.05)
        self.address = self._server.getsockname()[:2]
        self._stop = threading.Event()
        self._silent = threading.Event()
        self._threads: list[threading.Thread] = []

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

    def pose_at(self, now: float | None = None) -> dict[str, float]:
        now = time.monotonic() if now is None else now
        with self._lock:
            return {a: ax.value(now) for a, ax in self.axes.items()}

    # ------------------------------------------------------------------ server
    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            t = threading.Thread(target=self._serve, args=(conn,), daemon=True)
            t.start()
            self._threads.append(t)

    def _serve(self, conn: socket.socket) -> None:
        dec = gcs.GcsCommandDecoder()
        conn.settimeout(0.05)
        with conn:
            while not self._stop.is_set():
                try:
                    data = conn.recv(4096)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                for cmd in dec.feed(data):
                    self.commands.append(cmd)
                    reply = self._handle(cmd)
                    if reply is not None and not self._silent.is_set():
                        conn.sendall(reply)

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

    def _values(self, values: dict[str, float]) -> bytes:
        return gcs.encode_reply(f"{k}={v:.6f}" for k, v in values.items())

    def _move(self, targets: dict[str, float], now: float) -> None:
        if any(abs(v) > self.limit for v in targets.values()):
            self._fail(7)  # position out of limits
            return
        cur = {a: ax.value(now) for a, ax in self.axes.items()}
        dist = max(abs(targets[a] - cur[a]) for a in targets)
        duration = dist / self.velocity if self.velocity > 0 else 0.0
        for a, v in targets.items():  # all axes start and arrive together
            ax = self.axes[a]
            ax.start, ax.target, ax.t0, ax.duration = cur[a], v, now, duration

    def _halt(self, now: float) -> None:
        for ax in self.axes.values():
            v = ax.value(now)
            ax.start = ax.target = v
            ax.duration = 0.0
        self.error = gcs.STOPPED_BY_COMMAND

    def _handle(self, cmd: gcs.GcsCommand) -> bytes | None:
        now = time.monotonic()
        name, args = cmd.name, cmd.args
        with self._lock:
            moving = [a for a, ax in self.axes.items() if ax.value(now) != ax.target]
            if name == "ERR?":
                code, self.error = self.error, 0
                return gcs.encode_reply([str(code)])
            if name == "*IDN?":
                return gcs.encode_reply(["rotorbench simulator,C-887,0,0.0.0"])
            if name == "CSV?":
                return gcs.encode_reply(["2.0"])
            if name == "SAI?":
                return gcs.encode_reply(list(gcs.HEXAPOD_AXES))
            if name in ("POS?", "MOV?", "ONT?"):
                axes = args or gcs.HEXAPOD_AXES
                if any(a not in self.axes for a in axes):
                    self._fail(15)
                    return gcs.encode_reply(["0"]) if name == "ONT?" else self._values({})
                if name == "POS?":
                    return self._values({a: self.axes[a].value(now) for a in axes})
                if name == "MOV?":
                    return self._values({a: self.axes[a].target for a in axes})
                return gcs.encode_reply(f"{a}={int(a not in moving)}" for a in axes)
            if name in ("MOV", "MVR"):
                pairs = self._axis_pairs(args, self.axes)
                if pairs is not None:
                    if name == "MVR":
                        pairs = {a: self.axes[a].target + v for a, v in pairs.items()}
                    self._move(pairs, now)
                return None
            if name == "SPI":
                pairs = self._axis_pairs(args, self.pivot)
                if pairs is not None:
                    if moving:
                        self._fail(9)  # setting the pivot point not possible while moving
                    else:
                        self.pivot.update(pairs)
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
                mask = sum(1 << k for k, a in enumerate(gcs.HEXAPOD_AXES) if a in moving)
                return gcs.encode_reply([format(mask, "X")])
            if name == "#7":
                return gcs.encode_reply([gcs.BUSY_CHAR if moving else gcs.READY_CHAR])
            if name in ("#24", "STP", "HLT"):
                self._halt(now)
                return None
            if name in ("SVO", "FRF", "WAV", "WSL", "WGC", "WTR", "WGO", "DRC", "RTR"):
                return None  # accepted and recorded in ``commands``
            if name.endswith("?"):
                self._fail(2)
                return gcs.encode_reply(["0"])
            self._fail(2)  # unknown command
            return None
