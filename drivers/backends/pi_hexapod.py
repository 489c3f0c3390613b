"""A PI-style hexapod controller (C-887 class) over TCP, speaking GCS text commands.

The client does what pipython does on the wire (protocols.md §6.1-§6.2): commands end
with LF, replies end at an LF not preceded by a space, and every command is followed by
``ERR?`` so a refused command raises at once. Poses cross this boundary in SI — metres
and radians — and are sent in the controller's units, mm for X, Y, Z and degrees for
U, V, W (§6.2). ``stop()`` sends #24 (stop all) and clears the error 10 that follows.
"""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Iterable, Mapping

from drivers.codecs import gcs
from drivers.contracts import ChannelInfo, DeviceInfo
from drivers.errors import DeviceError

LINEAR_AXES = ("X", "Y", "Z")  # mm on the wire
ANGULAR_AXES = ("U", "V", "W")  # degrees on the wire
DEFAULT_TIMEOUT_S = 7.0  # pipython's socket timeout (§6.1)


def to_wire(pose: Mapping[str, float]) -> dict[str, float]:
    """SI pose {X: m, ..., U: rad, ...} -> controller units {X: mm, ..., U: deg}."""
    out = {}
    for axis, v in pose.items():
        if axis in LINEAR_AXES:
            out[axis] = float(v) * 1e3
        elif axis in ANGULAR_AXES:
            out[axis] = math.degrees(float(v))
        else:
            raise DeviceError(f"hexapod axis {axis!r} unknown (expected X Y Z U V W)")
    return out


def from_wire(values: Mapping[str, float]) -> dict[str, float]:
    return {a: (v * 1e-3 if a in LINEAR_AXES else math.radians(v) if a in ANGULAR_AXES else v)
            for a, v in values.items()}


def open_tcp(host: str, port: int = gcs.PORT, timeout_s: float = 2.0) -> socket.socket:
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        raise DeviceError(f"tcp://{host}:{port}: cannot connect ({exc})") from None
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # §6.1
    return sock


class PiHexapod:
    """GCS client on a connected socket (the caller owns the connection's creation)."""

    def __init__(self, sock: socket.socket, *, url: str = "tcp://hexapod",
                 timeout_s: float = DEFAULT_TIMEOUT_S, errcheck: bool = True) -> None:
        self.sock = sock
        self.url = url
        self.timeout_s = timeout_s
        self.errcheck = errcheck
        self.decoder = gcs.GcsReplyDecoder()
        self._replies: list[gcs.GcsReply] = []
        self.identification = self._identify()

    # ------------------------------------------------------------------ wire
    def _send(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except OSError as exc:
            raise DeviceError(f"{self.url}: send failed, controller gone? ({exc})") from None

    def _reply(self) -> gcs.GcsReply:
        end = time.monotonic() + self.timeout_s
        while not self._replies:
            left = end - time.monotonic()
            if left <= 0:
                raise DeviceError(f"{self.url}: no reply within {self.timeout_s} s")
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as exc:
                raise DeviceError(f"{self.url}: receive failed ({exc})") from None
            if not data:
                raise DeviceError(f"{self.url}: controller closed the connection")
            self._replies += self.decoder.feed(data)
        return self._replies.pop(0)

    def _check_error(self, what: str) -> None:
        self._send(gcs.err_query())
        code = gcs.parse_error_code(self._reply())
        if code:
            text = gcs.ERRORS.get(code, "see the controller manual")
            raise DeviceError(f"{self.url}: {what!r} failed: GCS error {code} ({text})")

    def command(self, line: bytes) -> None:
        """A command without reply, then ``ERR?`` (pipython's default)."""
        self._send(line)
        if self.errcheck:
            self._check_error(line.decode(gcs.ENCODING).strip())

    def query(self, line: bytes) -> gcs.GcsReply:
        self._send(line)
        reply = self._reply()
        if self.errcheck:
            self._check_error(line.decode(gcs.ENCODING).strip())
        return reply

    def _identify(self) -> gcs.Identification:
        return gcs.parse_idn(self.query(gcs.idn()))

    # ------------------------------------------------------------------ bench API
    def describe(self) -> DeviceInfo:
        units = {"X": "m", "Y": "m", "Z": "m", "U": "rad", "V": "rad", "W": "rad"}
        return DeviceInfo(kind="hexapod", model=f"{self.identification.model} (GCS)",
                          url=self.url,
                          channels=tuple(ChannelInfo(f"{a.lower()}_{units[a]}", units[a], 0.0)
                                         for a in gcs.HEXAPOD_AXES),
                          extra={"vendor": self.identification.vendor,
                                 "firmware": self.identification.firmware})

    def move_to(self, pose: Mapping[str, float]) -> None:
        """Absolute move of the given axes (SI); all axes start together (§6.3 MOV)."""
        self.command(gcs.mov(to_wire(pose)))

    def position(self, axes: Iterable[str] = ()) -> dict[str, float]:
        return from_wire(gcs.parse_axis_values(self.query(gcs.pos_query(axes))))

    def on_target(self) -> bool:
        values = gcs.parse_axis_values(self.query(gcs.ont_query()))
        return all(v == 1.0 for v in values.values())

    def wait_on_target(self, timeout_s: float = 30.0, poll_s: float = 0.02) -> None:
        end = time.monotonic() + timeout_s
        while not self.on_target():
            if time.monotonic() > end:
                self.stop()
                raise DeviceError(f"{self.url}: not on target within {timeout_s} s (stopped)")
            time.sleep(poll_s)

    def set_pivot(self, pivot_m: Mapping[str, float]) -> None:
        """Pivot point in metres; axis names as the controller uses them (R, S, T [U])."""
        self.command(gcs.spi({a: v * 1e3 for a, v in pivot_m.items()}))

    def set_velocity(self, velocity: float) -> None:
        self.command(gcs.vls(velocity))

    def stop(self) -> None:
        """Stop all motion (#24). The controller then reports error 10, which is cleared
        here. Raises only when the controller is gone."""
        self._send(gcs.STOP_ALL)
        self._send(gcs.err_query())
        code = gcs.parse_error_code(self._reply())
        if code not in (0, gcs.STOPPED_BY_COMMAND):
            raise DeviceError(f"{self.url}: stop answered with GCS error {code}")

    def close(self) -> None:
        """Stop and disconnect; never raises."""
        try:
            self.stop()
        except DeviceError:
            pass
        try:
            self.sock.close()
        except OSError:
            pass
