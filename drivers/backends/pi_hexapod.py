"""A PI-style hexapod controller (C-887 class) over TCP, speaking GCS text commands.

The client does what pipython does on the wire (protocols.md §6.1-§6.2): commands end
with LF, replies end at an LF not preceded by a space, and every command is followed by
``ERR?`` so a refused command raises at once. Poses cross this boundary in SI — metres
and radians — and are sent in the controller's units, mm for X, Y, Z and degrees for
U, V, W (§6.2).

:class:`PiHexapod` fills :class:`drivers.contracts.Hexapod`: a trajectory is
checked against the rig's limits (the controller does not report acceleration limits)
and the present pose (``POS?``), written as one wave table per axis, started with
``WGO``; the data recorder logs the actual position of the six axes, read back with
``DRR?``, differentiated (Savitzky-Golay fits) and turned into the body-frame log by
:mod:`drivers.hexapod_kinematics`. While
no trajectory runs the log continues at rest from ``POS?``. ``stop()`` (#24 and
``WGO n 0``) is safe from any thread at any time: if the main conversation is busy it
goes over a second connection, and if the controller dropped the connection it
reconnects to stop.

Every wire choice protocols.md does not verify lives in :class:`GcsDialect` (one place,
overridable from the rig file's device options); see docs/hexapod-tcp.md.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_coeffs, savgol_filter

from drivers.codecs import gcs
from drivers.contracts import (
    HEXAPOD_LOG_CHANNELS,
    Block,
    ChannelInfo,
    Clock,
    DeviceInfo,
    HexapodLimits,
    MonotonicClock,
    Trajectory,
)
from drivers.errors import DeviceError
from drivers.hexapod_kinematics import (
    GRAVITY_M_S2,
)
from drivers.hexapod_log import checked_spline, log_block

__all__ = ["DEFAULT_TIMEOUT_S", "ControllerState", "GcsDialect", "PiHexapod", "from_wire",
           "open_tcp", "to_wire"]

LINEAR_AXES = ("X", "Y", "Z")  # mm on the wire
ANGULAR_AXES = ("U", "V", "W")  # degrees on the wire
DEFAULT_TIMEOUT_S = 7.0  # pipython's socket timeout (§6.1)
DEFAULT_DERIVATIVE_WINDOW = 11  # recorder points per Savitzky-Golay fit (11 ms at 1 kHz)
Array = NDArray[np.float64]
_SI_PER_WIRE = np.array([1e-3, 1e-3, 1e-3, math.pi / 180, math.pi / 180, math.pi / 180])


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


# ---------------------------------------------------------------------------- dialect


@dataclass(frozen=True)
class GcsDialect:
    """Every wire fact the bench relies on that protocols.md does not verify ([U]), in one
    place. A user with a C-887 manual fixes them here or in the rig file's options.

    * ``pivot_axes``: SPI coordinate letters, R S T [U §6.3: "from memory"].
    * ``wave_line``: point-by-point wave table upload. protocols.md gives WAV only with
      SIN_P parameters and names PNT as a shape; the form chosen is the closest one,
      ``WAV <table> <X|&> PNT <firstpoint> <numpoints> <p1> ... <pn>`` [U], the first
      chunk with X (new table), the rest appended with & (§6.3 append modes).
    * wave tables hold absolute positions in mm / deg [U]; generator k drives axis k
      (X Y Z U V W = 1..6) through table k [U]; WTR's interpolation argument
      ``wave_interpolation`` (protocols.md's example uses 0) [U]; one ``WGO`` with all
      six ``generator mode`` pairs starts them together (pair syntax like MOV) [U].
    * data recorder: table k records ``DRC k <axis> 2`` (option 2 actual position §6.3);
      recording (re)starts when the wave generators start [U]; ``DRR?`` offsets count
      from 1 [U] and only points already recorded are asked for.
    * U, V, W are taken as roll, pitch, yaw of the bench's Z-Y-X convention (PI's U->V->W
      sequence about space-fixed axes) [U].
    """

    pivot_axes: tuple[str, str, str] = ("R", "S", "T")
    servo_cycle_s: float = gcs.SERVO_CYCLE_S_C887  # §6.3 pipython SERVOTIMES['C-887']
    wave_chunk_points: int = 100
    wave_first_point: int = 1
    wave_interpolation: int = 0
    record_option: int = gcs.RECORD_ACTUAL_POSITION
    drr_first_offset: int = 1
    drr_max_points: int = 2000

    @classmethod
    def from_options(cls, options: Mapping[str, object], where: str) -> GcsDialect:
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise DeviceError(f"{where}: unknown option(s) {', '.join(map(repr, unknown))}; "
                              f"expected {', '.join(sorted(names))}")
        values = dict(options)
        try:
            if "pivot_axes" in values:
                axes = tuple(str(a) for a in values["pivot_axes"])  # type: ignore[union-attr]
                if len(axes) != 3:
                    raise ValueError("pivot_axes needs three letters")
                values["pivot_axes"] = axes
            for name in names - {"pivot_axes"}:
                if name in values:
                    kind = float if name == "servo_cycle_s" else int
                    values[name] = kind(values[name])  # type: ignore[arg-type]
        except (TypeError, ValueError) as exc:
            raise DeviceError(f"{where}: bad option value ({exc})") from None
        dialect = cls(**values)  # type: ignore[arg-type]
        if not dialect.servo_cycle_s > 0 or dialect.wave_chunk_points < 1 \
                or dialect.drr_max_points < 1:
            raise DeviceError(f"{where}: servo_cycle_s, wave_chunk_points and drr_max_points "
                              "must be positive")
        return dialect

    # -- command lines ------------------------------------------------------------------
    def cycles_per_point(self, rate_hz: float, what: str) -> int:
        """Servo cycles per point = 1 / (rate x servo period); must be a whole number."""
        exact = 1.0 / (rate_hz * self.servo_cycle_s)
        n = round(exact)
        if n < 1 or abs(exact - n) > 1e-6 * exact:
            raise DeviceError(f"{what} {rate_hz:g} Hz is not a whole number of servo cycles "
                              f"({self.servo_cycle_s * 1e6:g} us each): {exact:.4g}")
        return n

    def wave_lines(self, table: int, values: Array) -> list[bytes]:
        """Wave table ``table`` holding ``values`` (controller units) in chunks [U]."""
        out = []
        for k in range(0, len(values), self.wave_chunk_points):
            chunk = values[k:k + self.wave_chunk_points]
            out.append(gcs.wav(table, "X" if k == 0 else "&", "PNT", self.wave_first_point,
                               len(chunk), *(float(v) for v in chunk)))
        return out

    def wave_setup(self, cycles_per_point: int) -> list[bytes]:
        out = []
        for k in range(1, 7):
            out += [gcs.wsl(k, k), gcs.wtr(k, cycles_per_point, self.wave_interpolation),
                    gcs.wgc(k, 1)]
        return out

    @staticmethod
    def wave_go(mode: int) -> bytes:
        """``WGO 1 m 2 m ... 6 m``: all six generators at once."""
        return gcs.command("WGO", *(x for k in range(1, 7) for x in (k, mode)))

    def recorder_setup(self, cycles_per_point: int) -> list[bytes]:
        return [*(gcs.drc(k, a, self.record_option) for k, a in enumerate(gcs.HEXAPOD_AXES, 1)),
                gcs.rtr(cycles_per_point)]

    def recorder_read(self, first: int, count: int) -> bytes:
        """Points ``first .. first + count - 1`` (0-based) of the six tables."""
        return gcs.drr_query(first + self.drr_first_offset, count, range(1, 7))


@dataclass(frozen=True)
class ControllerState:
    """What the controller says about itself before any motion (SI travel limits)."""

    servo: dict[str, bool]
    referenced: dict[str, bool]
    travel: dict[str, tuple[float, float]]  # axis -> (TMN?, TMX?) in m or rad

    def require_ready(self, url: str) -> None:
        for what, flags, fix in (("not referenced", self.referenced, "reference it (FRF)"),
                                 ("servo off", self.servo, "switch the servo on (SVO)")):
            off = [a for a in gcs.HEXAPOD_AXES if not flags.get(a, False)]
            if off:
                query = "FRF?" if flags is self.referenced else "SVO?"
                raise DeviceError(f"{url}: hexapod {what} ({query} {off[0]}=0): {fix} "
                                  "before any motion; refused")

    def as_dict(self) -> dict[str, object]:
        return {"servo": self.servo, "referenced": self.referenced,
                "travel": {a: list(v) for a, v in self.travel.items()}}


# ---------------------------------------------------------------------------- wire


class _Link:
    """One TCP conversation: send, wait for a complete reply, ``ERR?`` after commands."""

    def __init__(self, sock: socket.socket, url: str, timeout_s: float) -> None:
        self.sock = sock
        self.url = url
        self.timeout_s = timeout_s
        self.decoder = gcs.GcsReplyDecoder()
        self.replies: list[gcs.GcsReply] = []
        self.dead = False

    def send(self, data: bytes) -> None:
        if self.dead:
            raise DeviceError(f"{self.url}: connection lost")
        try:
            self.sock.sendall(data)
        except OSError as exc:
            self.dead = True
            raise DeviceError(f"{self.url}: send failed, controller gone? ({exc})") from None

    def reply(self) -> gcs.GcsReply:
        """The next reply. The timeout stands only if a read begun after the deadline
        finds nothing: a host that was itself off the processor past the deadline reads
        the reply waiting in its socket (the controller did answer in time)."""
        end = time.monotonic() + self.timeout_s
        while not self.replies:
            left = end - time.monotonic()
            try:
                self.sock.settimeout(max(left, 1e-3))
                data = self.sock.recv(1 << 16)
            except TimeoutError:
                if left > 0:
                    continue
                self.dead = True  # a late reply would answer the next question: start over
                raise DeviceError(f"{self.url}: no reply within {self.timeout_s} s") from None
            except OSError as exc:
                self.dead = True
                raise DeviceError(f"{self.url}: receive failed ({exc})") from None
            if not data:
                self.dead = True
                raise DeviceError(f"{self.url}: controller closed the connection")
            self.replies += self.decoder.feed(data)
        return self.replies.pop(0)

    def error_code(self) -> int:
        self.send(gcs.err_query())
        return gcs.parse_error_code(self.reply())

    def check(self, what: str) -> None:
        code = self.error_code()
        if code:
            text = gcs.ERRORS.get(code, "see the controller manual")
            raise DeviceError(f"{self.url}: {what!r} failed: GCS error {code} ({text})")

    def close(self) -> None:
        self.dead = True
        try:
            self.sock.close()
        except OSError:
            pass


def _what(line: bytes) -> str:
    text = line.decode(gcs.ENCODING).strip()
    return text if len(text) < 60 else text[:57] + "..."


# ---------------------------------------------------------------------------- log


@dataclass
class _RunLog:
    """Recorder read-back of one started trajectory: points ``0 .. n_total - 1``."""

    t0: float
    period_s: float
    n_total: int
    read: int = 0  # points fetched
    emitted: int = 0  # samples handed out
    base: int = 0  # index of buf[0]
    buf: Array = field(default_factory=lambda: np.empty((0, 6)))


def _derivatives(buf: Array, base: int, i: NDArray[np.int64], last: int, h: float
                 ) -> tuple[Array, Array]:
    """Velocity and acceleration of recorded points ``i`` (``buf[k - base]`` is point k of
    ``0 .. last``): central differences inside, second-order one-sided ones at both ends
    (a run starts and ends with a jump in acceleration, which a centred stencil smears)."""
    if last < 3:
        zeros = np.zeros((i.size, 6))
        return zeros, zeros
    c = np.clip(i, 1, last - 1) - base
    pm, p0, pp = buf[c - 1], buf[c], buf[c + 1]
    vel = (pp - pm) / (2.0 * h)
    acc = (pp - 2.0 * p0 + pm) / (h * h)
    for k, sign in ((0, 1), (last, -1)):
        hit = i == k
        if hit.any():
            q = [buf[k + sign * j - base] for j in range(4)]
            vel[hit] = sign * (-3.0 * q[0] + 4.0 * q[1] - q[2]) / (2.0 * h)
            acc[hit] = (2.0 * q[0] - 5.0 * q[1] + 4.0 * q[2] - q[3]) / (h * h)
    return vel, acc


class _Differentiator:
    """Velocity and acceleration of a run's recorded positions, streamed.

    ``window`` >= 5 (odd): Savitzky-Golay cubic fits over ``window`` points (scipy), the
    polynomial of the first/last window at the run's two ends; it keeps the noise of
    twice-differentiated positions down (a 3-point second difference multiplies position
    noise by sqrt(6)/h², a 21-point cubic fit by 0.013/h²) at no cost for motions far
    below ``1 / (window x h)``. ``window`` <= 3: the 3-point differences above.
    """

    def __init__(self, window: int, where: str) -> None:
        window = int(window)
        if window > 3 and window % 2 == 0:
            raise DeviceError(f"{where}: derivative_window {window}: expected an odd number")
        self.window = window if window > 3 else 0
        self.context = max(self.window, 4)  # points kept before the next one to emit
        self._coeffs: dict[tuple[int, float], Array] = {}

    def ready(self, read: int) -> int:
        """Points that can be emitted while the run goes on: each waits for successors."""
        if not self.window:
            return read - 3
        return read - self.window // 2 if read >= self.window else 0

    def _c(self, deriv: int, h: float) -> Array:
        key = (deriv, h)
        if key not in self._coeffs:
            self._coeffs[key] = savgol_coeffs(self.window, 3, deriv=deriv, delta=h, use="dot")
        return self._coeffs[key]

    def __call__(self, buf: Array, base: int, i: NDArray[np.int64], last: int, h: float
                 ) -> tuple[Array, Array]:
        w = self.window
        if not w or last + 1 < w:
            return _derivatives(buf, base, i, last, h)
        m = w // 2
        vel, acc = np.empty((i.size, 6)), np.empty((i.size, 6))
        inner = (i >= m) & (i <= last - m)
        if inner.any():
            rows = buf[i[inner, None] + np.arange(-m, m + 1) - base]  # (k, w, 6)
            vel[inner] = np.einsum("w,kwc->kc", self._c(1, h), rows)
            acc[inner] = np.einsum("w,kwc->kc", self._c(2, h), rows)
        for edge, first in ((i < m, 0), (i > last - m, last - w + 1)):
            if edge.any():
                seg = buf[first - base:first - base + w]
                k = i[edge] - first
                vel[edge] = np.asarray(savgol_filter(seg, w, 3, deriv=1, delta=h, axis=0,
                                                     mode="interp"))[k]
                acc[edge] = np.asarray(savgol_filter(seg, w, 3, deriv=2, delta=h, axis=0,
                                                     mode="interp"))[k]
        return vel, acc


def _units(name: str) -> str:
    for suffix, unit in (("_rad_s2", "rad/s^2"), ("_m_s2", "m/s^2"), ("_rad_s", "rad/s"),
                         ("_m_s", "m/s"), ("_rad", "rad"), ("_m", "m")):
        if name.endswith(suffix):
            return unit
    return ""


class PiHexapod:
    """GCS client on a connected socket; fills the ``Hexapod`` contract (module docstring).

    ``connect`` (a callable returning a new connected socket) enables the second stop
    connection and reconnect-to-stop; ``clock`` stamps the log (the rig's clock; a
    simulated controller shares the simulated one); ``limits`` come from the rig file.
    """

    def __init__(self, sock: socket.socket, *, url: str = "tcp://hexapod",
                 timeout_s: float = DEFAULT_TIMEOUT_S, errcheck: bool = True,
                 connect: Callable[[], socket.socket] | None = None,
                 limits: HexapodLimits | None = None, clock: Clock | None = None,
                 log_rate_hz: float = 1000.0, dialect: GcsDialect | None = None,
                 gravity: float = GRAVITY_M_S2, start_tolerance: float = 1e-6,
                 stop_lock_timeout_s: float = 0.2,
                 derivative_window: int = DEFAULT_DERIVATIVE_WINDOW) -> None:
        try:  # the socket is this object's from here on, whatever happens
            self.url = url
            self.timeout_s = timeout_s
            self.errcheck = errcheck
            self.dialect = dialect or GcsDialect()
            self._limits = limits or HexapodLimits()
            self.clock: Clock = clock or MonotonicClock()
            self.gravity = gravity
            self.start_tolerance = start_tolerance
            self.stop_lock_timeout_s = stop_lock_timeout_s
            self._connect = connect
            self._diff = _Differentiator(derivative_window, url)
            self._main = _Link(sock, url, timeout_s)
            self._lock = threading.RLock()  # the main conversation
            self._stop_lock = threading.Lock()  # the stop connection
            self._stop_link: _Link | None = None
            self.pivot_m = (0.0, 0.0, 0.0)
            self.record_cycles = self.dialect.cycles_per_point(log_rate_hz, "log rate")
            self.log_period_s = self.record_cycles * self.dialect.servo_cycle_s
            self._uploaded: Trajectory | None = None
            self._upload_pose = np.zeros(6)
            self._run: _RunLog | None = None
            self._pending: list[Block] = []
            self._rest_anchor = self.clock.now()
            self._rest_k = 1
            self._last_t = -math.inf
            self.stop_calls = 0
            self.closed = False
            self.identification = self._identify()
            self.state = self.controller_state()  # read before any motion (limits, reference)
            if connect is not None:
                try:
                    self._stop_link = _Link(connect(), url + " (stop connection)", timeout_s)
                except DeviceError:
                    self._stop_link = None  # one-connection controllers: the lock path only
        except BaseException:
            sock.close()
            raise

    @property
    def sock(self) -> socket.socket:
        return self._main.sock

    # ------------------------------------------------------------------ wire
    def command(self, line: bytes) -> None:
        """A command without reply, then ``ERR?`` (pipython's default)."""
        with self._lock:
            self._main.send(line)
            if self.errcheck:
                self._main.check(_what(line))

    def query(self, line: bytes) -> gcs.GcsReply:
        with self._lock:
            self._main.send(line)
            reply = self._main.reply()
            if self.errcheck:
                self._main.check(_what(line))
            return reply

    def _commands(self, lines: Iterable[bytes], what: str) -> None:
        """Many commands pipelined, then one ``ERR?`` (the controller keeps the error)."""
        with self._lock:
            self._main.send(b"".join(lines))
            self._main.check(what)

    def _identify(self) -> gcs.Identification:
        return gcs.parse_idn(self.query(gcs.idn()))

    def controller_state(self) -> ControllerState:
        """Servo (``SVO?``), referenced (``FRF?``) and soft travel limits (``TMN?``,
        ``TMX?``) as the controller reports them (PIPython reply syntax, §6.3)."""
        def values(name: str) -> dict[str, float]:
            return gcs.parse_axis_values(self.query(gcs.command(name)))

        servo, ref = values("SVO?"), values("FRF?")
        low, high = from_wire(values("TMN?")), from_wire(values("TMX?"))
        missing = [a for a in gcs.HEXAPOD_AXES if a not in low or a not in high]
        if missing:
            raise gcs.GcsReplyError(f"{self.url}: TMN?/TMX? reply lacks axis {missing[0]}")
        return ControllerState({a: v == 1.0 for a, v in servo.items()},
                               {a: v == 1.0 for a, v in ref.items()},
                               {a: (low[a], high[a]) for a in gcs.HEXAPOD_AXES})

    def check_motion(self, trajectory: Trajectory, *, refresh: bool = True) -> None:
        """Refuse a motion the controller would refuse or stop in: axes not referenced or
        servo off, or a pose beyond ``TMN?``/``TMX?``; reads the state afresh unless
        ``refresh`` is False (``upload``: eight round trips would delay every motion)."""
        if refresh:
            self.state = self.controller_state()
        state = self.state
        state.require_ready(self.url)
        lo = trajectory.poses.min(axis=0)
        hi = trajectory.poses.max(axis=0)
        for k, axis in enumerate(gcs.HEXAPOD_AXES):
            tmn, tmx = state.travel[axis]
            for value, limit, query, beyond in ((lo[k], tmn, "TMN?", lo[k] < tmn - 1e-12),
                                                (hi[k], tmx, "TMX?", hi[k] > tmx + 1e-12)):
                if beyond:
                    unit = "m" if axis in LINEAR_AXES else "rad"
                    raise DeviceError(
                        f"{self.url}: motion {trajectory.name!r} reaches {axis} = "
                        f"{value:.6g} {unit}, beyond the controller's {query} {axis} = "
                        f"{limit:.6g} {unit}; refused before it starts")

    # ------------------------------------------------------------------ motion API
    def describe(self) -> DeviceInfo:
        d = self.dialect
        return DeviceInfo(
            kind="hexapod", model=f"{self.identification.model} (PI GCS over TCP)", url=self.url,
            channels=tuple(ChannelInfo(c, _units(c), 1.0 / self.log_period_s)
                           for c in HEXAPOD_LOG_CHANNELS),
            extra={"limits": self._limits.as_dict(), "pivot_m": list(self.pivot_m),
                   "log_rate_hz": 1.0 / self.log_period_s, "vendor": self.identification.vendor,
                   "firmware": self.identification.firmware,
                   "servo_cycle_s": d.servo_cycle_s, "pivot_axes": list(d.pivot_axes),
                   "stop_connection": self._stop_link is not None,
                   "controller": self.state.as_dict(),
                   "unverified": "wave-table PNT upload, WTR interpolation, generator/axis "
                                 "mapping, recorder trigger and DRR? offsets, pivot letters "
                                 "(docs/hexapod-tcp.md)"})

    def limits(self) -> HexapodLimits:
        return self._limits

    def move_to(self, pose: Mapping[str, float]) -> None:
        """Absolute move of the given axes (SI); all axes start together (§6.3 MOV).
        Refused, naming axis and limit, unless referenced, servo on and within TMN?/TMX?."""
        wire = to_wire(pose)
        self.state = state = self.controller_state()
        state.require_ready(self.url)
        for axis, value in from_wire(wire).items():
            tmn, tmx = state.travel[axis]
            if not tmn - 1e-12 <= value <= tmx + 1e-12:
                raise DeviceError(f"{self.url}: MOV {axis} = {value:.6g} outside the "
                                  f"controller's TMN?..TMX? {tmn:.6g}..{tmx:.6g}; refused")
        self.command(gcs.mov(wire))

    def position(self, axes: Iterable[str] = ()) -> dict[str, float]:
        return from_wire(gcs.parse_axis_values(self.query(gcs.pos_query(axes))))

    def _pose(self) -> Array:
        pos = self.position()
        try:
            return np.array([pos[a] for a in gcs.HEXAPOD_AXES])
        except KeyError as exc:
            raise gcs.GcsReplyError(f"{self.url}: POS? reply lacks axis {exc}") from None

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

    def set_pivot(self, pivot_m: tuple[float, float, float] | Mapping[str, float]) -> None:
        """Rotation centre (m): ``(x, y, z)`` sent as the dialect's pivot letters, or a
        mapping of the controller's own letters. The controller refuses while moving."""
        if isinstance(pivot_m, Mapping):
            self.command(gcs.spi({a: float(v) * 1e3 for a, v in pivot_m.items()}))
            return
        p = tuple(float(v) for v in pivot_m)
        if len(p) != 3 or not all(math.isfinite(v) for v in p):
            raise DeviceError(f"{self.url}: pivot must be three finite numbers (m), got "
                              f"{pivot_m!r}")
        self.command(gcs.spi({a: v * 1e3 for a, v in zip(self.dialect.pivot_axes, p,
                                                           strict=True)}))
        self.pivot_m = p  # type: ignore[assignment]

    def set_velocity(self, velocity: float) -> None:
        self.command(gcs.vls(velocity))

    def _mask(self, line: bytes) -> int:
        reply = self.query(line)
        try:
            return int(reply.lines[0].strip() or "0", 16)
        except ValueError:
            raise gcs.GcsReplyError(f"{self.url}: {_what(line)!r} reply {reply.lines!r}: "
                                    "expected a hex mask") from None

    def is_moving(self) -> bool:
        """Wave generators running (#9) or any axis moving (#5), §6.1."""
        with self._lock:
            return bool(self._mask(gcs.WAVE_RUNNING)) or bool(self._mask(gcs.IS_MOVING))

    # ------------------------------------------------------------------ trajectories
    def upload(self, trajectory: Trajectory) -> None:
        """Check the trajectory (limits, present pose), then write the wave tables and set
        up generators and recorder; nothing moves until ``start``."""
        name = trajectory.name
        checked_spline(trajectory, self._limits, self.gravity, self.url)
        self.check_motion(trajectory, refresh=False)  # state as read at open / preflight
        d = self.dialect
        cycles = d.cycles_per_point(trajectory.rate_hz, f"trajectory {name!r} rate")
        with self._lock:
            self._uploaded = None
            if self.is_moving():
                raise DeviceError(f"{self.url}: upload of {name!r} refused while moving")
            here = self._pose()
            jump = float(np.abs(trajectory.poses[0] - here).max())
            if jump > self.start_tolerance:
                raise DeviceError(f"{self.url}: trajectory {name!r} starts {jump:.4g} (m or "
                                  "rad) away from the present pose; refused")
            wire = trajectory.poses / _SI_PER_WIRE
            lines = [*d.recorder_setup(self.record_cycles), *d.wave_setup(cycles)]
            for k in range(6):
                lines += d.wave_lines(k + 1, wire[:, k])
            self._commands(lines, f"upload of {name!r} (WAV/WSL/WTR/WGC/DRC/RTR)")
            self._uploaded = trajectory
            self._upload_pose = here

    def start(self) -> None:
        """Start all six wave generators together (one WGO) and note the start time."""
        with self._lock:
            traj = self._uploaded
            if traj is None:
                raise DeviceError(f"{self.url}: start without an uploaded trajectory")
            if self.is_moving():
                raise DeviceError(f"{self.url}: start refused while a trajectory runs")
            self._uploaded = None
            t0 = self.clock.now()
            self._finish_run(t0)  # the recorder restarts with WGO: read the last run first
            self._pending.append(self._rest_block(t0, self._upload_pose, inclusive=False))
            self.command(self.dialect.wave_go(1))
            n = math.floor(traj.duration_s / self.log_period_s + 1e-9) + 1
            self._run = _RunLog(t0, self.log_period_s, n)

    # ------------------------------------------------------------------ log
    def read_log(self) -> Block:
        """New samples since the previous call (recorder during a run, ``POS?`` at rest)."""
        with self._lock:
            now = self.clock.now()
            blocks, self._pending = self._pending, []
            if self._run is not None:
                blocks.append(self._read_run(now))
            if self._run is None:
                blocks.append(self._rest_block(now, None, inclusive=True))
            blocks = [b for b in blocks if len(b)]
            if not blocks:
                return Block.empty(HEXAPOD_LOG_CHANNELS)
            t = np.concatenate([b.t_s for b in blocks])
            keep = t > self._last_t + 1e-12  # a run's first point may repeat the rest sample
            if not keep.any():
                return Block.empty(HEXAPOD_LOG_CHANNELS)
            values = {c: np.concatenate([b.values[c] for b in blocks])[keep]
                      for c in HEXAPOD_LOG_CHANNELS}
            self._last_t = float(t[keep][-1])
            return Block(t[keep], values)

    def _finish_run(self, now: float) -> None:
        """Read what is left of the previous run's log into the pending samples."""
        if self._run is not None:
            self._pending.append(self._read_run(now))
        run = self._run
        if run is not None:  # points the recorder did not give: the log ends before them
            run.n_total = run.read
            if run.read > run.emitted:
                self._pending.append(self._read_run(now))
            self._run = None

    def _rest_block(self, until: float, pose: Array | None, *, inclusive: bool) -> Block:
        """Samples at rest on the log grid up to ``until`` (pose from ``POS?`` if None)."""
        eps = 1e-9 if inclusive else -1e-9
        k_end = math.floor((until - self._rest_anchor) / self.log_period_s + eps)
        if k_end < self._rest_k:
            return Block.empty(HEXAPOD_LOG_CHANNELS)
        k = np.arange(self._rest_k, k_end + 1)
        self._rest_k = k_end + 1
        t = self._rest_anchor + k * self.log_period_s
        p = self._pose() if pose is None else pose
        zeros = np.zeros((k.size, 6))
        return self._block(t, np.tile(p, (k.size, 1)), zeros, zeros)

    def _read_run(self, now: float) -> Block:
        run = self._run
        assert run is not None
        due = min(run.n_total, math.floor((now - run.t0) / run.period_s + 1e-9) + 1)
        while run.read < due:
            count = min(due - run.read, self.dialect.drr_max_points)
            rows = gcs.parse_data_array(self.query(self.dialect.recorder_read(run.read, count)))
            data = rows.data
            if data.size == 0:
                break
            if data.shape[1] != 6:
                raise gcs.GcsReplyError(f"{self.url}: DRR? gave {data.shape[1]} columns, "
                                        "expected the 6 recorded axes")
            data = data[:count] * _SI_PER_WIRE
            run.buf = np.vstack([run.buf, data])
            run.read += len(data)
            if len(data) < count:
                break
        final = run.read >= run.n_total
        end = run.n_total if final else self._diff.ready(run.read)
        if end <= run.emitted:
            return Block.empty(HEXAPOD_LOG_CHANNELS)
        i = np.arange(run.emitted, end)
        last = min(run.read, run.n_total) - 1
        vel, acc = self._diff(run.buf, run.base, i, last, run.period_s)
        p = run.buf[i - run.base]
        t = run.t0 + i * run.period_s
        run.emitted = end
        keep = max(0, end - self._diff.context - run.base)
        run.buf, run.base = run.buf[keep:], run.base + keep
        if final:
            self._run = None
            self._rest_anchor, self._rest_k = float(t[-1]), 1
        return self._block(t, p, vel, acc)

    def _block(self, t: NDArray[np.floating], pose: Array, vel: Array, acc: Array) -> Block:
        return log_block(t, pose, vel, acc, self.gravity)

    # ------------------------------------------------------------------ stop
    def stop(self) -> None:
        """Stop all motion: #24, then ``WGO n 0`` for the six generators; clears the error
        10 that follows. Any thread, any time; raises ``DeviceError`` only when no
        connection to the controller could carry the stop."""
        self.stop_calls += 1
        self._uploaded = None
        run = self._run
        if run is not None:  # the log ends where the platform stopped
            n = math.floor((self.clock.now() - run.t0) / run.period_s + 1e-9) + 1
            run.n_total = max(1, min(run.n_total, max(n, run.read)))
        locked = self._lock.acquire(timeout=self.stop_lock_timeout_s)
        try:
            errors = []
            for link in self._stop_links(locked):
                try:
                    self._stop_on(link)
                    return
                except DeviceError as exc:
                    errors.append(str(exc))
            raise DeviceError(f"{self.url}: stop not confirmed: " + "; ".join(errors))
        finally:
            if locked:
                self._lock.release()

    def _stop_links(self, locked: bool) -> Iterable[_Link]:
        """The main connection if it is free, else the stop connection, else a new one."""
        if locked and not self._main.dead:
            yield self._main
        if self._stop_link is not None and not self._stop_link.dead:
            yield self._stop_link
        if self._connect is None or self.closed:
            return
        try:
            link = _Link(self._connect(), self.url + " (reconnected)", self.timeout_s)
        except DeviceError:
            return
        if locked and self._main.dead:  # the new link carries the main conversation on
            old_main, self._main = self._main, link
            old_main.close()  # its socket is dead but still open (a ResourceWarning later)
        else:
            old, self._stop_link = self._stop_link, link
            if old is not None:
                old.close()
        yield link

    def _stop_on(self, link: _Link) -> None:
        guard = self._stop_lock if link is not self._main else None
        if guard is not None:
            guard.acquire()
        try:
            link.send(gcs.STOP_ALL + self.dialect.wave_go(0))
            code = link.error_code()
            if code not in (0, gcs.STOPPED_BY_COMMAND):
                raise DeviceError(f"{link.url}: stop answered with GCS error {code}")
        finally:
            if guard is not None:
                guard.release()

    def close(self) -> None:
        """Stop and disconnect; never raises."""
        try:
            self.stop()
        except DeviceError:
            pass
        self.closed = True
        self._main.close()
        if self._stop_link is not None:
            self._stop_link.close()
